from glob import glob

from setuptools import find_packages, setup

PACKAGE = "dombot_sim"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", sorted(glob("config/*.yaml") + glob("config/*.xml"))),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="DOM-BOT developers",
    maintainer_email="dombot@example.org",
    description=(
        "Drake simulation of the DOM-BOT cell exposed over ROS 2 like real hardware: "
        "cameras, joint states, trajectory and gripper actions."
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "sim_node = dombot_sim.entry_points:sim_node",
            "snapshot = dombot_sim.entry_points:snapshot",
        ],
    },
)

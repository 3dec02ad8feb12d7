from glob import glob

from setuptools import find_packages, setup

PACKAGE = "dombot_layer"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/config", sorted(glob("config/*.yaml"))),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="DOM-BOT developers",
    maintainer_email="dombot@example.org",
    description=(
        "Domino-laying vehicle: exact trolley kinematics, wheel velocity commands, path "
        "schedules and a vehicle simulation."
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "layer_node = dombot_layer.entry_points:layer_node",
            "vehicle_sim_node = dombot_layer.entry_points:vehicle_sim_node",
        ],
    },
)

from glob import glob

from setuptools import find_packages, setup

PACKAGE = "dombot_planner"

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
        "The /plan_place service: pick-and-place trajectories by Drake kinematic "
        "trajectory optimization on a shadow plant."
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": ["planner_node = dombot_planner.entry_points:planner_node"],
    },
)

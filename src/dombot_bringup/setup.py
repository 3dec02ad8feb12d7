from glob import glob

from setuptools import find_packages, setup

PACKAGE = "dombot_bringup"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        (f"share/{PACKAGE}/launch", sorted(glob("launch/*.launch.py"))),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="DOM-BOT developers",
    maintainer_email="dombot@example.org",
    description=(
        "Bring-up of the DOM-BOT node graph: builds a domino run from a pile in "
        "simulation and knocks it down."
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "bringup = dombot_bringup.entry_points:bringup",
            "record = dombot_bringup.entry_points:record",
            "replay = dombot_bringup.entry_points:replay",
        ],
    },
)

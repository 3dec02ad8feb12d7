from glob import glob

from setuptools import find_packages, setup

PACKAGE = "dombot_perception"

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
        "RGB-D perception of a domino pile: segmentation, multi-camera box fitting, grasp"
        " scoring; publishes domino poses."
    ),
    license="Apache-2.0",
    entry_points={
        "console_scripts": [
            "perception_node = dombot_perception.entry_points:perception_node",
        ],
    },
)

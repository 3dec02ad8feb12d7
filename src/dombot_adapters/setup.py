from setuptools import find_packages, setup

PACKAGE = "dombot_adapters"

setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="DOM-BOT developers",
    maintainer_email="dombot@example.org",
    description="What every DOM-BOT node adapter shares: pose and time messages, a quiet "
    "shutdown, settings dataclasses as ROS parameters.",
    license="Apache-2.0",
)

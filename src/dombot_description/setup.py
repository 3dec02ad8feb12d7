from pathlib import Path

from setuptools import find_packages, setup

PACKAGE = "dombot_description"
DATA_DIRS = ("models", "scenarios")


def share_files() -> list[tuple[str, list[str]]]:
    """Install models and scenarios under share/ too, where ROS tools look for them."""
    entries = []
    for data_dir in DATA_DIRS:
        for folder in sorted(Path(PACKAGE, data_dir).glob("**")):
            files = [str(f) for f in sorted(folder.iterdir()) if f.is_file()]
            if files:
                entries.append((f"share/{PACKAGE}/{folder.relative_to(PACKAGE)}", files))
    return entries


setup(
    name=PACKAGE,
    version="0.1.0",
    packages=find_packages(exclude=["test"]),
    package_data={PACKAGE: [f"{d}/**/*" for d in DATA_DIRS]},
    data_files=[
        ("share/ament_index/resource_index/packages", [f"resource/{PACKAGE}"]),
        (f"share/{PACKAGE}", ["package.xml"]),
        *share_files(),
    ],
    install_requires=["setuptools"],
    zip_safe=False,
    maintainer="DOM-BOT developers",
    maintainer_email="dombot@example.org",
    description="Robot, gripper, table, domino and camera models and the one scenario file "
    "the DOM-BOT simulator and planner both load.",
    license="Apache-2.0",
)

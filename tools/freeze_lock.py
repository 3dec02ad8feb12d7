"""Print the installed distributions as a pip lock file.

``pip freeze`` is not usable here: the ROS 2 wheels embed the egg-info of the
packages they were built from (``action_msgs``, ``rclpy`` ...), which pip then
lists as if they were installable distributions. Only real ``.dist-info``
installs are written. The local CPU torch build is pinned without its ``+cpu``
tag so that pip takes it from the machine's wheel directory.
"""

from __future__ import annotations

import sys
from datetime import date
from importlib.metadata import distributions


def locked_requirements() -> list[str]:
    pins = set()
    for dist in distributions():
        if not str(dist._path).endswith(".dist-info"):
            continue
        version = dist.version.removesuffix("+cpu")
        pins.add(f"{dist.metadata['Name'].lower()}=={version}")
    return sorted(pins)


if __name__ == "__main__":
    print(
        f"# Exact versions resolved from requirements.in on {date.today()} "
        f"(python {sys.version_info.major}.{sys.version_info.minor}); regenerate with ./dombot lock"
    )
    print("\n".join(locked_requirements()))

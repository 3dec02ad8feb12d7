"""Test-session settings shared by every package's tests.

Each pytest session gets its own ROS domain and keeps DDS discovery on the
loopback interface, so concurrent sessions (or a developer's running nodes) never
see each other's topics.
"""

from __future__ import annotations

import os

os.environ.setdefault("ROS_DOMAIN_ID", str(10 + os.getpid() % 90))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
os.environ.setdefault("MPLBACKEND", "Agg")

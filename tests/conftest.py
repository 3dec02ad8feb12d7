"""Test-session settings shared by every package's tests.

Every pytest process that runs tests (the session, or each pytest-xdist worker) holds a
ROS domain of its own while it lives and keeps DDS discovery on the loopback interface,
so parallel workers, concurrent sessions and a developer's running nodes never see each
other's topics.

With pytest-xdist (on by default, see pyproject.toml) a module's tests run on one worker,
so a module-scoped fixture (a node process, a planner) is set up once; a module marked
``spread`` lets its independent tests run on several workers. Slow tests are handed out
first, so the longest ones do not start last.
"""

from __future__ import annotations

import fcntl
import os
import tempfile
from pathlib import Path

import pytest

# Domain ids whose Fast DDS ports are valid and outside Linux's ephemeral port range
# (ROS 2 docs, "The ROS_DOMAIN_ID"); 0, the default, is left to a developer's own nodes.
# 10-99 come last: benchmarks/bench_fuzz.py takes 10 + pid % 90 without a lock.
DOMAINS = (*range(1, 10), 100, 101, *range(215, 233), *range(10, 100))
_held: list[int] = []  # open lock files: each domain is held until the process ends


def _hold_a_free_domain() -> int:
    """A domain that no other test process on this machine holds, locked for the life of
    this process (the kernel drops the lock however the process ends)."""
    for domain in DOMAINS:
        path = Path(tempfile.gettempdir()) / f"dombot-test-ros-domain-{domain}.lock"
        try:
            handle = os.open(path, os.O_CREAT | os.O_RDWR, 0o666)
        except OSError:
            continue  # another user's lock file
        try:
            fcntl.flock(handle, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except OSError:
            os.close(handle)
            continue
        _held.append(handle)
        return domain
    raise RuntimeError(f"all {len(DOMAINS)} ROS domains are held by other test processes")


os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
os.environ.setdefault("RMW_IMPLEMENTATION", "rmw_fastrtps_cpp")
os.environ.setdefault("MPLBACKEND", "Agg")


def pytest_configure(config: pytest.Config) -> None:
    # The xdist controller runs no tests and needs no domain; its workers each take one.
    if "PYTEST_XDIST_WORKER" in os.environ or getattr(config.option, "dist", "no") == "no":
        os.environ["ROS_DOMAIN_ID"] = str(_hold_a_free_domain())


@pytest.hookimpl(tryfirst=True)  # before xdist reads the groups
def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    for item in items:
        if not item.get_closest_marker("xdist_group") and not item.get_closest_marker("spread"):
            item.add_marker(pytest.mark.xdist_group(item.path.stem))  # one worker per module
    if "PYTEST_XDIST_WORKER" in os.environ:  # the controller hands out in this order
        slow_modules = {item.path for item in items if item.get_closest_marker("slow")}
        items.sort(key=lambda item: item.path not in slow_modules)  # stable: modules stay whole

"""Test-session settings shared by every package's tests.

Every pytest process that runs tests (the session, or each pytest-xdist worker) holds a
ROS domain of its own while it lives and keeps DDS discovery on the loopback interface,
so parallel workers, concurrent sessions and a developer's running nodes never see each
other's topics.

``./dombot test`` runs the tests in two pytest-xdist workers (``-n 2 --dist loadscope``;
``-n 0``: in one process). A module's tests run on one worker, so a module-scoped fixture
(a node process, a planner) is set up once; the modules in ``SPREAD`` let their
independent tests run on several workers. The suite's wall time is its slower worker's:
work is handed out costliest first by the CPU each module took in a whole run
(``CPU_S``), a worker is given more only when it is about to run out, and the cheap
modules come last to even out the two workers' ends.
"""

from __future__ import annotations

import fcntl
import os
import signal
import tempfile
from pathlib import Path

import pytest
import rclpy

# Domain ids whose Fast DDS ports are valid and outside Linux's ephemeral port range
# (ROS 2 docs, "The ROS_DOMAIN_ID"); 0, the default, is left to a developer's own nodes.
# 10-99 come last: benchmarks/bench_fuzz.py takes 10 + pid % 90 without a lock.
DOMAINS = (*range(1, 10), 100, 101, *range(215, 233), *range(10, 100))
_held: list[int] = []  # open lock files: each domain is held until the process ends
# Modules whose tests share no costly fixture and take long each: their tests may run on
# different workers (any other module's tests run on one, its module fixtures set up once).
SPREAD = {
    "tests/description/test_console.py",  # each test starts and interrupts a process
    "tests/foundation/test_parameter_files.py",  # each test starts a node
    "tests/sim/test_physics.py",  # a Drake world of its own per test, a quarter of the suite
}
# CPU seconds of each module's tests in a whole run at 81a0a7a (user + sys of its worker
# and the children it waited for; docs/SPEED.md, the test-suite row). Modules not listed
# took less than 4 s: they are handed out after these, those with slow tests first.
CPU_S = {
    "tests/bringup/test_arm_job.py": 134.5,
    "tests/bringup/test_partial_build.py": 77.9,
    "tests/sim/test_physics.py": 53.5,
    "tests/reliability/test_fuzz.py": 45.8,
    "tests/planner/test_execution.py": 25.7,
    "tests/perception/test_struck_run.py": 22.3,
    "tests/ros2cli/test_ros2cli.py": 20.0,
    "tests/planner/test_curved_runs.py": 17.0,
    "tests/planner/test_planner.py": 14.4,
    "tests/bringup/test_layer_job.py": 11.4,
    "tests/sim/test_sim_node.py": 10.8,
    "tests/bringup/test_sim_cell.py": 10.7,
    "tests/sim/test_still_cell.py": 10.2,
    "tests/bringup/test_recording.py": 10.0,
    "tests/perception/test_perception_node.py": 9.1,
    "tests/description/test_console.py": 8.6,
    "tests/layer/test_vehicle_sim.py": 8.6,
    "tests/planner/test_planner_node.py": 8.3,
    "tests/perception/test_placement_check.py": 7.8,
    "tests/planner/test_published_trajectories.py": 7.2,
    "tests/foundation/test_parameter_files.py": 7.2,
    "tests/bringup/test_pile_view.py": 7.4,
    "tests/planner/test_stretch_start.py": 5.1,
    "tests/bringup/test_task.py": 4.3,
}


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
# A shell without job control starts a background job (`cmd &` in a script, CI runners,
# nohup) with SIGINT ignored, and every child inherits that: the node processes the tests
# stop with SIGINT, as Ctrl-C or the bring-up does, ignored it (test_console's Ctrl-C
# tests waited out their timeouts). The tests' children start as from a terminal.
if signal.getsignal(signal.SIGINT) is signal.SIG_IGN:
    signal.signal(signal.SIGINT, signal.default_int_handler)


def pytest_configure(config: pytest.Config) -> None:
    # The xdist controller runs no tests and needs no domain; its workers each take one.
    if "PYTEST_XDIST_WORKER" in os.environ or getattr(config.option, "dist", "no") == "no":
        os.environ["ROS_DOMAIN_ID"] = str(_hold_a_free_domain())


def pytest_xdist_make_scheduler(config: pytest.Config, log):
    """--dist loadscope, with a module's tests on one worker unless it is in SPREAD, handed
    out in the order pytest_collection_modifyitems gives (xdist's default, the modules with
    most tests first, started the one-test end-to-end modules last), each unit to the worker
    that runs out first."""
    if config.getvalue("dist") != "loadscope":
        return None
    from xdist.scheduler import LoadScopeScheduling

    config.option.loadscopereorder = False

    class ModuleScheduling(LoadScopeScheduling):
        def _split_scope(self, nodeid: str) -> str:
            module = nodeid.split("::", 1)[0]
            return nodeid if module in SPREAD else module

        def _reschedule(self, node) -> None:
            # xdist gives a worker more once two of its tests are left, so the next unit
            # waits behind a running test however long while the other worker may be free
            # first. A worker runs a test once it holds the next (or is told to stop): one
            # left is when it needs more.
            if not self.workqueue or self._pending_of(self.assigned_work[node]) <= 1:
                super()._reschedule(node)

    return ModuleScheduling(config, log)


@pytest.fixture(scope="module", autouse=True)
def _no_ros_context_left_behind():
    """A module fixture that fails between its rclpy.init() and rclpy.shutdown() left the
    default context initialised, and every later module's rclpy.init() in that process
    failed ('Context.init() must only be called once': 61 errors after one failure)."""
    yield
    if rclpy.ok():
        rclpy.shutdown()


def _module(item: pytest.Item) -> str:
    return item.nodeid.split("::", 1)[0]


def pytest_collection_modifyitems(items: list[pytest.Item]) -> None:
    if "PYTEST_XDIST_WORKER" in os.environ:  # the controller hands out in this order
        slow_modules = {_module(item) for item in items if item.get_closest_marker("slow")}

        def rank(item: pytest.Item) -> tuple[float, bool]:
            module = _module(item)
            return -CPU_S.get(module, 0.0), module not in slow_modules

        items.sort(key=rank)  # stable: modules stay whole

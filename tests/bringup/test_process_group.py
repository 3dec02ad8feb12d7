"""The bring-up's process supervisor: prefixed logs, death reports, restarts, clean stop."""

from __future__ import annotations

import contextlib
import io
import os
import signal
import subprocess
import sys
import time

import pytest

from dombot_bringup.process_group import MAX_RESTARTS, NodeDiedError, ProcessGroup

SLEEPER = "import time, sys\nprint('ready', flush=True)\nwhile True: time.sleep(0.1)"
CRASHER = "import sys\nfor i in range(30): print(f'line {i}', flush=True)\nsys.exit(3)"
IGNORES_SIGINT = (
    "import signal, time\nsignal.signal(signal.SIGINT, signal.SIG_IGN)\n"
    "print('stubborn', flush=True)\nwhile True: time.sleep(0.1)"
)


def python(code: str) -> list[str]:
    return [sys.executable, "-c", code]


def test_output_is_forwarded_with_the_node_name() -> None:
    sink = io.StringIO()
    with ProcessGroup(sink=sink) as group:
        sleeper = group.start("sleeper", python(SLEEPER))
        group.wait_until(lambda: "ready" in sleeper.tail, timeout=20, what="sleeper output")
    assert "[sleeper] ready" in sink.getvalue()


def test_a_dead_node_is_reported_with_exit_code_and_last_lines() -> None:
    with ProcessGroup(sink=io.StringIO()) as group:
        group.start("sleeper", python(SLEEPER))
        group.start("crasher", python(CRASHER))
        with pytest.raises(NodeDiedError) as died:
            group.wait_until(lambda: False, timeout=20, what="nothing")
    assert died.value.name == "crasher"
    assert died.value.returncode == 3
    assert died.value.tail[-1] == "line 29"
    assert len(died.value.tail) == 20
    assert "exit code 3" in str(died.value)


def test_a_restartable_node_that_dies_is_started_again_until_it_used_its_restarts() -> None:
    sink = io.StringIO()
    with ProcessGroup(sink=sink) as group:
        sleeper = group.start("sleeper", python(SLEEPER), restartable=True)
        for restart in range(1, MAX_RESTARTS + 1):
            group.wait_until(lambda: sleeper.returncode is None, timeout=20, what="a start")
            killed = sleeper.process.pid
            sleeper.signal(9)
            sleeper.wait(timeout=20)
            group.check()
            assert sleeper.process.pid != killed
            assert group.restarts() == {"sleeper": restart}
        sleeper.signal(9)
        sleeper.wait(timeout=20)
        with pytest.raises(NodeDiedError) as died:
            group.check()
    assert died.value.name == "sleeper" and died.value.returncode == -9
    assert (
        f"[bringup] node 'sleeper' died with exit code -9; starting it again "
        f"(restart 1 of {MAX_RESTARTS})" in sink.getvalue().splitlines()
    )


def test_stop_escalates_past_a_process_that_ignores_sigint() -> None:
    group = ProcessGroup(sink=io.StringIO(), stop_timeout=1.0)
    stubborn = group.start("stubborn", python(IGNORES_SIGINT))
    group.wait_until(lambda: "stubborn" in stubborn.tail, timeout=20, what="start")
    codes = group.stop()
    assert codes["stubborn"] is not None and codes["stubborn"] < 0


def test_timeout_names_what_was_awaited() -> None:
    with ProcessGroup(sink=io.StringIO()) as group:
        group.start("sleeper", python(SLEEPER))
        with pytest.raises(TimeoutError, match="the planner service"):
            group.wait_until(lambda: False, timeout=0.5, what="the planner service")


def test_nodes_do_not_outlive_a_killed_supervisor(tmp_path) -> None:
    """A supervisor killed with SIGKILL cannot stop its nodes; the kernel does (pdeathsig)."""
    pid_file = tmp_path / "child.pid"
    supervisor = (
        "import sys, time\n"
        "from dombot_bringup.process_group import ProcessGroup\n"
        "group = ProcessGroup()\n"
        f"child = group.start('sleeper', [sys.executable, '-c', {SLEEPER!r}])\n"
        # Only once the node has printed: a write to the dead supervisor's pipe would kill
        # it with SIGPIPE and pass this test for the wrong reason.
        "group.wait_until(lambda: 'ready' in child.tail, timeout=20, what='ready')\n"
        f"open({str(pid_file)!r}, 'w').write(str(child.process.pid))\n"
        "time.sleep(60)\n"
    )
    process = subprocess.Popen(python(supervisor), stdout=subprocess.DEVNULL)
    deadline = time.monotonic() + 20
    while not pid_file.exists() or not pid_file.read_text():
        assert time.monotonic() < deadline, "the supervisor never started its node"
        time.sleep(0.05)
    child = int(pid_file.read_text())
    os.kill(child, 0)  # alive
    process.kill()
    process.wait()
    deadline = time.monotonic() + 10
    while _alive(child):
        assert time.monotonic() < deadline, "the node outlived its killed supervisor"
        time.sleep(0.05)


STUBBORN = (
    "import signal, time\n"
    "for s in (signal.SIGINT, signal.SIGTERM): signal.signal(s, signal.SIG_IGN)\n"
    "print('ready', flush=True)\nwhile True: time.sleep(0.1)"
)
# the bring-up's shape: nodes started, rclpy initialised, the job waiting for an answer
BRINGUP_LIKE = """
import sys, time
import rclpy
from dombot_bringup.process_group import ProcessGroup
try:
    with ProcessGroup(stop_timeout=1.0) as group:
        children = [group.start('sleeper', [sys.executable, '-c', {sleeper!r}]),
                    group.start('stubborn', [sys.executable, '-c', {stubborn!r}])]
        rclpy.init()
        group.wait_until(lambda: all('ready' in c.tail for c in children), 60, 'ready')
        pids = ' '.join(str(c.process.pid) for c in children)
        open({pid_file!r}, 'w').write(pids)
        time.sleep(600)
except KeyboardInterrupt:
    sys.exit(130)
"""


@pytest.mark.parametrize(
    ("to", "signum"),
    [
        ("supervisor", signal.SIGTERM),
        ("supervisor", signal.SIGINT),
        ("group", signal.SIGTERM),
        ("group and supervisor", signal.SIGTERM),  # `ros2 run` forwards the group's
    ],
)
def test_a_signal_to_the_supervisor_stops_every_node(tmp_path, to: str, signum: int) -> None:
    """As the bring-up: nodes in sessions of their own (a kill of the bring-up's process
    group does not reach them), rclpy initialised (its SIGTERM handler alone only shut its
    context down), the job waiting for an answer; one node ignores SIGINT and SIGTERM.
    A SIGTERM (CI, kill) or SIGINT (Ctrl-C) stops them all, the stubborn one with SIGKILL."""
    pid_file, output = tmp_path / "children.pid", tmp_path / "supervisor.out"
    supervisor = BRINGUP_LIKE.format(sleeper=SLEEPER, stubborn=STUBBORN, pid_file=str(pid_file))
    with output.open("w") as sink:
        process = subprocess.Popen(python(supervisor), stdout=sink, start_new_session=True)
    children: list[int] = []
    try:
        deadline = time.monotonic() + 60
        while not pid_file.exists() or not pid_file.read_text():
            assert process.poll() is None, output.read_text()
            assert time.monotonic() < deadline, "the supervisor never started its nodes"
            time.sleep(0.05)
        children = [int(pid) for pid in pid_file.read_text().split()]
        if "group" in to:
            os.killpg(process.pid, signum)
        if "supervisor" in to:
            process.send_signal(signum)
        assert process.wait(timeout=120) == 130, output.read_text()
        deadline = time.monotonic() + 30
        while any(_alive(child) for child in children):
            assert time.monotonic() < deadline, f"nodes outlived the stop: {output.read_text()}"
            time.sleep(0.05)
    finally:  # a failed test leaves nothing running (the stubborn one ignores pdeathsig's)
        for pid in [process.pid, *children]:
            with contextlib.suppress(ProcessLookupError):
                os.kill(pid, signal.SIGKILL)
        process.wait()
    lines = output.read_text().splitlines()
    assert f"[bringup] {signal.Signals(signum).name}: stopping the nodes" in lines
    assert "[bringup] stubborn still running after 1 s: sending SIGKILL" in lines


def _alive(pid: int) -> bool:
    try:
        os.kill(pid, 0)
    except ProcessLookupError:
        return False
    # A zombie (exited, not yet reaped by init) counts as gone.
    with open(f"/proc/{pid}/stat") as stat:
        return stat.read().split()[2] != "Z"

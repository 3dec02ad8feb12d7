"""The bring-up's process supervisor: prefixed logs, death reports, clean stop."""

from __future__ import annotations

import io
import sys

import pytest

from dombot_bringup.process_group import NodeDiedError, ProcessGroup

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

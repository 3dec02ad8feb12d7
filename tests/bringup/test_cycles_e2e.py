"""The perpetual cycle end to end over DDS with real node processes: a line of two is
built from the pile, knocked down, and built again from the toppled dominoes perception
sees lying in the build area; each cycle reported.

Two dominoes, not the README's three: the cycle does for two what it does for three (the
second cycle offers each slot its nearest toppled domino first, the one lying over the
next slot included; ``test_cycles.py`` checks that order for three without ROS), with a
third less physics to step (28 s simulated instead of 43). The pile keeps one spare."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from support.planning_clock import UNHURRIED
from support.ros_processes import executable_path

BRINGUP = executable_path("dombot_bringup", "bringup")
LINE_OF_TWO_TWICE = [
    *("--layout", "line", "--start", "0.5", "0.1", "--heading", "90", "--count", "2"),
    *("--pile", "3", "--seed", "0", "--cycles", "2", "--real-time-factor", "0"),
    *("--plan-budget", str(UNHURRIED)),  # a refusal is the planner's search, not the clock
]


@pytest.mark.slow
@pytest.mark.timeout(2400)
def test_a_toppled_line_is_built_again_from_its_own_dominoes(tmp_path: Path) -> None:
    log = tmp_path / "bringup.log"  # the job's and its nodes' lines, as they come
    with log.open("w") as sink:
        result = subprocess.run(
            [str(BRINGUP), "--out", str(tmp_path), *LINE_OF_TWO_TWICE],
            stdout=sink,
            stderr=subprocess.PIPE,
            text=True,
            timeout=2300,
            stdin=subprocess.DEVNULL,
        )
    stdout = log.read_text()
    output = stdout[-8000:] + result.stderr[-4000:]
    assert "Traceback" not in result.stderr, output
    report = json.loads((tmp_path / "run_report.json").read_text())
    one, two = report["cycles"]
    assert result.returncode == report["summary"]["exit_status"], output
    # cycle 1: the line from the pile, knocked down, every domino seen down
    assert (one["cycle"], one["placed"], one["dominoes"], one["toppled_found"]) == (1, 2, 2, 0)
    assert one["toppled_by_perception"] == 2 and one["exit_status"] == 0, one
    # cycle 2: perception found both toppled ones lying and the arm picked them up again
    assert two["toppled_found"] == 2 and two["toppled_picked"] == 2, two
    assert two["placed"] == 2 and two["toppled_by_perception"] == 2, two
    assert result.returncode == 0, output
    # every node's memory at each cycle's end
    for cycle in (one, two):
        assert {"bringup", "sim_node", "planner_node"} <= set(cycle["rss_mb"]), cycle
    # each cycle's own report beside the combined one, and a line each in the log
    for number in (1, 2):
        own = json.loads((tmp_path / f"cycle{number}" / "run_report.json").read_text())
        assert own["cycles"][-1]["cycle"] == number
    lines = [line for line in stdout.splitlines() if "[bringup] cycle " in line]
    assert any(line.split("] ")[1].startswith("cycle 2/2 'line': SUCCESS") for line in lines)
    assert stdout.count("[bringup] poured") == 1  # the pile is poured once

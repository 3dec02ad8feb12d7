"""A partial build end to end over DDS with real node processes: a slot no placement
reaches is left empty, the run is built around it and what stands is knocked down in
sections; the job exits 3."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from support.planning_clock import UNHURRIED
from support.ros_processes import executable_path

BRINGUP = executable_path("dombot_bringup", "bringup")
# The spiral's first five at 22 mm spacing, a safety gap at the 3rd and 4th (--section 2;
# two slots wide at this spacing), filled last: the 4th, between the standing 3rd and 5th,
# is so close to both that every place pose has the pads in a standing neighbour (the
# planner proves it: PLACE_UNREACHABLE, "pads–standing"; at the default spacing the
# flatter grasps now reach such a slot), while the others, placed with a side free, plan.
# (A spiral of 6 had its gap at the 5th: the user's run of issue 23 that ended with
# nothing toppled.) Asked before the build (task.gaps), the planner refuses the 4th between
# its neighbours and the gap is dropped (5 of 5 placed); kept as laid out, the gap stays.
SPIRAL_WITH_A_GAP_NOTHING_REACHES = [
    "--layout",
    "spiral",
    "--count",
    "5",
    "--spacing",
    "0.022",
    "--section",
    "2",
    "--gaps-as-laid-out",  # asked first, the planner refuses the 4th: the gap is dropped
    "--pile",
    "8",
    "--seed",
    "1",
    "--spreads",  # the refusals are about the slot: pushing the pile apart cannot help
    "0",
    "--real-time-factor",
    "0",
    "--plan-budget",  # a refusal is the planner's search, never a loaded machine's clock
    str(UNHURRIED),
]


@pytest.mark.timeout(1800)
def test_a_slot_no_placement_reaches_is_left_empty_and_what_stands_is_knocked_down(
    tmp_path: Path,
) -> None:
    result = subprocess.run(
        [str(BRINGUP), "--out", str(tmp_path), *SPIRAL_WITH_A_GAP_NOTHING_REACHES],
        capture_output=True,
        text=True,
        timeout=1700,
        stdin=subprocess.DEVNULL,
    )
    output = result.stdout[-6000:] + result.stderr[-4000:]
    assert result.returncode == 3, output
    assert "PARTIAL" in result.stderr and "Traceback" not in result.stderr, output
    report = json.loads((tmp_path / "run_report.json").read_text())
    [empty] = report["empty_slots"]
    assert empty["slot"] == 4, report["empty_slots"]
    # the planner said why: no place pose for the slot (refusals about the dominoes offered,
    # GRASP_UNREACHABLE, may come with it)
    assert "PLACE_UNREACHABLE x" in empty["reason"], empty
    assert report["dominoes"][3]["refusals"]["PLACE_UNREACHABLE"] >= 1, report["dominoes"][3]
    assert report["message"].startswith("domino 4 could not be placed ("), report["message"]
    assert not report["built"] and report["struck"]
    sections = [
        (s["first_slot"], s["last_slot"], s["struck"], s["toppled_by_perception"])
        for s in report["sections"]
    ]
    assert sections == [(1, 3, True, 3), (5, 5, True, 1)], report["sections"]
    # struck from the run's end backwards: the lone 5th first, then the 1st to 3rd
    lines = result.stdout.splitlines()
    strikes = [line for line in lines if "[bringup] knocking down" in line]
    assert [line.split("knocking down ")[1] for line in strikes] == ["domino 5", "dominoes 1-3"]
    # the simulator's truth: four stood upright before the strikes, every one fell
    assert report["summary"]["standing_before_strike_by_truth"] == 4
    assert report["toppled_by_perception"] and report["toppled_by_truth"]
    for domino in report["dominoes"]:
        if domino["index"] == 3:
            assert not domino["placed"] and domino["truth_after_strike"] is None, domino
            continue
        assert domino["placed"] and domino["truth_built"]["tilt_deg"] < 10.0, domino
        assert domino["truth_after_strike"]["tilt_deg"] > 45.0, domino
    assert report["summary"]["exit_status"] == 3

"""The safety gaps of s_curve30 (22 mm spacing) asked of the real planner in-process
(issue 23): its first gap's last slot, which the bring-up left empty, is refused between
its two standing neighbours and plans with one, so ``task.gaps`` drops the gap from real
geometry, not a script.

The first 10 slots of bench_bringup's s_curve30 are the same as its first 10 of 30 (the
curve is sampled by arc length from its start): one gap, slots 5 and 6.
"""

from __future__ import annotations

import math
from dataclasses import replace

import pytest

from dombot_bringup import layouts
from dombot_bringup.task.cell import Detection, Posture
from dombot_bringup.task.gaps import gap_slots
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_description.grasp import flat_pose
from dombot_description.scenario import load_scenario
from dombot_planner.errors import ErrorCode
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.settings import PlannerSettings
from support.in_process_planner import in_process
from support.planning_clock import UNHURRIED
from support.scripted_cell import ScriptedCell

pytestmark = pytest.mark.slow  # a few KTO plans and refusals

SCENARIO = load_scenario()
# as bench_bringup's s_curve30: --start 0.46 -0.08 --heading 75 --length 0.6
# --amplitude 0.08 --spacing 0.022, its first 10 slots
S_CURVE = layouts.s_curve((0.46, -0.08), math.radians(75), 0.6, 0.08, 10, 0.022)
PILE_DOMINO = flat_pose(*SCENARIO.pile_center, 2.4).GetAsMatrix4()


@pytest.fixture(scope="module")
def planner() -> PickPlacePlanner:
    return PickPlacePlanner(SCENARIO, PlannerSettings(default_time_budget=UNHURRIED))


def test_s_curve30s_first_gap_cannot_be_filled_between_its_neighbours_and_is_dropped(
    planner,
) -> None:
    assert layouts.safety_gaps(S_CURVE, ArmJobSettings.section) == [range(4, 6)]
    cell = ScriptedCell(
        pile=[Detection(PILE_DOMINO, Posture.FLAT, score=0.9, clearance=0.01)],
        place=in_process(planner),
    )
    job = Job.new(cell, S_CURVE, "s_curve", ArmJobSettings(plan_budget=UNHURRIED))
    assert gap_slots(job) == []  # dropped: built in run order
    (decision,) = job.report.safety_gaps
    assert (decision.slots, decision.verdict, decision.now) == ([5, 6], "dropped", [])
    # slot 6 as laid out, then the gap one slot on (its last slot 7) and one back (5)
    asked = cell.place_requests
    assert [next(i for i, r in enumerate(job.releases) if r is q.place) for q in asked] == [5, 6, 4]
    assert decision.plans == 3
    assert decision.why.startswith("PLACE_UNREACHABLE at place")
    # the pads meet the neighbours: what the bring-up met at slot 6
    between = in_process(planner)(asked[0])
    assert between.error == ErrorCode.PLACE_UNREACHABLE
    assert "pads–standing" in between.message
    # with one neighbour standing (slots 1-5 built, as in run order) slot 6 plans
    one_side = replace(asked[0], standing=tuple(job.targets[:5]))
    assert in_process(planner)(one_side).success

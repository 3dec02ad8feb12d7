"""Slot 3 of the s-curve of 10 at 22 mm, asked of the real planner in-process (issue 23):
refused with the 2nd standing, planned with the 4th, so the bring-up builds it before the
2nd (``task.order``) and every slot has a side free at its turn.

`bringup --layout s-curve --count 10 --spacing 0.022` turns towards the arm near its
inner reach (slot 3 is 0.427 m from the base axis). A canonical or flatter hold stands
the gripper 22-27° from vertical, leaning over one neighbour. Leaning over the 4th (the
free side in run order) puts the wrist 0.404 m from the shoulder, inside the 0.410 m the
elbow's limit allows: no IK, or the line up leaves the reach. Leaning over the 2nd, the
closed pads are 0.2-0.5 mm into it at 22 mm (2 mm required). With the 2nd not yet
standing that lean plans.
"""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform

from dombot_bringup import layouts
from dombot_bringup.task.cell import Detection, Posture
from dombot_bringup.task.geometry import placement_pose
from dombot_bringup.task.order import build_order
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_description.grasp import flat_pose
from dombot_description.scenario import load_scenario
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings
from support.in_process_planner import in_process
from support.planning_clock import UNHURRIED
from support.scripted_cell import ScriptedCell

pytestmark = pytest.mark.slow  # a few KTO plans and refusals

SCENARIO = load_scenario()
# as `bringup --layout s-curve --count 10 --spacing 0.022` (the s-curve's defaults)
S_CURVE = layouts.s_curve((0.45, 0.0), math.radians(90), 0.45, 0.05, 10, 0.022)
PILE_DOMINO = flat_pose(*SCENARIO.pile_center, 2.4)


@pytest.fixture(scope="module")
def planner() -> PickPlacePlanner:
    return PickPlacePlanner(SCENARIO, PlannerSettings(default_time_budget=UNHURRIED))


def slot3(standing: tuple[int, ...]) -> PickPlaceRequest:
    """The bring-up's request for slot 3 with ``standing`` slots (1-based) built."""
    return PickPlaceRequest(
        PILE_DOMINO,
        RigidTransform(placement_pose(S_CURVE[2], ArmJobSettings.place_lead)),
        SCENARIO.home_position,
        standing=tuple(RigidTransform(placement_pose(S_CURVE[n - 1])) for n in standing),
    )


def test_slot3_lies_near_the_inner_reach_limit() -> None:
    assert math.hypot(S_CURVE[2].x, S_CURVE[2].y) == pytest.approx(0.427, abs=5e-4)


@pytest.mark.parametrize("standing", [(2,), (2, 4)])
def test_with_the_2nd_standing_no_hold_places_it(planner, standing) -> None:
    """Leaning over the 4th the wrist is out of the elbow's reach, over the 2nd the pads
    meet it."""
    with pytest.raises(PlanningError) as caught:
        planner.plan(slot3(standing))
    assert caught.value.code == ErrorCode.PLACE_UNREACHABLE
    assert "in collision at the pose (pads–standing)" in caught.value.message
    assert "the wrist beyond the elbow's reach" in caught.value.message


@pytest.mark.parametrize("standing", [(), (4,)])
def test_with_the_2nd_not_yet_standing_it_plans_leaning_over_its_place(planner, standing) -> None:
    plan = planner.plan(slot3(standing))
    approach = plan.release_pose.rotation().matrix()[:, 2]
    towards_2nd = np.array([S_CURVE[1].x - S_CURVE[2].x, S_CURVE[1].y - S_CURVE[2].y])
    assert float(-approach[:2] @ towards_2nd) > 0.0  # the gripper body over the 2nd's side


def test_the_bring_up_starts_the_run_at_the_4th(planner) -> None:
    """Asked before the build (``task.order``), the planner refuses the 4th with the 3rd
    standing (the last so, from the end backwards) and places the 3rd, 2nd and 1st each
    with the one ahead standing: the run is built 4, 3, 2, 1, then 5 to 10."""
    cell = ScriptedCell(
        pile=[Detection(PILE_DOMINO.GetAsMatrix4(), Posture.FLAT, score=0.9, clearance=0.01)],
        place=in_process(planner),
    )
    job = Job.new(cell, S_CURVE, "s_curve", ArmJobSettings(plan_budget=UNHURRIED))
    assert build_order(job, range(10)) == [3, 2, 1, 0, 4, 5, 6, 7, 8, 9]
    (decision,) = job.report.build_order
    assert (decision.start, decision.plans) == (4, 10)
    assert decision.behind.startswith("4: PLACE_UNREACHABLE at place")

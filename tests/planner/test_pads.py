"""Refusals told before any IK: the pads' place and path against the pile, the wrist's
reach, a hold with no place pose between standing neighbours (dombot_planner.pads,
foreseen_refusal) agree with the planner's answers."""

from __future__ import annotations

import dataclasses
from pathlib import Path

import numpy as np
import pytest
from pydrake.math import RigidTransform, RollPitchYaw, RotationMatrix

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import BoxArray, OrientedBox, flat_pose, pick_grasps, upright_pose
from dombot_description.scenario import load_scenario
from dombot_planner.arm_reach import WristReach
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.foreseen_refusal import NO_PLACE, foreseen_refusal, no_place
from dombot_planner.grasp_candidates import ranked_grasps
from dombot_planner.motion import WRIST_OUT, Deadline
from dombot_planner.pads import pads_in_pile
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.request_planning import RequestPlanning
from dombot_planner.settings import PlannerSettings
from dombot_planner.shared_work import SharedWork
from support.planning_clock import UNHURRIED

SCENARIO = load_scenario()
SETTINGS = PlannerSettings(default_time_budget=UNHURRIED)
DOMINO = flat_pose(0.60, -0.28, 0.4)
SIZE = np.asarray(DOMINO_SIZE)
PLACE = upright_pose(0.55, 0.15, 0.3)
SPACING = 0.6 * DOMINO_SIZE[0]  # a run's default (dombot_bringup.layouts)
BENCHMARKS = Path(__file__).parents[2] / "benchmarks"


@pytest.fixture(scope="module")
def planner() -> PickPlacePlanner:
    return PickPlacePlanner(SCENARIO, SETTINGS)


def beside(gap: float) -> tuple[RigidTransform, ...]:
    """Pile dominoes along both long faces of DOMINO, ``gap`` from them."""
    return tuple(DOMINO @ RigidTransform([0.0, side * (SIZE[1] + gap), 0.0]) for side in (-1, 1))


def pick(**changes) -> PickPlaceRequest:
    return dataclasses.replace(
        PickPlaceRequest(
            domino_pose=DOMINO,
            place_pose=PLACE,
            start=SCENARIO.home_position,
        ),
        **changes,
    )


def test_overlap_beyond_a_depth_is_the_penetration_depth() -> None:
    """Two boxes 3 mm into each other along x overlap beyond 2 mm, not beyond 4 mm; turned
    a box turned 45° about z with a corner 3 mm into its end face leaves it by 3 mm."""
    a = OrientedBox(RigidTransform(), SIZE)
    b = OrientedBox(RigidTransform([SIZE[0] - 0.003, 0.0, 0.0]), SIZE)
    assert a.overlaps(b, 0.002) and not a.overlaps(b, 0.004)
    turned = RotationMatrix.MakeZRotation(-np.pi / 4)  # its edges ±45° from x
    corner = np.array([SIZE[0] / 2 - 0.003, 0.0, 0.0])  # c's corner 3 mm inside a's end
    c = OrientedBox(RigidTransform(turned, corner + turned @ (SIZE * [0.5, 0.5, 0.0])), SIZE)
    assert a.overlaps(c, 0.0029) and not a.overlaps(c, 0.0031)


def test_overlapping_many_boxes_at_once_judges_each_as_alone() -> None:
    """The batched test gives each of 200 boxes about a box (random poses within a
    domino's length, seeded) the verdict it gives that box alone, at three tolerances, and
    both verdicts occur."""
    rng = np.random.default_rng(7)
    a = OrientedBox(RigidTransform(RotationMatrix(RollPitchYaw(rng.uniform(-3, 3, 3)))), SIZE)
    poses = [
        RigidTransform(RollPitchYaw(rng.uniform(-3, 3, 3)), rng.uniform(-0.05, 0.05, 3))
        for _ in range(200)
    ]
    boxes = BoxArray.of([OrientedBox(pose, SIZE * rng.uniform(0.2, 1.0, 3)) for pose in poses])
    for tolerance in (0.0, 0.002, 0.004):
        together = a.overlapping(boxes, tolerance)
        alone = [a.overlapping(BoxArray.of([box]), tolerance)[0] for box in boxes.boxes()]
        assert together.tolist() == alone
        assert 0 < together.sum() < len(poses)


def test_pads_in_pile_at_the_canonical_grasp() -> None:
    """Neighbours 4 mm beside the long faces take in the open pads (8 mm a side) beyond
    pile_nudge; 14 mm beside them they do not."""
    grasp = pick_grasps(DOMINO)[0]
    assert pads_in_pile(grasp, beside(0.004), SETTINGS.pile_nudge)
    assert not pads_in_pile(grasp, beside(0.014), SETTINGS.pile_nudge)
    assert not pads_in_pile(grasp, (), SETTINGS.pile_nudge)


@pytest.mark.parametrize(
    ("changes", "foreseen"),
    [
        ({"pile": beside(0.004)}, True),  # boxed in: no pad fits, tilted or from the top
        ({"pile": beside(0.014)}, False),  # the pads nudge them: it plans
        ({"pile": beside(0.004), "pads_into_pile": True}, False),  # the pads may reach in
        ({}, False),
    ],
)
def test_a_foreseen_refusal_is_the_planners(planner, changes: dict, foreseen: bool) -> None:
    """``foreseen_refusal`` says why only where the planner refuses the grasp."""
    request = pick(**changes)
    why = foreseen_refusal(request, SETTINGS)
    assert bool(why) == foreseen
    if foreseen:
        with pytest.raises(PlanningError) as refused:
            planner.plan(request)
        assert refused.value.code == ErrorCode.GRASP_UNREACHABLE


def test_the_pads_path_among_seen_points_is_foreseen() -> None:
    """Seen points filling the space around the domino (but its own) meet every grasp's
    pads' path, the regrasp's too."""
    grid = np.stack(np.meshgrid(*[np.arange(-0.05, 0.0501, 0.004)] * 2, [0.002]), -1)
    points = grid.reshape(-1, 3) + DOMINO.translation() * [1, 1, 0]
    why = foreseen_refusal(pick(pile_points=points), SETTINGS)
    assert "pads' path meets pile points" in why


@pytest.fixture(scope="module")
def recorded() -> list[PickPlaceRequest]:
    """The bring-up's recorded /plan_place requests (benchmarks/data/plan_requests.npz)."""
    with pytest.MonkeyPatch.context() as patch:
        patch.syspath_prepend(str(BENCHMARKS))
        from bench_plan_replay import DEFAULT_FILE, load_requests

        return load_requests(DEFAULT_FILE)


@pytest.mark.parametrize(
    ("index", "refused"),
    [
        (4, True),  # the pads' path on seen points, or the wrist beyond the elbow's reach
        (53, True),  # the pads in a pile domino, or the wrist beyond the elbow's reach
        (72, False),  # half its canonical grasps beyond the reach: the others plan
    ],
)
def test_the_wrist_beyond_reach_is_foreseen(
    planner, recorded: list[PickPlaceRequest], index: int, refused: bool
) -> None:
    """Recorded pile requests whose every grasp the pads' tests leave has the wrist beyond
    the elbow's reach, at the grasp or along every lift, are foreseen given the planner's
    wrist shell (not by the pads alone) and refused by the planner; one with half its
    grasps beyond the reach is not foreseen and plans."""
    request = dataclasses.replace(recorded[index], time_budget=UNHURRIED)
    reach = WristReach.of_scenario(SCENARIO)
    assert not foreseen_refusal(request, SETTINGS)
    why = foreseen_refusal(request, SETTINGS, reach)
    assert (WRIST_OUT in why) == refused
    if refused:
        with pytest.raises(PlanningError) as refusal:
            planner.plan(request)
        assert refusal.value.code == ErrorCode.GRASP_UNREACHABLE
        assert WRIST_OUT in refusal.value.message
    else:
        assert planner.plan(request).segments


def neighbours(*sides: int) -> tuple[RigidTransform, ...]:
    """Upright dominoes one SPACING before (-1) and after (1) PLACE along its run."""
    return tuple(PLACE @ RigidTransform([0.0, 0.0, side * SPACING]) for side in sides)


def test_a_steeper_hold_has_no_place_between_two_standing_neighbours(planner) -> None:
    """A safety gap filled last: the holds of the steeper grasps (the gripper leaning
    further over the run at place) have no place pose between two standing neighbours,
    the canonical and flatter ones have, and with one neighbour the steeper ones have too.
    The planner agrees: given one such grasp it reaches the domino and refuses every
    place pose for the pads' clearance to the neighbours."""
    gap = pick(standing=neighbours(-1, 1))
    canonical, (steeper, flatter) = ranked_grasps(gap, SETTINGS)
    assert steeper and all(no_place(gap, SETTINGS, grasp) for grasp in steeper)
    assert not any(no_place(gap, SETTINGS, grasp) for grasp in canonical + flatter)
    one_side = pick(standing=neighbours(-1))
    assert not any(no_place(one_side, SETTINGS, grasp) for grasp in steeper)
    for grasp in steeper[:2]:
        search = RequestPlanning(planner, gap, Deadline(UNHURRIED), SharedWork(planner), [grasp])
        with pytest.raises(PlanningError) as refused:
            search.plan()
        assert refused.value.code == ErrorCode.PLACE_UNREACHABLE
        assert "in collision at the pose (pads–standing)" in refused.value.message


@pytest.mark.parametrize("index", [124, 128])
def test_turned_holds_with_no_place_are_not_solved_for(
    planner, recorded: list[PickPlaceRequest], index: int
) -> None:
    """Recorded requests at a slot between standing neighbours where only steeper grasps
    pass the tests before IK, and their holds have no place pose: the planner refuses
    them without solving for those grasps (it solved their picks and places before,
    "2 turned grasps reach it, but no place pose suits their hold"), with the same code,
    and ``foreseen_refusal`` tells the refusal given the wrist shell."""
    request = dataclasses.replace(recorded[index], time_budget=UNHURRIED)
    why = foreseen_refusal(request, SETTINGS, WristReach.of_scenario(SCENARIO))
    assert NO_PLACE in why
    with pytest.raises(PlanningError) as refusal:
        planner.plan(request)
    assert refusal.value.code == ErrorCode.GRASP_UNREACHABLE
    assert NO_PLACE in refusal.value.message
    assert "turned grasps reach it" not in refusal.value.message

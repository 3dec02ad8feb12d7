"""The planning tiers of a request share their scenes and IK (shared_work.SharedWork): the
answers must be those of tiers that each search from scratch."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import flat_pose, upright_pose
from dombot_description.scenario import load_scenario
from dombot_planner import planner as planner_module
from dombot_planner.errors import PlanningError
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings
from dombot_planner.shared_work import SharedWork
from support.planning_clock import UNHURRIED

SCENARIO = load_scenario()
SETTINGS = PlannerSettings(default_time_budget=UNHURRIED)


class Unshared(SharedWork):
    """Every scene and IK program new, as each tier built its own before SharedWork."""

    def scene(self, *args, **kwargs):
        self._scenes.clear()
        self._iks.clear()
        return super().scene(*args, **kwargs)

    def ik(self, scene, rotation):
        self._iks.clear()
        return super().ik(scene, rotation)


@pytest.fixture(scope="module")
def planner() -> PickPlacePlanner:
    return PickPlacePlanner(SCENARIO, SETTINGS)


def sides(domino: RigidTransform, gap: float) -> tuple[RigidTransform, ...]:
    """Pile dominoes along both long faces, ``gap`` m from them."""
    return tuple(
        domino @ RigidTransform([0.0, side * (DOMINO_SIZE[1] + gap), 0.0]) for side in (-1, 1)
    )


def request(domino: RigidTransform, pile: tuple[RigidTransform, ...] = ()) -> PickPlaceRequest:
    """To a place between two standing neighbours (test_planner's)."""
    step = 0.6 * DOMINO_SIZE[0] * np.array([math.cos(0.3), math.sin(0.3)])
    return PickPlaceRequest(
        domino_pose=domino,
        place_pose=upright_pose(0.55, 0.15, 0.3),
        start=SCENARIO.home_position,
        standing=tuple(upright_pose(0.55 + s * step[0], 0.15 + s * step[1], 0.3) for s in (-1, 1)),
        pile=pile,
    )


def answer(planner: PickPlacePlanner, req: PickPlaceRequest) -> tuple:
    """Everything the node answers: the error's code, stage and message, or the plan's
    flags, poses and sampled segments."""
    try:
        plan = planner.plan(req)
    except PlanningError as error:
        return (error.code, error.stage, error.message)
    samples = [
        (s.label, s.gripper_after, s.gripper_position, s.times, s.positions)
        for s in plan.sampled(SETTINGS.sample_period)
    ]
    poses = (plan.grasp_pose.GetAsMatrix4(), plan.release_pose.GetAsMatrix4())
    return (plan.nudged, plan.regrasped, poses, samples)


def assert_same(shared: tuple, unshared: tuple) -> None:
    assert len(shared) == len(unshared)
    for a, b in zip(shared, unshared, strict=True):
        if isinstance(a, list):  # sampled segments
            assert len(a) == len(b)
            for sa, sb in zip(a, b, strict=True):
                assert sa[:3] == sb[:3]
                np.testing.assert_array_equal(sa[3], sb[3])
                np.testing.assert_array_equal(sa[4], sb[4])
        elif isinstance(a, tuple) and a and isinstance(a[0], np.ndarray):
            for pa, pb in zip(a, b, strict=True):
                np.testing.assert_array_equal(pa, pb)
        else:
            assert a == b


BOXED = flat_pose(0.60, -0.28, 0.4)
BEARING = math.atan2(-0.30, 0.55)
CASES = {
    # no grasp keeps the pads clear: planned by the nudging tier
    "nudged": request(BOXED, sides(BOXED, 0.014)),
    # boxed in: all three tiers fail (the message lists each tier's reasons)
    "refused": request(BOXED, sides(BOXED, 0.004)),
    # radial near the base: no tilted grasp reaches it, the regrasp plans
    "regrasped": request(flat_pose(0.545 * math.cos(BEARING), 0.545 * math.sin(BEARING), BEARING)),
}


@pytest.mark.parametrize("case", CASES)
def test_tiers_sharing_their_work_answer_as_tiers_searching_alone(
    planner, monkeypatch, case
) -> None:
    req = CASES[case]
    shared = answer(planner, req)
    with monkeypatch.context() as patch:
        patch.setattr(planner_module, "SharedWork", Unshared)
        unshared = answer(planner, req)
    if case == "refused":
        assert isinstance(shared[2], str) and "nudging the pile failed too" in shared[2]
    else:
        assert shared[:2] == (case == "nudged", case == "regrasped")
    assert_same(shared, unshared)


def test_a_scene_and_an_ik_program_are_built_once_per_request(planner) -> None:
    """The same dominoes at the same opening give the same scene; its IK programs are
    kept per orientation; a repeated solve or clearance query gives an equal answer."""
    req = CASES["nudged"]
    work = SharedWork(planner)
    scene = work.scene(0.03, req, target=req.domino_pose)
    assert work.scene(0.03, req, target=req.domino_pose) is scene
    assert work.scene(0.03, req) is not scene
    q = SCENARIO.home_position
    tcp = scene.tcp_pose(q)
    ik = work.ik(scene, tcp.rotation())
    assert work.ik(scene, tcp.rotation()) is ik
    first = scene.clearance(q)
    assert scene.clearance(q) == first
    solved = ik.solve(tcp.translation(), q, q)
    assert solved is not None
    np.testing.assert_array_equal(ik.solve(tcp.translation(), q, q), solved)

"""Requests the planner must refuse at once or shrink (issue 26, found by fuzzing over DDS):
budgets and obstacle lists beyond their maxima, start states with repeated names or
impossible velocities, places off the table, a 'held' domino that is not in the hand;
and retiming that stays within the joint limits at any sample."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest

from dombot_description.grasp import flat_pose, upright_pose
from dombot_description.scenario import load_scenario
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import (
    MAX_PILE_DOMINOES,
    MAX_PILE_POINTS,
    MAX_STANDING,
    PILE_NEIGHBOURHOOD,
    PickPlaceRequest,
    arm_positions,
    near_pick,
)
from dombot_planner.timing import JointLimits, retime

SCENARIO = load_scenario()
PICK = flat_pose(0.60, -0.28, 0.4)


@pytest.fixture(scope="module")
def planner() -> PickPlacePlanner:
    return PickPlacePlanner(SCENARIO)


def request(**changes) -> PickPlaceRequest:
    base = PickPlaceRequest(
        domino_pose=PICK, place_pose=upright_pose(0.55, 0.15, 0.3), start=SCENARIO.home_position
    )
    return dataclasses.replace(base, **changes)


def refusal(planner: PickPlacePlanner, req: PickPlaceRequest) -> PlanningError:
    """What ``check`` (the node's answer before queueing) says; ``plan`` says the same."""
    with pytest.raises(PlanningError) as caught:
        planner.check(req)
    return caught.value


@pytest.mark.parametrize(
    ("changes", "code", "words"),
    [
        ({"time_budget": 1e12}, ErrorCode.INVALID_REQUEST, "time_budget"),
        ({"time_budget": 1e300}, ErrorCode.INVALID_REQUEST, "time_budget"),
        ({"standing": (PICK,) * (MAX_STANDING + 1)}, ErrorCode.INVALID_REQUEST, "standing"),
        ({"pile": (PICK,) * (MAX_PILE_DOMINOES + 1)}, ErrorCode.INVALID_REQUEST, "pile_domino"),
        (
            {"pile_points": np.zeros((MAX_PILE_POINTS + 1, 3))},
            ErrorCode.INVALID_REQUEST,
            "pile_points",
        ),
        ({"domino_pose": flat_pose(-0.60, 0.0, 0.0)}, ErrorCode.OUTSIDE_WORKSPACE, "table top"),
        ({"place_pose": upright_pose(0.0, -0.72, 0.0)}, ErrorCode.OUTSIDE_WORKSPACE, "table top"),
    ],
    ids=["budget_1e12", "budget_1e300", "standing", "pile", "points", "behind_arm", "off_table"],
)
def test_refused_before_planning(planner, changes, code, words) -> None:
    error = refusal(planner, request(**changes))
    assert error.code == code
    assert words in error.message


def test_a_held_domino_far_from_the_tcp_is_not_in_the_hand(planner) -> None:
    """The arm at home, the 'held' domino at the place: 349 mm from the TCP."""
    with pytest.raises(PlanningError) as caught:
        planner.plan(request(holding=True, domino_pose=upright_pose(0.55, 0.15, 0.3)))
    assert caught.value.code == ErrorCode.INVALID_REQUEST
    assert "not in the hand" in caught.value.message


def test_far_pile_dominoes_and_points_are_dropped_and_all_when_holding() -> None:
    near, far = flat_pose(0.65, -0.28, 0.0), flat_pose(0.60, -0.28 + PILE_NEIGHBOURHOOD + 0.01, 0)
    points = np.array([[0.62, -0.28, 0.01], [0.2, 0.3, 0.01]])
    shrunk = near_pick(request(pile=(near, far), pile_points=points))
    assert shrunk.pile == (near,)
    assert shrunk.pile_points.tolist() == [points[0].tolist()]
    held = near_pick(request(pile=(near,), pile_points=points, holding=True))
    assert held.pile == () and len(held.pile_points) == 0


@pytest.mark.parametrize(
    ("names", "velocities", "words"),
    [
        ([*SCENARIO.arm_joints, SCENARIO.arm_joints[2]], [], "more than once"),
        (list(SCENARIO.arm_joints), [0.0] * 3, "velocities"),
        (list(SCENARIO.arm_joints), [0.0, 0.0, math.nan, 0, 0, 0, 0], "velocity"),
        (list(SCENARIO.arm_joints), [0.0, 0.0, 50.0, 0, 0, 0, 0], "velocity"),
    ],
    ids=["repeated_name", "velocity_length", "velocity_nan", "velocity_beyond_limit"],
)
def test_start_states_that_cannot_be_are_refused(planner, names, velocities, words) -> None:
    positions = [*SCENARIO.home_position, SCENARIO.home_position[2]][: len(names)]
    with pytest.raises(PlanningError) as caught:
        arm_positions(
            names,
            positions,
            SCENARIO.arm_joints,
            planner.lower,
            planner.upper,
            velocities=velocities,
            velocity_limits=planner.velocity_limits,
        )
    assert caught.value.code == ErrorCode.INVALID_REQUEST
    assert words in caught.value.message


def test_retimed_paths_stay_within_the_limits_at_every_sample(planner) -> None:
    """Random joint paths across the workspace, retimed: at most the limits (within the
    0.1 % the executor allows) at 2 ms samples, whatever TOPP-RA's grid saw."""
    from pydrake.trajectories import PiecewisePolynomial

    rng = np.random.default_rng(7)
    plant = planner.plants.get(0.024).plant
    limits = JointLimits(planner.limits.velocity, planner.limits.acceleration)
    for _ in range(12):
        knots = rng.uniform(planner.lower * 0.8, planner.upper * 0.8, (4, 7))
        path = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
            np.linspace(0, 1, 4), knots.T, np.zeros(7), np.zeros(7)
        )
        timed = retime("transfer", path, plant, limits)
        assert timed is not None
        _, velocity, acceleration = timed.sample(np.arange(0.0, timed.duration, 0.001))
        assert np.max(np.abs(velocity) / limits.velocity) <= 1.001
        assert np.max(np.abs(acceleration) / limits.acceleration) <= 1.001

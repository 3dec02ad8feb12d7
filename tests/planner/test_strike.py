"""The strike planner without ROS: plans checked by the independent verifier."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import flat_pose, release_opening, upright_pose
from dombot_description.scenario import load_scenario
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.plan_segments import GRIPPER_CLOSE, GRIPPER_NONE
from dombot_planner.request import StrikeRequest
from dombot_planner.settings import PlannerSettings
from dombot_planner.strike import StrikePlanner
from dombot_planner.verify import StrikeChecker
from support.planning_clock import UNHURRIED, jump_clock

SCENARIO = load_scenario()
SETTINGS = PlannerSettings(default_time_budget=UNHURRIED)
SPACING = 0.6 * DOMINO_SIZE[0]
OPEN = release_opening(DOMINO_SIZE[1])  # as a place leaves the fingers


def run_poses(x: float, y: float, heading: float, count: int = 4, spacing: float = SPACING):
    step = spacing * np.array([math.cos(heading), math.sin(heading)])
    return [upright_pose(*(np.array([x, y]) + i * step), heading) for i in range(count)]


def request(**changes) -> StrikeRequest:
    poses = run_poses(0.55, 0.15, 0.3)
    base = StrikeRequest(poses[0], SCENARIO.home_position, OPEN, tuple(poses[1:]))
    return dataclasses.replace(base, **changes)


@pytest.fixture(scope="module")
def planner() -> StrikePlanner:
    return StrikePlanner(SCENARIO, SETTINGS)


def check(plan, req: StrikeRequest):
    checker = StrikeChecker(SCENARIO, req.domino_pose, req.standing, SETTINGS.acceleration_limit)
    return checker.check(plan.sampled(SETTINGS.sample_period), req.start, req.finger_opening)


def failure(planner: StrikePlanner, req: StrikeRequest) -> PlanningError:
    with pytest.raises(PlanningError) as caught:
        planner.plan(req)
    return caught.value


@pytest.fixture(scope="module")
def planned(planner):
    req = request()
    plan = planner.plan(req)
    return req, plan, check(plan, req)


def test_plan_closes_the_gripper_then_approaches_pushes_and_retreats(planned) -> None:
    _, plan, _ = planned
    events = [(s.label, s.gripper_after) for s in plan.segments]
    assert events == [
        ("close_gripper", GRIPPER_CLOSE),
        ("approach", GRIPPER_NONE),
        ("push", GRIPPER_NONE),
        ("retreat", GRIPPER_NONE),
    ]
    assert plan.segments[0].gripper_position == 0.0
    assert not plan.segments[0].pieces  # closes where the arm is


def test_closed_start_needs_no_close_command(planner) -> None:
    plan = planner.plan(request(finger_opening=0.0005))
    assert [s.label for s in plan.segments] == ["approach", "push", "retreat"]


def test_approach_keeps_clear_of_table_and_every_domino(planned) -> None:
    _, _, result = planned
    for moving in ("arm", "pads"):
        for obstacle in ("table", "standing", "target"):
            assert result.min_clearance("approach", moving, obstacle) >= SETTINGS.coarse_clearance
        assert result.min_clearance("approach", moving, "self") >= 0.0
    assert result.samples > 300


def test_push_touches_only_the_struck_domino(planned) -> None:
    _, _, result = planned
    assert result.min_clearance("push", "pads", "target") < 0.0  # it is pushed
    assert result.min_clearance("push", "pads", "standing") >= SETTINGS.fine_obstacle_clearance
    for obstacle in ("table", "standing", "target"):
        assert result.min_clearance("push", "arm", obstacle) >= SETTINGS.coarse_clearance
    assert result.min_clearance("push", "pads", "table") >= SETTINGS.coarse_clearance
    for moving in ("arm", "pads"):
        assert result.min_clearance("retreat", moving, "standing") >= 0.002
        assert result.min_clearance("retreat", moving, "table") >= SETTINGS.coarse_clearance


def test_start_where_a_push_ended_is_left_straight_up_first(planner, planned) -> None:
    """Planned again from the end of its push (the pads where the struck domino stands,
    as if it had not fallen): first straight up out of it, no closer to the rest of the run,
    then the approach keeps its clearance."""
    _, plan, _ = planned
    push = plan.segments[2].pieces[-1]
    again_req = request(start=push.sample([push.duration])[0][0], finger_opening=0.0)
    again = planner.plan(again_req)
    assert [s.label for s in again.segments] == ["approach", "push", "retreat"]
    assert again.segments[0].pieces[0].label == "escape"
    result = check(again, again_req)
    assert result.min_clearance("escape", "pads", "standing") >= 0.0138 - 0.0005
    assert result.min_clearance("escape", "arm", "standing") >= SETTINGS.coarse_clearance
    for moving in ("arm", "pads"):
        for obstacle in ("table", "standing", "target"):
            assert result.min_clearance("approach", moving, obstacle) >= SETTINGS.coarse_clearance


def test_push_is_where_and_as_far_and_fast_as_wanted(planned) -> None:
    _, _, result = planned
    assert result.fingertip_height == pytest.approx(0.75 * DOMINO_SIZE[0], abs=1e-3)
    assert result.push_past_contact == pytest.approx(SETTINGS.push_distance, abs=1e-3)
    assert result.contact_speed == pytest.approx(SETTINGS.push_speed, rel=0.05)


def test_requested_push_distance_and_speed_are_used(planner) -> None:
    req = request(push_distance=0.008, push_speed=0.05)
    result = check(planner.plan(req), req)
    assert result.push_past_contact == pytest.approx(0.008, abs=1e-3)
    assert result.contact_speed == pytest.approx(0.05, rel=0.05)


def test_plan_respects_joint_limits_and_joins_without_jumps(planned) -> None:
    _, plan, result = planned
    assert result.position_limit_excess <= 1e-9
    assert result.velocity_use <= 1.003
    assert result.acceleration_use <= 1.003
    assert result.largest_jump <= 1e-9
    for segment in plan.sampled(SETTINGS.sample_period):
        if len(segment.times) > 1:
            assert np.abs(segment.velocities[[0, -1]]).max() <= 1e-6


def test_same_request_gives_the_same_plan(planner, planned) -> None:
    req, plan, _ = planned
    again = planner.plan(req)
    for a, b in zip(plan.sampled(0.05), again.sampled(0.05), strict=True):
        assert a.positions == pytest.approx(b.positions, abs=1e-9)


TILTED = RigidTransform(
    upright_pose(0.55, 0.15, 0.3).rotation() @ RotationMatrix.MakeYRotation(0.4),
    upright_pose(0.55, 0.15, 0.3).translation(),
)


@pytest.mark.parametrize(
    ("changes", "code"),
    [
        ({"time_budget": -1.0}, ErrorCode.INVALID_REQUEST),
        ({"push_distance": -0.01}, ErrorCode.INVALID_REQUEST),
        ({"push_speed": math.nan}, ErrorCode.INVALID_REQUEST),
        ({"push_speed": 2.0}, ErrorCode.INVALID_REQUEST),
        ({"domino_pose": flat_pose(0.55, 0.15, 0.3)}, ErrorCode.INVALID_REQUEST),
        ({"domino_pose": TILTED}, ErrorCode.INVALID_REQUEST),
        ({"domino_pose": upright_pose(1.2, 0.0, 0.0)}, ErrorCode.OUTSIDE_WORKSPACE),
        ({"domino_pose": upright_pose(0.84, 0.0, 0.0)}, ErrorCode.PLACE_UNREACHABLE),
        (
            {"standing": tuple(run_poses(0.55, 0.15, 0.3, spacing=0.004)[1:])},
            ErrorCode.PLACE_IN_COLLISION,
        ),
        (  # a domino stands right behind: no room for the pusher
            {
                "standing": (
                    *run_poses(0.55, 0.15, 0.3)[1:],
                    *run_poses(0.55, 0.15, 0.3 + math.pi, 2)[1:],
                )
            },
            ErrorCode.PLACE_IN_COLLISION,
        ),
        ({"push_distance": 0.03}, ErrorCode.PLACE_IN_COLLISION),  # reaches the next domino
        ({"start": np.array([0.0, 2.0, 0.0, 0.0, 0.0, 0.0, 0.0])}, ErrorCode.INVALID_REQUEST),
    ],
    ids=[
        "negative_budget",
        "negative_push",
        "nan_speed",
        "too_fast",
        "domino_flat",
        "domino_tilted",
        "domino_far",
        "out_of_reach",
        "overlaps_standing",
        "domino_behind",
        "push_reaches_next",
        "start_in_collision",
    ],
)
def test_bad_requests_get_their_error_code(planner, changes, code) -> None:
    error = failure(planner, request(**changes))
    assert error.code == code, error
    assert error.message


def test_a_used_up_budget_gives_timeout(planner, monkeypatch) -> None:
    jump_clock(monkeypatch)
    error = failure(planner, request(time_budget=0.5))
    assert error.code == ErrorCode.TIMEOUT
    assert "time budget of 0.50 s used up" in error.message


HEADING = 0.3
ACROSS = np.array([-math.sin(HEADING), math.cos(HEADING), 0.0])  # the run's left normal


def sweep_request(**changes) -> StrikeRequest:
    """A domino fallen flat across the run at its second slot, 13 mm off the run's line,
    between two standing neighbours (as S-curve seed 2 left one, out of every grasp's
    reach): pushed 31 mm along the run's normal, its near end 8 mm beyond the run's side."""
    run = run_poses(0.55, 0.15, HEADING)
    slot = run[1].translation()
    fallen = flat_pose(*(slot + 0.013 * ACROSS)[:2], HEADING + math.pi / 2)
    base = StrikeRequest(
        fallen,
        SCENARIO.home_position,
        OPEN,
        (run[0], *run[2:]),
        push_distance=0.031,
        sweep=ACROSS,
    )
    return dataclasses.replace(base, **changes)


def test_sweep_pushes_a_fallen_domino_low_across_the_run(planner) -> None:
    req = sweep_request()
    plan = planner.plan(req)
    checker = StrikeChecker(SCENARIO, req.domino_pose, req.standing, SETTINGS.acceleration_limit)
    result = checker.check(plan.sampled(SETTINGS.sample_period), req.start, req.finger_opening)
    assert [s.label for s in plan.segments] == ["close_gripper", "approach", "push", "retreat"]
    assert result.fingertip_height == pytest.approx(0.4 * DOMINO_SIZE[2], abs=1e-3)
    assert result.push_past_contact == pytest.approx(0.031, abs=1e-3)
    assert result.min_clearance("push", "pads", "target") < 0.0
    assert result.min_clearance("push", "pads", "standing") >= SETTINGS.fine_obstacle_clearance
    assert result.min_clearance("push", "pads", "table") >= SETTINGS.pad_table_clearance
    for phase in ("approach", "push", "retreat"):
        assert result.min_clearance(phase, "arm", "standing") >= SETTINGS.coarse_clearance
    pushed = plan.segments[2].pieces[-1]
    end, start = (
        checker.tcp_pose(pushed.sample([t])[0][0]).translation() for t in (pushed.duration, 0.0)
    )
    travel = end - start
    assert travel / np.linalg.norm(travel) == pytest.approx(ACROSS, abs=1e-3)


@pytest.mark.parametrize(
    ("changes", "code"),
    [
        ({"sweep": np.array([math.nan, 0.0, 0.0])}, ErrorCode.INVALID_REQUEST),
        ({"sweep": np.array([0.0, 0.0, 1.0])}, ErrorCode.INVALID_REQUEST),
        ({"sweep": 2.0 * ACROSS}, ErrorCode.INVALID_REQUEST),
        ({"push_distance": 0.2}, ErrorCode.INVALID_REQUEST),
        # along the run: into the next standing domino
        (
            {"sweep": np.array([math.cos(HEADING), math.sin(HEADING), 0.0])},
            ErrorCode.PLACE_IN_COLLISION,
        ),
    ],
    ids=["nan", "vertical", "not_unit", "too_far", "into_the_run"],
)
def test_bad_sweeps_get_their_error_code(planner, changes, code) -> None:
    error = failure(planner, sweep_request(**changes))
    assert error.code == code, error
    assert error.message


def test_planner_keeps_working_after_failures(planner, monkeypatch) -> None:
    with monkeypatch.context() as patched:
        jump_clock(patched)
        assert failure(planner, request(time_budget=0.5)).code == ErrorCode.TIMEOUT
    for bad, code in (
        ({"time_budget": -1.0}, ErrorCode.INVALID_REQUEST),
        ({"push_distance": 0.03}, ErrorCode.PLACE_IN_COLLISION),
    ):
        assert failure(planner, request(**bad)).code == code
    assert planner.plan(request()).segments

"""Strategies for sim_node's arm and gripper actions, and the action endpoints."""

from __future__ import annotations

import itertools
import math
from collections.abc import Callable, Sequence

from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import GripperCommand as GripperTarget
from hypothesis import strategies as st
from rclpy.node import Node
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from support.fuzz.harness import Case, Endpoint, action_sender
from support.fuzz.replies import (
    gripper_outcome,
    gripper_problem,
    trajectory_outcome,
    trajectory_problem,
)
from support.fuzz.values import ARM, HOME, HUGE, NON_FINITE

INVALID_GOAL = frozenset({"INVALID_GOAL"})
INVALID_JOINTS = frozenset({"INVALID_JOINTS"})


def duration(seconds: float) -> Duration:
    whole = math.floor(seconds)
    return Duration(sec=int(whole), nanosec=int((seconds - whole) * 1e9))


def trajectory_goal(
    names: Sequence[str], points: Sequence[tuple[float, Sequence[float]]], **fields
) -> FollowJointTrajectory.Goal:
    """A goal through ``points`` (time from start [s], positions); ``fields``: per-point
    lists set on every point (velocities, accelerations, effort)."""
    trajectory = JointTrajectory(joint_names=list(names))
    for seconds, positions in points:
        point = JointTrajectoryPoint(positions=list(positions), time_from_start=duration(seconds))
        for name, values in fields.items():
            setattr(point, name, list(values))
        trajectory.points.append(point)
    return FollowJointTrajectory.Goal(trajectory=trajectory)


def valid_trajectory() -> FollowJointTrajectory.Goal:
    """Home in 0.5 s: served from wherever the arm is after the fuzzed goals (none moves it)."""
    return trajectory_goal(ARM, [(0.5, HOME)])


def trajectory_cases() -> st.SearchStrategy[Case]:
    """Goals with one thing broken: the code is known for each; none moves the arm."""
    names = st.sampled_from(["", "elbow", "iiwa_joint_8", "wsg_left_finger_joint", "ä" * 300])

    def renamed(args: tuple[int, str]) -> Case:
        i, name = args
        wrong = [*ARM[:i], name, *ARM[i + 1 :]]
        return Case(trajectory_goal(wrong, [(1.0, HOME)]), "wrong joint name", INVALID_JOINTS)

    def twice(i: int) -> Case:
        goal = trajectory_goal([*ARM, ARM[i]], [(1.0, [*HOME, HOME[i]])])
        return Case(goal, "duplicate joint name", INVALID_JOINTS)

    def missing(n: int) -> Case:
        return Case(trajectory_goal(ARM[:n], [(1.0, HOME[:n])]), "missing joints", INVALID_JOINTS)

    def wrong_length(n: int) -> Case:
        return Case(trajectory_goal(ARM, [(1.0, HOME[:1] * n)]), f"{n} positions", INVALID_GOAL)

    def beyond(args: tuple[int, float]) -> Case:
        i, value = args
        position = list(HOME)
        position[i] = value
        return Case(trajectory_goal(ARM, [(1.0, position)]), "position beyond limits", INVALID_GOAL)

    def fast(args: tuple[int, float]) -> Case:
        i, value = args
        velocity = [0.0] * 7
        velocity[i] = value
        goal = trajectory_goal(ARM, [(1.0, HOME)], velocities=velocity)
        return Case(goal, "velocity beyond limits or not finite", INVALID_GOAL)

    def jump(i: int) -> Case:  # a 1 rad step in 10 ms: the interpolated speed is far over
        position = list(HOME)
        position[i] += 1.0 if position[i] < 0 else -1.0
        return Case(
            trajectory_goal(ARM, [(0.01, position)]), "too fast between points", INVALID_GOAL
        )

    def times(seconds: list[float]) -> Case:
        goal = trajectory_goal(ARM, [(t, HOME) for t in seconds])
        return Case(goal, "times not increasing", INVALID_GOAL)

    def ignored(args: tuple[str, list[float]]) -> Case:
        field_name, values = args
        goal = trajectory_goal(ARM, [(1.0, HOME)], **{field_name: values})
        return Case(goal, f"bad {field_name}", INVALID_GOAL)

    def huge(n: int) -> Case:
        goal = trajectory_goal(ARM, [(0.5 + 0.01 * i, HOME) for i in range(n)])
        return Case(goal, f"{n} points", INVALID_GOAL)

    far_start = [h + (0.5 if h < 0 else -0.5) for h in HOME]
    empty = Case(
        trajectory_goal([], []), "empty goal", frozenset({"INVALID_JOINTS", "INVALID_GOAL"})
    )
    multi_dof = trajectory_goal(ARM, [(1.0, HOME)])
    multi_dof.multi_dof_trajectory.joint_names = ["base"]
    return st.one_of(
        st.tuples(st.integers(0, 6), names).map(renamed),
        st.integers(0, 6).map(twice),
        st.integers(0, 6).map(missing),
        st.sampled_from([0, 1, 6, 8, 100_000]).map(wrong_length),
        st.tuples(st.integers(0, 6), st.sampled_from([3.2, -3.2, 10.0, 1e300, *NON_FINITE])).map(
            beyond
        ),
        st.tuples(st.integers(0, 6), st.sampled_from([20.0, -50.0, 1e300, *NON_FINITE])).map(fast),
        st.integers(0, 6).map(jump),
        st.one_of(
            st.lists(st.sampled_from([0.0, 0.5, 1.0]), min_size=2, max_size=5).filter(
                lambda t: any(b <= a for a, b in itertools.pairwise(t))
            ),
            st.just([-1.0, 1.0]),
        ).map(times),
        st.tuples(
            st.sampled_from(["accelerations", "effort"]),
            st.one_of(
                st.lists(st.floats(-100, -1), min_size=1, max_size=6),  # negative and short
                st.lists(st.sampled_from([*NON_FINITE, 1.0]), min_size=7, max_size=7).filter(
                    lambda v: not all(map(math.isfinite, v))
                ),
            ),
        ).map(ignored),
        st.sampled_from([10_001, 100_000]).map(huge),
        st.just(
            Case(trajectory_goal(ARM, [(0.0, far_start)]), "t = 0 far from here", INVALID_GOAL)
        ),
        st.just(Case(trajectory_goal(ARM, []), "no points", INVALID_GOAL)),
        st.just(empty),
        st.just(Case(multi_dof, "multi_dof_trajectory", INVALID_JOINTS)),
    )


def gripper_goal(position: float, max_effort: float = 0.0) -> GripperCommand.Goal:
    return GripperCommand.Goal(command=GripperTarget(position=position, max_effort=max_effort))


def gripper_cases() -> st.SearchStrategy[Case]:
    """Openings outside the 0–0.11 m stroke or not finite, efforts negative or not finite."""
    aborted = frozenset({"ABORTED"})
    return st.one_of(
        st.one_of(
            st.sampled_from([*NON_FINITE, *HUGE, -1e-9, 0.111]), st.floats(-1e300, -1e-6)
        ).map(lambda p: Case(gripper_goal(p), "opening outside the stroke", aborted)),
        st.one_of(st.sampled_from([*NON_FINITE, -1e300]), st.floats(-1e300, -1e-6)).map(
            lambda e: Case(gripper_goal(0.05, e), "bad max_effort", aborted)
        ),
        st.sampled_from([1e6, 1e300]).map(
            lambda e: Case(
                gripper_goal(0.05, e), "huge max_effort (capped)", frozenset({"SUCCEEDED"})
            )
        ),
    )


def action_endpoints(node: Node) -> dict[str, tuple[Endpoint, Callable[[], st.SearchStrategy]]]:
    """sim_node's arm and gripper actions with their case strategies."""
    return {
        "/arm_controller/follow_joint_trajectory": (
            Endpoint(
                "/arm_controller/follow_joint_trajectory",
                "sim_node",
                action_sender(
                    node, FollowJointTrajectory, "/arm_controller/follow_joint_trajectory"
                ),
                trajectory_outcome,
                Case(valid_trajectory(), "valid", frozenset({"SUCCESSFUL"})),
                trajectory_problem,
            ),
            trajectory_cases,
        ),
        "/gripper_controller/gripper_cmd": (
            Endpoint(
                "/gripper_controller/gripper_cmd",
                "sim_node",
                action_sender(node, GripperCommand, "/gripper_controller/gripper_cmd"),
                gripper_outcome,
                Case(gripper_goal(0.05), "valid", frozenset({"SUCCEEDED"})),
                gripper_problem,
            ),
            gripper_cases,
        ),
    }

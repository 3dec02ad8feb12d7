"""The goal monitor's verdicts, without ROS or physics: tolerances, settle, stall."""

from __future__ import annotations

import numpy as np

from dombot_sim.goal_monitor import (
    DEFAULT_GOAL_TOLERANCE,
    GOAL_SETTLE_TIME,
    GRIPPER_STALL_TIME,
    GRIPPER_START_GRACE,
    GripperMonitor,
    Outcome,
    Tolerances,
    TrajectoryMonitor,
    joint_tolerances,
)

NAMES = ["a", "b", "c"]
ZERO = np.zeros(3)


def off(**errors: float) -> np.ndarray:
    """Joint positions that many radians away from ZERO."""
    return np.array([errors.get(name, 0.0) for name in NAMES])


def test_tolerances_follow_control_msgs_zero_is_default_negative_is_off() -> None:
    given = [("b", 0.0), ("c", -1.0), ("unknown", 0.5), ("a", 0.2)]
    np.testing.assert_allclose(joint_tolerances(given, NAMES, 0.01), [0.2, 0.01, -1.0])


def test_goal_met_at_the_end_succeeds_and_keeps_the_worst_error() -> None:
    monitor = TrajectoryMonitor(NAMES, end=1.0, tolerances=Tolerances.defaults(3))
    assert monitor.check(0.5, off(a=0.3), ZERO).outcome is Outcome.RUNNING
    verdict = monitor.check(1.0, off(b=0.005), ZERO)
    assert verdict.outcome is Outcome.SUCCEEDED
    np.testing.assert_allclose(verdict.error, [0.0, 0.005, 0.0])
    assert monitor.worst == 0.3


def test_goal_missed_waits_for_the_settle_time_then_names_the_joint() -> None:
    monitor = TrajectoryMonitor(NAMES, end=1.0, tolerances=Tolerances.defaults(3))
    late = off(c=2 * DEFAULT_GOAL_TOLERANCE)
    assert monitor.check(1.0, late, ZERO).outcome is Outcome.RUNNING
    assert monitor.check(1.0 + GOAL_SETTLE_TIME, late, ZERO).outcome is Outcome.RUNNING
    verdict = monitor.check(1.01 + GOAL_SETTLE_TIME, late, ZERO)
    assert verdict.outcome is Outcome.GOAL_TOLERANCE_VIOLATED
    assert verdict.message.startswith("c ended 0.0200 rad")


def test_settling_within_the_settle_time_succeeds() -> None:
    monitor = TrajectoryMonitor(NAMES, end=1.0, tolerances=Tolerances.defaults(3))
    assert monitor.check(1.1, off(a=0.05), ZERO).outcome is Outcome.RUNNING
    assert monitor.check(1.3, off(a=0.001), ZERO).outcome is Outcome.SUCCEEDED


def test_path_tolerance_aborts_at_once_even_before_the_end() -> None:
    tolerances = Tolerances(path=np.array([-1.0, 0.1, -1.0]), goal=np.full(3, 0.01))
    monitor = TrajectoryMonitor(NAMES, end=5.0, tolerances=tolerances)
    assert monitor.check(0.1, off(a=1.0, b=0.09), ZERO).outcome is Outcome.RUNNING
    verdict = monitor.check(0.2, off(b=-0.15), ZERO)
    assert verdict.outcome is Outcome.PATH_TOLERANCE_VIOLATED
    assert "on b: 0.1500 rad" in verdict.message


def test_unchecked_goal_joints_may_end_anywhere() -> None:
    tolerances = Tolerances(path=np.full(3, -1.0), goal=np.array([0.01, -1.0, 0.0]), settle=0.0)
    monitor = TrajectoryMonitor(NAMES, end=1.0, tolerances=tolerances)
    assert monitor.check(1.0, off(b=3.0, c=3.0), ZERO).outcome is Outcome.SUCCEEDED


def test_gripper_reaching_its_opening_is_done() -> None:
    monitor = GripperMonitor(goal=0.05, start=0.0, stroke_time=1.0)
    assert not monitor.check(0.1, 0.03, 0.1, 0.0, 40.0).done
    verdict = monitor.check(0.2, 0.0495, 0.1, 0.0, 40.0)
    assert verdict.done and verdict.reached and not verdict.stalled


def test_gripper_stalls_only_when_still_at_the_force_limit_long_enough() -> None:
    monitor = GripperMonitor(goal=0.0, start=0.0, stroke_time=1.0)
    t0 = GRIPPER_START_GRACE + 0.01
    assert not monitor.check(t0, 0.02, 0.0, -40.0, 40.0).done
    assert not monitor.check(t0 + GRIPPER_STALL_TIME, 0.02, 0.0, -40.0, 40.0).done
    verdict = monitor.check(t0 + GRIPPER_STALL_TIME + 0.01, 0.02, 0.0, -40.0, 40.0)
    assert verdict.done and verdict.stalled and not verdict.reached


def test_gripper_still_below_the_force_limit_is_not_stalled_and_times_out() -> None:
    monitor = GripperMonitor(goal=0.0, start=0.0, stroke_time=1.0)
    for t in (0.1, 0.5, 1.5):
        verdict = monitor.check(t, 0.02, 0.0, -10.0, 40.0)
        assert not verdict.stalled and not verdict.done
    verdict = monitor.check(2.01, 0.02, 0.0, -10.0, 40.0)
    assert verdict.done and not verdict.stalled and not verdict.reached


def test_gripper_moving_again_restarts_the_stall_clock() -> None:
    monitor = GripperMonitor(goal=0.0, start=0.0, stroke_time=1.0)
    monitor.check(0.1, 0.02, 0.0, -40.0, 40.0)
    monitor.check(0.15, 0.019, 0.05, -40.0, 40.0)  # moving: the clock restarts
    assert not monitor.check(0.2 + GRIPPER_STALL_TIME, 0.019, 0.0, -40.0, 40.0).stalled

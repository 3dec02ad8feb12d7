"""The simulator's trajectory check and spline (dombot_sim.trajectory) without ROS: a goal
whose first point, at t = 0, is a few mrad from where the arm is (within the start
tolerance) is followed from the arm's position within the velocity limits, not refused."""

from __future__ import annotations

import numpy as np
import pytest

from dombot_sim.trajectory import (
    INTERPOLATION_SPEED_MARGIN,
    JointLimits,
    TrajectoryError,
    build_trajectory,
)

NAMES = tuple(f"iiwa_joint_{i}" for i in range(1, 8))
# the LBR iiwa 14's URDF limits, as the simulated arm has them
LIMITS = JointLimits(
    NAMES,
    lower=np.radians([-170, -120, -170, -120, -170, -120, -175]),
    upper=np.radians([170, 120, 170, 120, 170, 120, 175]),
    velocity=np.array([1.48353, 1.48353, 1.745329, 1.308997, 2.268928, 2.356194, 2.356194]),
)
PERIOD = 0.01  # s between points, as the planner publishes them
START = np.array([0.0, 0.4, 0.0, -1.6, 0.0, 1.1, 0.0])
MOVE = np.array([0.5, 0.6, -0.3, 0.4, 0.2, -0.5, 0.8])  # rad from START


def rest_to_rest(share: float = 0.95) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Times, positions, velocities of a quintic rest-to-rest move by MOVE, sampled every
    PERIOD, whose fastest joint peaks at ``share`` of its limit (a time-optimal plan rides
    the limit)."""
    duration = 1.875 * np.max(np.abs(MOVE) / (share * LIMITS.velocity))  # quintic peak 15/8
    times = np.append(np.arange(0.0, duration, PERIOD), duration)
    tau = times / duration
    shape = 10 * tau**3 - 15 * tau**4 + 6 * tau**5
    rate = (30 * tau**2 - 60 * tau**3 + 30 * tau**4) / duration
    return times, START + np.outer(shape, MOVE), np.outer(rate, MOVE)


def build(current: np.ndarray, times=None, q=None, v=None):
    given = rest_to_rest()
    times, q, v = (given[i] if x is None else x for i, x in enumerate((times, q, v)))
    return build_trajectory(NAMES, times, q, v, current, LIMITS)


def largest_speed_use(spline) -> float:
    t = np.linspace(0.0, spline.end_time(), int(spline.end_time() / 1e-4))
    return float(np.max(np.abs(spline.MakeDerivative(1).vector_values(t).T) / LIMITS.velocity))


def test_a_goal_from_the_arms_position_keeps_its_timing() -> None:
    times, q, _ = rest_to_rest()
    spline = build(START)
    assert spline.end_time() == pytest.approx(times[-1])
    assert spline.value(times[5]).ravel() == pytest.approx(q[5])


def test_an_arm_11_mrad_from_the_first_point_is_moved_from_where_it_is() -> None:
    """The refusal seen in the bring-up ("iiwa_joint_2 moves at 1.664 rad/s, over its limit
    1.484 rad/s"): 11 mrad covered within the first 10 ms interval."""
    times, q, _ = rest_to_rest()
    current = START + np.array([0.0, 0.0111, 0.0, 0.0, 0.0, 0.0, 0.0])
    spline = build(current)
    assert spline.value(0.0).ravel() == pytest.approx(current)
    assert largest_speed_use(spline) <= 1.0 + INTERPOLATION_SPEED_MARGIN
    delay = spline.end_time() - times[-1]
    assert 0.0 < delay < 0.02  # the first interval lengthened, nothing else
    assert spline.value(times[-1] + delay).ravel() == pytest.approx(q[-1])
    assert spline.value(times[20] + delay).ravel() == pytest.approx(q[20])


@pytest.mark.parametrize("seed", range(5))
def test_any_start_offset_within_the_tolerance_keeps_the_velocity_limits(seed: int) -> None:
    direction = np.random.default_rng(seed).uniform(-1.0, 1.0, 7)
    current = START + 0.0499 * direction / np.abs(direction).max()  # start_tolerance 0.05
    spline = build(current)
    assert spline.value(0.0).ravel() == pytest.approx(current)
    assert largest_speed_use(spline) <= 1.0 + INTERPOLATION_SPEED_MARGIN


def test_an_arm_beyond_the_start_tolerance_is_refused() -> None:
    with pytest.raises(TrajectoryError, match=r"0\.060 rad from the current position"):
        build(START + np.array([0.0, 0.06, 0.0, 0.0, 0.0, 0.0, 0.0]))


def test_a_step_later_in_the_goal_is_still_refused() -> None:
    """Only the interval from the arm's position is lengthened."""
    times, q, v = rest_to_rest()
    q = q.copy()
    q[30:, 1] += 0.02  # 20 mrad in one 10 ms interval: ~3 rad/s
    with pytest.raises(TrajectoryError, match=r"interpolated velocity, sample 5[89]\d"):
        build(START + np.array([0.0, 0.01, 0.0, 0.0, 0.0, 0.0, 0.0]), q=q, v=v, times=times)

"""Check a commanded joint trajectory and turn it into a spline the arm can follow.

The rules are those of ros2_control's joint_trajectory_controller and
control_msgs/FollowJointTrajectory, so a client written for a real arm works here:

* joint names must be the arm's joints, each once, in any order (INVALID_JOINTS);
* at most MAX_POINTS points; times strictly increase; every value is finite; positions
  stay within the joint limits and velocities within the velocity limits; accelerations
  and efforts, if given, have one value per joint (they are not used: the arm is
  position-controlled) (INVALID_GOAL);
* a first point later than t = 0 is reached from the current position; a first point at
  t = 0 must be the current position (within ``start_tolerance``): the arm starts where it
  is, and with velocities given the first interval is lengthened as far as the velocity
  limits need to cover the difference (one 10 ms sample interval covers only ~10 mrad), the
  rest of the trajectory following that much later;
* with velocities the spline is cubic Hermite through positions and velocities;
  without, a cubic with continuous accelerations that starts and ends at rest.
"""

from __future__ import annotations

import itertools
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from types import MappingProxyType

import numpy as np
from pydrake.trajectories import PiecewisePolynomial

INVALID_GOAL = -1
INVALID_JOINTS = -2
LIMIT_MARGIN = 1e-6  # rad: rounding allowed at a position limit
POINT_SPEED_MARGIN = 1e-3  # relative: a time-optimal plan's points sit on the limit
# Between the given points the spline may overshoot a velocity limit the points respect
# (a time-optimal trajectory rides the limit); like a robot driver, allow a little.
INTERPOLATION_SPEED_MARGIN = 0.05
SPEED_SAMPLES_PER_SEGMENT = 20
START_STRETCH = 1.25  # factor the first interval grows by per try to cover a start offset
START_STRETCH_TRIES = 20  # up to 1.25**19 ≈ 70 times its length
MAX_POINTS = 10_000  # 100 s at the planner's 0.01 s sample period; more is a mistake


class TrajectoryError(ValueError):
    """A rejected trajectory: ``code`` is the FollowJointTrajectory error code."""

    def __init__(self, code: int, message: str) -> None:
        super().__init__(message)
        self.code = code


@dataclass(frozen=True)
class JointLimits:
    names: tuple[str, ...]
    lower: np.ndarray
    upper: np.ndarray
    velocity: np.ndarray


def build_trajectory(
    joint_names: Sequence[str],
    times: Sequence[float],
    positions: Sequence[Sequence[float]],
    velocities: Sequence[Sequence[float]] | None,
    current: np.ndarray,
    limits: JointLimits,
    start_tolerance: float = 0.05,
    unused: Mapping[str, Sequence[Sequence[float]]] = MappingProxyType({}),
) -> PiecewisePolynomial:
    """The spline (rows in ``limits.names`` order, time from 0) or a TrajectoryError.

    ``unused``: per-point fields only checked (name → rows, e.g. accelerations, effort):
    each row empty or one finite value per joint, as joint_trajectory_controller wants.
    """
    order = _joint_order(joint_names, limits.names)
    if len(times) > MAX_POINTS:
        raise TrajectoryError(
            INVALID_GOAL, f"{len(times)} points; at most {MAX_POINTS} are followed"
        )
    times = np.asarray(times, dtype=float)
    q = _matrix(positions, len(times), len(order), "positions")[:, order]
    v = None
    if velocities is not None:
        v = _matrix(velocities, len(times), len(order), "velocities")[:, order]
    _check_values(times, q, v, limits)
    for what, rows in unused.items():
        for i, row in enumerate(rows):
            if len(row) and (len(row) != len(order) or not np.all(np.isfinite(row))):
                raise TrajectoryError(
                    INVALID_GOAL, f"point {i}: {what} must be empty or {len(order)} finite numbers"
                )
    if times[0] > 0.0:
        times = np.concatenate([[0.0], times])
        q = np.vstack([current, q])
        v = None if v is None else np.vstack([np.zeros_like(current), v])
    else:
        offset = np.abs(q[0] - current).max()
        if offset > start_tolerance:
            raise TrajectoryError(
                INVALID_GOAL,
                f"the point at t = 0 is {offset:.3f} rad from the current position "
                f"(allowed {start_tolerance} rad); start later than 0 to move there",
            )
        q[0] = current
        if v is not None and len(times) > 1:
            times = _stretch_first_interval(times, q, v, limits)
    if len(times) == 1:
        return PiecewisePolynomial.ZeroOrderHold([0.0, 1e-3], np.column_stack([q[0], q[0]]))
    if v is None:
        spline = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
            times, q.T, np.zeros(q.shape[1]), np.zeros(q.shape[1])
        )
    else:
        spline = PiecewisePolynomial.CubicHermite(times, q.T, v.T)
    _check_spline_speed(spline, times, limits)
    return spline


def _joint_order(names: Sequence[str], arm: Sequence[str]) -> list[int]:
    """Index into ``names`` for each arm joint, in arm order."""
    names = list(names)
    unknown = [n for n in names if n not in arm]
    if unknown:
        raise TrajectoryError(INVALID_JOINTS, f"unknown joints {unknown}; the arm has {list(arm)}")
    if len(set(names)) != len(names):
        raise TrajectoryError(INVALID_JOINTS, f"a joint is named twice in {names}")
    missing = [n for n in arm if n not in names]
    if missing:
        raise TrajectoryError(INVALID_JOINTS, f"joints {missing} are missing")
    return [names.index(n) for n in arm]


def _matrix(rows: Sequence[Sequence[float]], count: int, width: int, what: str) -> np.ndarray:
    if len(rows) != count or any(len(row) != width for row in rows):
        raise TrajectoryError(
            INVALID_GOAL, f"every point needs {width} {what} (one per joint name)"
        )
    return np.array(rows, dtype=float).reshape(count, width)


def _check_values(
    times: np.ndarray, q: np.ndarray, v: np.ndarray | None, limits: JointLimits
) -> None:
    if times.size == 0:
        raise TrajectoryError(INVALID_GOAL, "the trajectory has no points")
    if not (np.all(np.isfinite(times)) and np.all(np.isfinite(q))):
        raise TrajectoryError(INVALID_GOAL, "times and positions must be finite numbers")
    if times[0] < 0.0 or np.any(np.diff(times) <= 0.0):
        raise TrajectoryError(INVALID_GOAL, "time_from_start must be >= 0 and strictly increase")
    below = q < limits.lower - LIMIT_MARGIN
    above = q > limits.upper + LIMIT_MARGIN
    if below.any() or above.any():
        point, joint = np.argwhere(below | above)[0]
        raise TrajectoryError(
            INVALID_GOAL,
            f"point {point}: {limits.names[joint]} = {q[point, joint]:.4f} rad is outside "
            f"its limits [{limits.lower[joint]:.4f}, {limits.upper[joint]:.4f}]",
        )
    if v is not None:
        if not np.all(np.isfinite(v)):
            raise TrajectoryError(INVALID_GOAL, "velocities must be finite numbers")
        _check_speeds(np.abs(v), limits, "velocity at point", POINT_SPEED_MARGIN)


def _stretch_first_interval(
    times: np.ndarray, q: np.ndarray, v: np.ndarray, limits: JointLimits
) -> np.ndarray:
    """``times`` with the first interval (from the current position, put in place of the
    first point) lengthened until its cubic passes the interpolated speed check, the rest
    shifted by as much; unchanged if it passes already or no length does (then refused).

    A planner samples its trajectory from the start state it was given; the arm may be a
    few mrad from it when the goal arrives (e.g. a joint state read while it still moved),
    which one 10 ms interval covers only at 150 rad/s per rad: 11 mrad at 1.66 rad/s."""
    first = times[1] - times[0]
    for tries in range(START_STRETCH_TRIES):
        length = first * START_STRETCH**tries
        piece = PiecewisePolynomial.CubicHermite([0.0, length], q[:2].T, v[:2].T)
        speed = _interpolated_speed(piece, [0.0, length])
        if not _over_speed(speed, limits, INTERPOLATION_SPEED_MARGIN).any():
            return np.concatenate([times[:1], times[1:] + (length - first)])
    return times


def _interpolated_speed(spline: PiecewisePolynomial, times: Sequence[float]) -> np.ndarray:
    """|velocity| (samples × joints) at SPEED_SAMPLES_PER_SEGMENT samples per interval."""
    samples = np.concatenate(
        [np.linspace(a, b, SPEED_SAMPLES_PER_SEGMENT) for a, b in itertools.pairwise(times)]
    )
    return np.abs(spline.MakeDerivative(1).vector_values(samples).T)


def _check_spline_speed(
    spline: PiecewisePolynomial, times: np.ndarray, limits: JointLimits
) -> None:
    speed = _interpolated_speed(spline, times)
    _check_speeds(speed, limits, "interpolated velocity, sample", INTERPOLATION_SPEED_MARGIN)


def _over_speed(speed: np.ndarray, limits: JointLimits, allowance: float) -> np.ndarray:
    return speed > limits.velocity * (1.0 + allowance) + LIMIT_MARGIN


def _check_speeds(
    speed: np.ndarray, limits: JointLimits, where: str, allowance: float = 0.0
) -> None:
    over = _over_speed(speed, limits, allowance)
    if over.any():
        row, joint = np.argwhere(over)[0]
        raise TrajectoryError(
            INVALID_GOAL,
            f"{where} {row}: {limits.names[joint]} moves at {speed[row, joint]:.3f} rad/s, "
            f"over its limit {limits.velocity[joint]:.3f} rad/s"
            + (f" (+{allowance:.1%} allowed)" if allowance else ""),
        )

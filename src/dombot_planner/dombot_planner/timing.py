"""Retiming with Drake's TOPP-RA: each path piece gets the time-optimal scaling s(t) under
joint velocity and acceleration limits (and a TCP speed limit on the straight lines),
starting and ending at rest; pieces played one after the other therefore join without
jumps (the paper's time scaling of two segments, without hand tuning)."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from pydrake.multibody.optimization import Toppra
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame
from pydrake.trajectories import PiecewisePolynomial, Trajectory

RETIME_ROUNDS = 3
LIMIT_TOLERANCE = 0.002  # a limit exceeded in the dense check is tightened this much more
CHECK_PERIOD = 0.002  # s between the samples that check the limits


@dataclass(frozen=True)
class JointLimits:
    velocity: np.ndarray  # rad/s, symmetric
    acceleration: np.ndarray  # rad/s², symmetric


@dataclass
class TimedPath:
    """A joint path q(s) and its time scaling s(t); at rest at both ends."""

    label: str
    fine: bool  # part of a final approach or retreat (straight line), not a coarse move
    path: Trajectory
    scaling: PiecewisePolynomial

    @property
    def duration(self) -> float:
        return self.scaling.end_time()

    def sample(self, times: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Positions, velocities, accelerations (each len(times) × n) at ``times``."""
        times = np.clip(np.asarray(times, dtype=float), 0.0, self.duration)
        s = self.scaling.vector_values(times)[0]
        s_dot = self.scaling.MakeDerivative(1).vector_values(times)[0]
        s_ddot = self.scaling.MakeDerivative(2).vector_values(times)[0]
        q = self.path.vector_values(s)
        dq_ds = self.path.MakeDerivative(1).vector_values(s)
        d2q_ds2 = self.path.MakeDerivative(2).vector_values(s)
        velocity = dq_ds * s_dot
        acceleration = d2q_ds2 * s_dot**2 + dq_ds * s_ddot
        return q.T, velocity.T, acceleration.T


def line_path(waypoints: np.ndarray, spacing: float) -> PiecewisePolynomial:
    """A C2 joint path through straight-line IK waypoints, parametrised by TCP distance."""
    breaks = spacing * np.arange(len(waypoints))
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(breaks, waypoints.T, False)


def retime(
    label: str,
    path: Trajectory,
    plant: MultibodyPlant,
    limits: JointLimits,
    *,
    fine: bool = False,
    tcp: Frame | None = None,
    tcp_speed: float | None = None,
    grid_points: int = 100,
) -> TimedPath | None:
    """Time-optimal scaling of ``path`` under ``limits``; None if TOPP-RA finds none.

    TOPP-RA enforces the limits at its grid points only (and hardly at the last one); the
    result is sampled densely and, where a limit is exceeded, solved again with that limit
    tightened by the excess. Still exceeded after RETIME_ROUNDS, the scaling is slowed
    down uniformly (velocities scale with 1/k, accelerations with 1/k²) until it is not.
    """
    grid = np.linspace(path.start_time(), path.end_time(), grid_points)
    scale = np.ones(2)  # velocity, acceleration
    for _ in range(RETIME_ROUNDS):
        toppra = Toppra(path, plant, grid)
        velocity, acceleration = limits.velocity * scale[0], limits.acceleration * scale[1]
        toppra.AddJointVelocityLimit(-velocity, velocity)
        toppra.AddJointAccelerationLimit(-acceleration, acceleration)
        if tcp is not None and tcp_speed is not None:
            toppra.AddFrameTranslationalSpeedLimit(tcp, tcp_speed)
        scaling = toppra.SolvePathParameterization()
        if scaling is None or not math.isfinite(scaling.end_time()):
            return None
        timed = TimedPath(label, fine, path, scaling)
        use = limit_use(timed, limits)
        if np.all(use <= 1.0):  # the executor allows 0.1 % over at its points, no more
            return timed
        scale = scale / np.maximum(use, 1.0) * (1.0 - LIMIT_TOLERANCE)
    stretch = max(use[0], math.sqrt(use[1])) * (1.0 + LIMIT_TOLERANCE)
    timed.scaling.ScaleTime(stretch)
    return timed


def limit_use(timed: TimedPath, limits: JointLimits) -> np.ndarray:
    """Largest |velocity| / limit and |acceleration| / limit over samples CHECK_PERIOD
    apart (at least 400): denser than the published trajectory points."""
    samples = max(400, math.ceil(timed.duration / CHECK_PERIOD) + 1)
    _, velocity, acceleration = timed.sample(np.linspace(0.0, timed.duration, samples))
    return np.array(
        [
            np.max(np.abs(velocity) / limits.velocity),
            np.max(np.abs(acceleration) / limits.acceleration),
        ]
    )

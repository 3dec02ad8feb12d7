"""Check the closed-form kinematics against the independent vehicle simulation."""

from __future__ import annotations

import numpy as np

from dombot_layer.kinematics import LayerKinematics, forward, wheel_angular_velocities
from dombot_layer.vehicle_sim import SimulationResult, circle_center, simulate


def drive_circle(
    kinematics: LayerKinematics,
    deposit_radius: float,
    distance: float,
    speed: float = 0.1,
    spacing: float = 0.01,
    start_at_equilibrium: bool = False,
) -> tuple[SimulationResult, np.ndarray]:
    """Simulate the wheel speeds IK gives for ``deposit_radius``; return the run and each
    laid domino's distance from the circle's centre.

    ``start_at_equilibrium`` starts the trolley at eq. (9)'s angle (θ clockwise of
    the tractor in a left turn, anticlockwise in a right turn) instead of straight.
    """
    geometry = kinematics.geometry
    midpoint = kinematics.midpoint_radius(deposit_radius)
    left, right = wheel_angular_velocities(geometry, midpoint, speed)
    theta = -float(np.sign(midpoint)) * forward(geometry, midpoint).theta
    result = simulate(
        geometry,
        lambda t: (left, right),
        distance / speed,
        spacing=spacing,
        initial_trolley_angle=theta if start_at_equilibrium else 0.0,
    )
    return result, np.linalg.norm(result.deposits - circle_center(midpoint), axis=1)

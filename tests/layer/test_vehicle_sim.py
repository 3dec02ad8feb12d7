"""The independent vehicle simulation confirms the closed-form kinematics."""

from __future__ import annotations

import numpy as np
import pytest

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import LayerKinematics, wheel_angular_velocities
from dombot_layer.vehicle_sim import VehicleSimulator, circle_center, simulate
from dombot_layer.verification import drive_circle

GEOMETRY = VehicleGeometry()
KINEMATICS = LayerKinematics(GEOMETRY)
SPEED = 0.1  # m/s


def laid_radii(deposit_radius: float, distance: float, start_at_equilibrium: bool) -> np.ndarray:
    return drive_circle(KINEMATICS, deposit_radius, distance, SPEED, 0.01, start_at_equilibrium)[1]


@pytest.mark.parametrize("radius", [0.1, 0.3, 1.0, 10.0, -0.15, -1.0, -10.0])
def test_deposits_settle_on_the_predicted_radius_after_the_transient(radius: float) -> None:
    radii = laid_radii(radius, distance=8.0, start_at_equilibrium=False)
    settled = radii[len(radii) // 2 :]
    assert np.max(np.abs(settled - abs(radius))) < 1e-4
    assert abs(radii[0] - abs(radius)) > 1e-3  # started straight: there was a transient


@pytest.mark.parametrize("side", ["left", "right"])
def test_the_predicted_trolley_angle_is_the_simulated_steady_state(side: str) -> None:
    # Down to the minimum laying radius, where settling from straight takes many turns.
    sign = 1.0 if side == "left" else -1.0
    for factor in (1.0001, 1.01, 1.5):
        radius = sign * factor * KINEMATICS.minimum_laying_radius(side)
        radii = laid_radii(radius, distance=2.0, start_at_equilibrium=True)
        assert np.max(np.abs(radii - abs(radius))) < 1e-6


def test_a_wrong_trolley_model_would_be_caught() -> None:
    # Same wheels, trolley 10 % longer: the simulated circle must differ measurably.
    longer = VehicleGeometry(d_tw=GEOMETRY.d_tw * 1.1)
    midpoint = KINEMATICS.midpoint_radius(0.3)
    left, right = wheel_angular_velocities(GEOMETRY, midpoint, SPEED)
    result = simulate(longer, lambda t: (left, right), 80.0, spacing=0.01)
    settled = np.linalg.norm(result.deposits - circle_center(midpoint), axis=1)[-50:]
    assert np.min(np.abs(settled - 0.3)) > 1e-3


def test_straight_driving_lays_a_straight_line_at_the_spacing() -> None:
    omega = SPEED / GEOMETRY.wheel_radius
    result = simulate(GEOMETRY, lambda t: (omega, omega), 10.0, spacing=0.02)
    assert np.allclose(result.deposits[:, 1], -GEOMETRY.d_t, atol=1e-12)
    gaps = np.linalg.norm(np.diff(result.deposits, axis=0), axis=1)
    assert gaps == pytest.approx(np.full(gaps.size, 0.02), abs=1e-9)


def test_stepping_in_real_time_lays_the_same_dominoes_as_the_batch_run() -> None:
    midpoint = KINEMATICS.midpoint_radius(0.4)
    left, right = wheel_angular_velocities(GEOMETRY, midpoint, SPEED)
    batch = simulate(GEOMETRY, lambda t: (left, right), 6.0, spacing=0.02)
    stepper = VehicleSimulator(GEOMETRY, spacing=0.02)
    laid = np.concatenate([stepper.step(left, right, 0.05) for _ in range(120)])
    assert laid.shape == batch.deposits.shape
    assert np.max(np.abs(laid - batch.deposits)) < 1e-8

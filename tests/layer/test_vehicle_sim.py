"""The independent vehicle simulation confirms the closed-form kinematics."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import (
    LayerKinematics,
    forward,
    trolley_wheel_radius,
    wheel_angular_velocities,
)
from dombot_layer.vehicle_sim import SimulationResult, VehicleSimulator, circle_center, simulate
from dombot_layer.verification import drive_circle

GEOMETRY = VehicleGeometry()
KINEMATICS = LayerKinematics(GEOMETRY)
SPEED = 0.1  # m/s
LEFT_MINIMUM = KINEMATICS.minimum_laying_radius("left")
RIGHT_MINIMUM = KINEMATICS.minimum_laying_radius("right")


def trolley_angle_error(result: SimulationResult, deposit_radius: float) -> np.ndarray:
    """Simulated trolley angle minus eq. (9)'s θ (signed: +θ in a left turn)."""
    midpoint = KINEMATICS.midpoint_radius(deposit_radius)
    theta = math.copysign(forward(GEOMETRY, midpoint).theta, midpoint)
    return result.trolley_angle - theta


@pytest.mark.parametrize(
    "radius",
    [
        *(LEFT_MINIMUM, 1.0001 * LEFT_MINIMUM, 1.01 * LEFT_MINIMUM, 0.1, 1.0, 10.0),
        *(-RIGHT_MINIMUM, -1.0001 * RIGHT_MINIMUM, -0.1, -1.0, -10.0),
    ],
)
def test_eq_9_is_the_simulated_steady_state_from_the_minimum_to_10_m(radius: float) -> None:
    # Started at eq. (9)'s trolley angle, the trolley must stay there and lay on r_d.
    result, laid = drive_circle(KINEMATICS, radius, 2.0, SPEED, 0.01, start_at_equilibrium=True)
    assert np.max(np.abs(laid - abs(radius))) < 1e-4
    assert np.max(np.abs(trolley_angle_error(result, radius))) < 1e-6


@pytest.mark.parametrize("radius", [1.5 * LEFT_MINIMUM, 0.1, 10.0, -RIGHT_MINIMUM, -1.0])
def test_deposits_settle_on_the_predicted_radius_after_the_transient(radius: float) -> None:
    # Started straight, the trolley angle converges to eq. (9); every domino laid after
    # that lies on the predicted circle.
    result, laid = drive_circle(KINEMATICS, radius, 15.0, SPEED, 0.01)
    last_unsettled = np.nonzero(np.abs(trolley_angle_error(result, radius)) > 1e-6)[0][-1]
    settled_at = result.time[min(last_unsettled + 1, result.time.size - 1)]
    assert settled_at < 0.8 * result.time[-1]
    after = result.deposit_times > settled_at
    assert np.count_nonzero(after) >= 100
    assert np.max(np.abs(laid[after] - abs(radius))) < 1e-4
    assert abs(laid[0] - abs(radius)) > 1e-3  # started straight: there was a transient


@pytest.mark.parametrize("radius", [0.3, -0.3, -RIGHT_MINIMUM, 1.01 * LEFT_MINIMUM])
def test_the_trolley_settles_at_the_rate_of_the_towing_model(radius: float) -> None:
    # Linearising ψ̇_t = (Ṗ · n_t)/d_tw about eq. (9): the trolley-angle error shrinks by
    # exp(−R_w/d_tw) per radian the tractor turns. Near the left minimum R_w → 0, which
    # is why settling there takes hundreds of turns.
    midpoint = KINEMATICS.midpoint_radius(radius)
    theta = math.copysign(forward(GEOMETRY, midpoint).theta, midpoint)
    left, right = wheel_angular_velocities(GEOMETRY, midpoint, SPEED)
    two_turns = 4 * math.pi * abs(midpoint) / SPEED
    # A microradian: small enough to stay linear even where R_w is a millimetre.
    result = simulate(GEOMETRY, lambda t: (left, right), two_turns, 0.05, -theta + 1e-6)
    error = np.abs(trolley_angle_error(result, radius))
    resolved = error > 1e-11
    rate = -np.polyfit(np.abs(result.heading[resolved]), np.log(error[resolved]), 1)[0]
    assert rate == pytest.approx(trolley_wheel_radius(GEOMETRY, midpoint) / GEOMETRY.d_tw, 1e-3)


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
    assert np.allclose(result.deposits[:, 1], -GEOMETRY.d_t, atol=1e-12)  # d_t > 0: right
    assert np.allclose(result.deposits[0], [-0.29, -0.02], atol=1e-12)  # rig length behind M
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


def test_simulation_refuses_a_nonpositive_spacing() -> None:
    with pytest.raises(ValueError, match="positive"):
        simulate(GEOMETRY, lambda t: (1.0, 1.0), 1.0, spacing=0.0)

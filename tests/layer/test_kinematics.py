"""Layer kinematics: eqs (1)–(12) by hand, the inverse to round-off, and the domain's edges."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import (
    LayerKinematics,
    UnreachableRadiusError,
    deposit_radius,
    forward,
    wheel_angular_velocities,
    wheel_radii,
    wheel_speed_ratio,
)

GEOMETRY = VehicleGeometry(d_p=0.10, d_tw=0.15, d_l=0.04, d_t=0.02, d_w=0.16, wheel_radius=0.03)
KINEMATICS = LayerKinematics(GEOMETRY)


def test_forward_matches_the_source_equations_computed_by_hand() -> None:
    r_m = 1.0
    alpha = math.atan(r_m / 0.10)  # eq. (7)
    beta = math.acos(0.15 / math.sqrt(r_m**2 + 0.10**2))  # eq. (8)
    theta = math.pi - alpha - beta  # eqs. (6), (9)
    phi = math.atan(0.02 / 0.04)  # eq. (4)
    z = math.sqrt(0.04**2 + 0.02**2)  # eq. (5)
    x = 0.10 + 0.15 * math.cos(theta) + z * math.cos(phi - theta)  # eq. (1)
    y = r_m - 0.15 * math.sin(theta) + z * math.sin(phi - theta)  # eq. (2)
    result = forward(GEOMETRY, r_m)
    assert result.theta == pytest.approx(theta, abs=1e-15)
    assert (result.x, result.y) == pytest.approx((x, y), abs=1e-15)
    assert result.deposit_radius == pytest.approx(math.hypot(x, y), abs=1e-15)  # eq. (3)


def test_forward_numbers_for_a_known_case() -> None:
    # θ = π − atan(10) − acos(0.15/√1.01) = 0.249484 rad; r_d = 1.014519 m (by calculator).
    result = forward(GEOMETRY, 1.0)
    assert result.theta == pytest.approx(0.2494840, abs=1e-6)
    assert result.deposit_radius == pytest.approx(1.0145192, abs=1e-6)


def test_trolley_wheel_rolls_on_a_circle_about_the_centre() -> None:
    # The trolley axle line passes through O: (W − P) · W = 0, the premise of eqs (6)–(8).
    for r_m in (0.2, 0.5, 3.0):
        theta = forward(GEOMETRY, r_m).theta
        pivot = np.array([GEOMETRY.d_p, r_m])
        wheel = pivot + GEOMETRY.d_tw * np.array([math.cos(theta), -math.sin(theta)])
        assert (wheel - pivot) @ wheel == pytest.approx(0.0, abs=1e-14)


def test_right_turn_mirrors_the_lateral_offset() -> None:
    mirrored = VehicleGeometry(
        d_p=0.10, d_tw=0.15, d_l=0.04, d_t=-0.02, d_w=0.16, wheel_radius=0.03
    )
    assert deposit_radius(GEOMETRY, -0.7) == pytest.approx(
        -deposit_radius(mirrored, 0.7), abs=1e-15
    )


@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["left", "right"])
def test_inverse_round_trips_to_a_nanometre_over_three_decades(sign: float) -> None:
    radii = sign * np.geomspace(0.1, 100.0, 20001)
    midpoint, valid = KINEMATICS.midpoint_radii(radii)
    assert valid.all()
    assert np.max(np.abs(deposit_radius(GEOMETRY, midpoint) - radii)) <= 1e-9
    scalar = [KINEMATICS.midpoint_radius(r) for r in radii[::500]]
    assert np.max(np.abs(deposit_radius(GEOMETRY, np.array(scalar)) - radii[::500])) <= 1e-9
    assert np.allclose(scalar, midpoint[::500], rtol=0, atol=1e-12)


def test_inverse_is_on_the_branch_continuous_with_straight_driving() -> None:
    radii = np.geomspace(KINEMATICS.minimum_laying_radius("left"), 50.0, 5000)
    midpoint, _ = KINEMATICS.midpoint_radii(radii)
    # Larger deposit circle, larger vehicle circle (flat to round-off at the minimum,
    # where dr_d/dr_m is infinite).
    assert np.all(np.diff(midpoint) >= 0)
    assert np.all(np.diff(midpoint[100:]) > 0)


def test_straight_line_limit() -> None:
    assert KINEMATICS.midpoint_radius(math.inf) == math.inf
    assert KINEMATICS.midpoint_radius(-math.inf) == -math.inf
    assert wheel_speed_ratio(GEOMETRY, math.inf) == 1.0
    left, right = wheel_angular_velocities(GEOMETRY, math.inf, 0.3)
    assert left == right == pytest.approx(10.0)
    huge = KINEMATICS.midpoint_radius(1e5)
    assert wheel_speed_ratio(GEOMETRY, huge) == pytest.approx(1.0, abs=2e-6)


@pytest.mark.parametrize(
    ("radius", "reason"),
    [
        (float("nan"), "NaN"),
        (0.0, "zero radius"),
        (0.03, "below the minimum laying radius"),
        (-0.03, "below the minimum laying radius .* right turn"),
    ],
)
def test_unreachable_radii_raise_with_a_reason(radius: float, reason: str) -> None:
    with pytest.raises(UnreachableRadiusError, match=reason) as error:
        KINEMATICS.midpoint_radius(radius)
    assert error.value.radius is radius or math.isnan(error.value.radius)


def test_vectorized_inverse_marks_invalid_radii() -> None:
    radii = np.array([0.5, np.nan, 0.0, 0.01, -0.01, np.inf, -2.0])
    midpoint, valid = KINEMATICS.midpoint_radii(radii)
    assert valid.tolist() == [True, False, False, False, False, True, True]
    assert np.isnan(midpoint[~valid]).all()


def test_minimum_laying_radius_is_where_the_trolley_wheel_reaches_the_centre() -> None:
    # At the arccos limit r_m² + d_p² = d_tw² the trolley wheel sits on O, so the
    # deposit point circles O at the trolley offset z = √(d_l² + d_t²).
    limit = KINEMATICS.geometric_limit
    assert limit == pytest.approx(math.sqrt(0.15**2 - 0.10**2))
    assert abs(deposit_radius(GEOMETRY, limit)) == pytest.approx(GEOMETRY.deposit_offset, abs=1e-12)
    assert math.isnan(deposit_radius(GEOMETRY, 0.5 * limit))
    assert KINEMATICS.minimum_laying_radius("left") == pytest.approx(
        GEOMETRY.deposit_offset, rel=1e-6
    )


def test_right_turns_have_two_solutions_near_the_minimum() -> None:
    # Turning right, the deposit offset points at O: r_d first shrinks then grows with r_m.
    minimum = KINEMATICS.minimum_laying_radius("right")
    target = -(minimum + 0.002)
    solutions = KINEMATICS.all_midpoint_radii(target)
    assert len(solutions) == 2
    assert solutions[0] == pytest.approx(KINEMATICS.midpoint_radius(target))
    for r_m in solutions:
        assert deposit_radius(GEOMETRY, r_m) == pytest.approx(target, abs=1e-12)
    assert abs(solutions[1]) < abs(solutions[0])


def test_wheel_radii_ratio_and_velocities_for_both_turns() -> None:
    inner, outer = wheel_radii(GEOMETRY, 0.5)
    assert (inner, outer) == pytest.approx((0.42, 0.58))
    assert wheel_speed_ratio(GEOMETRY, 0.5) == pytest.approx(0.42 / 0.58)
    left, right = wheel_angular_velocities(GEOMETRY, 0.5, 0.1)
    assert (left, right) == pytest.approx((0.1 * 0.42 / 0.5 / 0.03, 0.1 * 0.58 / 0.5 / 0.03))
    left_r, right_r = wheel_angular_velocities(GEOMETRY, -0.5, 0.1)
    assert (left_r, right_r) == pytest.approx((right, left))
    assert wheel_speed_ratio(GEOMETRY, -0.5) == pytest.approx(wheel_speed_ratio(GEOMETRY, 0.5))


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("d_p", 0.0, "d_p must be positive"),
        ("d_tw", -0.1, "d_tw must be positive"),
        ("wheel_radius", float("nan"), "wheel_radius must be finite"),
        ("d_w", "wide", "d_w must be a number"),
    ],
)
def test_geometry_names_the_bad_field(field: str, value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        VehicleGeometry(**{field: value})


def test_lateral_offset_may_be_zero_or_negative() -> None:
    assert VehicleGeometry(d_t=0.0).deposit_offset == pytest.approx(0.04)
    assert VehicleGeometry(d_t=-0.01).deposit_angle(1.0) < 0

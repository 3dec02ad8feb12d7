"""Layer kinematics: eqs (1)–(12) by hand, the exact inverse, and the domain's edges."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.optimize import brentq

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import (
    LayerKinematics,
    RadiusStatus,
    UnreachableRadiusError,
    deposit_radius,
    forward,
    trolley_wheel_radius,
    wheel_angular_velocities,
    wheel_radii,
    wheel_speed_ratio,
)

GEOMETRY = VehicleGeometry(d_p=0.10, d_tw=0.15, d_l=0.04, d_t=0.02, d_w=0.16, wheel_radius=0.03)
KINEMATICS = LayerKinematics(GEOMETRY)
# d_p > d_tw: no arccos limit; the laying branch starts at r_m = 0 (spinning on the spot).
LONG_TRACTOR = VehicleGeometry(d_p=0.20, d_tw=0.10, d_l=0.04, d_t=0.02, d_w=0.16, wheel_radius=0.03)


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
    # The trolley axle line passes through O: (W − P) · W = 0, the premise of eqs (6)–(8),
    # and W's circle has radius R_w = √(r_m² + d_p² − d_tw²).
    for r_m in (0.2, 0.5, 3.0):
        theta = forward(GEOMETRY, r_m).theta
        pivot = np.array([GEOMETRY.d_p, r_m])
        wheel = pivot + GEOMETRY.d_tw * np.array([math.cos(theta), -math.sin(theta)])
        assert (wheel - pivot) @ wheel == pytest.approx(0.0, abs=1e-14)
        assert np.linalg.norm(wheel) == pytest.approx(trolley_wheel_radius(GEOMETRY, r_m), 1e-14)


def test_deposit_radius_closed_form_equals_eqs_1_to_9() -> None:
    # r_d² = d_l² + (R_w + s·d_t)²: O is on W's axle line, D is d_l along and d_t across it.
    r_m = np.concatenate([np.geomspace(0.112, 1000.0, 2000), -np.geomspace(0.112, 1000.0, 2000)])
    wheel = np.sqrt(r_m**2 + 0.10**2 - 0.15**2)
    closed_form = np.sign(r_m) * np.hypot(0.04, wheel + np.sign(r_m) * 0.02)
    assert np.max(np.abs(deposit_radius(GEOMETRY, r_m) - closed_form)) <= 1e-12


def test_right_turn_mirrors_the_lateral_offset() -> None:
    mirrored = VehicleGeometry(
        d_p=0.10, d_tw=0.15, d_l=0.04, d_t=-0.02, d_w=0.16, wheel_radius=0.03
    )
    assert deposit_radius(GEOMETRY, -0.7) == pytest.approx(
        -deposit_radius(mirrored, 0.7), abs=1e-15
    )


def test_inverse_by_hand() -> None:
    # r_d = 0.5 left: R_w = √(0.5² − 0.04²) − 0.02, r_m = √(R_w² + 0.15² − 0.10²).
    wheel = math.sqrt(0.25 - 0.0016) - 0.02
    assert KINEMATICS.midpoint_radius(0.5) == pytest.approx(math.sqrt(wheel**2 + 0.0125), 1e-15)
    # r_d = −0.5 right: the offset points at O, R_w = √(0.5² − 0.04²) + 0.02.
    wheel = math.sqrt(0.25 - 0.0016) + 0.02
    assert KINEMATICS.midpoint_radius(-0.5) == pytest.approx(-math.sqrt(wheel**2 + 0.0125), 1e-15)


@pytest.mark.parametrize("sign", [1.0, -1.0], ids=["left", "right"])
def test_inverse_round_trips_to_a_nanometre_over_three_decades(sign: float) -> None:
    radii = sign * np.geomspace(0.1, 100.0, 20001)
    inverse = KINEMATICS.midpoint_radii(radii)
    assert inverse.valid.all()
    assert np.max(np.abs(deposit_radius(GEOMETRY, inverse.midpoint_radius) - radii)) <= 1e-9
    scalar = np.array([KINEMATICS.midpoint_radius(r) for r in radii[::50]])
    assert np.max(np.abs(deposit_radius(GEOMETRY, scalar) - radii[::50])) <= 1e-9
    assert np.array_equal(scalar, inverse.midpoint_radius[::50])


@pytest.mark.parametrize("turn", ["left", "right"])
def test_inverse_round_trips_from_the_minimum_radius(turn: str) -> None:
    sign = 1.0 if turn == "left" else -1.0
    minimum = KINEMATICS.minimum_laying_radius(turn)
    radii = sign * minimum * np.geomspace(1.0, 1e4, 5001)
    inverse = KINEMATICS.midpoint_radii(radii)
    assert inverse.valid.all()
    assert np.max(np.abs(deposit_radius(GEOMETRY, inverse.midpoint_radius) - radii)) <= 1e-9


@pytest.mark.parametrize("radius", [0.05, 0.3, 7.0, -0.041, -0.3, -7.0])
def test_closed_form_inverse_agrees_with_brentq_on_eqs_1_to_9(radius: float) -> None:
    # Independent check: bracket the root of eqs (1)–(9) on the laying branch, from the
    # branch start to far beyond r_d, and let scipy find it.
    sign = math.copysign(1.0, radius)
    branch_start = 0.1118034 if sign > 0 else math.sqrt(0.02**2 + 0.0125)
    root = brentq(
        lambda r: abs(deposit_radius(GEOMETRY, sign * r)) - abs(radius),
        branch_start,
        abs(radius) + 1.0,
        xtol=1e-15,
    )
    assert KINEMATICS.midpoint_radius(radius) == pytest.approx(sign * root, abs=1e-12)


def test_inverse_is_on_the_branch_continuous_with_straight_driving() -> None:
    radii = np.geomspace(KINEMATICS.minimum_laying_radius("right"), 50.0, 5000)
    midpoint = np.abs(KINEMATICS.midpoint_radii(-radii).midpoint_radius)
    # Larger deposit circle, larger vehicle circle, all the way down to the minimum.
    assert np.all(np.diff(midpoint) > 0)


def test_straight_line_limit() -> None:
    assert KINEMATICS.midpoint_radius(math.inf) == math.inf
    assert KINEMATICS.midpoint_radius(-math.inf) == -math.inf
    assert deposit_radius(GEOMETRY, -math.inf) == -math.inf
    assert forward(GEOMETRY, math.inf).theta == 0.0
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
        (-0.0, "zero radius"),
        (0.03, r"below the minimum laying radius 0\.0447214 m .* left turn"),
        (-0.039, r"below the minimum laying radius 0\.04 m .* right turn"),
    ],
)
def test_unreachable_radii_raise_with_a_reason(radius: float, reason: str) -> None:
    with pytest.raises(UnreachableRadiusError, match=reason) as error:
        KINEMATICS.midpoint_radius(radius)
    assert error.value.radius is radius


def test_vectorized_inverse_marks_invalid_radii_with_a_status() -> None:
    radii = np.array([0.5, np.nan, 0.0, 0.01, -0.01, np.inf, -2.0])
    inverse = KINEMATICS.midpoint_radii(radii)
    assert inverse.valid.tolist() == [True, False, False, False, False, True, True]
    assert np.isnan(inverse.midpoint_radius[~inverse.valid]).all()
    s = RadiusStatus
    assert inverse.status.tolist() == [
        s.REACHABLE, s.NAN, s.ZERO, s.BELOW_MINIMUM, s.BELOW_MINIMUM, s.REACHABLE, s.REACHABLE
    ]  # fmt: skip


def test_minimum_laying_radii_by_hand() -> None:
    # Left: the branch starts at the arccos limit r_m² + d_p² = d_tw², where the trolley
    # wheel sits on O and D circles it at z = √(d_l² + d_t²).
    limit = KINEMATICS.geometric_limit
    assert limit == pytest.approx(math.sqrt(0.15**2 - 0.10**2), abs=1e-15)
    assert KINEMATICS.minimum_laying_radius("left") == pytest.approx(math.hypot(0.04, 0.02))
    assert deposit_radius(GEOMETRY, limit) == pytest.approx(math.hypot(0.04, 0.02), abs=1e-15)
    # Right: D's offset points at O; r_d is smallest, d_l, when R_w = d_t.
    assert KINEMATICS.minimum_laying_radius("right") == pytest.approx(0.04, abs=1e-15)
    assert KINEMATICS.minimum_laying_radius("both") == KINEMATICS.minimum_laying_radius("left")
    with pytest.raises(ValueError, match="turn must be"):
        KINEMATICS.minimum_laying_radius("up")  # type: ignore[arg-type]


def test_the_arccos_limit_is_the_edge_of_the_forward_domain() -> None:
    limit = KINEMATICS.geometric_limit
    assert math.isnan(deposit_radius(GEOMETRY, 0.999 * limit))
    assert math.isnan(forward(GEOMETRY, 0.0).theta)
    assert np.isfinite(deposit_radius(GEOMETRY, np.array([limit, -limit]))).all()
    inverse = KINEMATICS.midpoint_radii(np.geomspace(0.04472136, 0.05, 1000))
    assert np.all(inverse.midpoint_radius >= limit)


def test_right_turns_have_two_solutions_near_the_minimum() -> None:
    # r_d = −0.042: R_w = 0.02 ± √(0.042² − 0.04²), both above the arccos limit.
    spread = math.sqrt(0.042**2 - 0.04**2)
    expected = [-math.sqrt((0.02 + s) ** 2 + 0.0125) for s in (spread, -spread)]
    solutions = KINEMATICS.all_midpoint_radii(-0.042)
    assert solutions == pytest.approx(expected, abs=1e-15)
    assert solutions[0] == KINEMATICS.midpoint_radius(-0.042)
    assert deposit_radius(GEOMETRY, np.array(solutions)) == pytest.approx([-0.042] * 2, abs=1e-15)


def test_one_solution_away_from_the_fold() -> None:
    assert KINEMATICS.all_midpoint_radii(-0.3) == [KINEMATICS.midpoint_radius(-0.3)]
    assert KINEMATICS.all_midpoint_radii(0.045) == [KINEMATICS.midpoint_radius(0.045)]
    assert KINEMATICS.all_midpoint_radii(-0.04) == [KINEMATICS.midpoint_radius(-0.04)]
    assert KINEMATICS.all_midpoint_radii(math.inf) == [math.inf]
    with pytest.raises(UnreachableRadiusError):
        KINEMATICS.all_midpoint_radii(0.01)


def test_a_long_tractor_cannot_lay_its_tightest_circle() -> None:
    # d_p > d_tw: R_w ≥ S = √(d_p² − d_tw²) with r_m = 0 at R_w = S; left minimum
    # √(d_l² + (S + d_t)²) needs the tractor to spin on the spot.
    kinematics = LayerKinematics(LONG_TRACTOR)
    spin = math.sqrt(0.20**2 - 0.10**2)
    minimum = math.hypot(0.04, spin + 0.02)
    assert kinematics.geometric_limit == 0.0
    assert kinematics.minimum_laying_radius("left") == pytest.approx(minimum, abs=1e-15)
    with pytest.raises(UnreachableRadiusError, match="turning on the spot"):
        kinematics.midpoint_radius(kinematics.minimum_laying_radius("left"))
    status = kinematics.midpoint_radii(kinematics.minimum_laying_radius("left")).status
    assert status == RadiusStatus.SPIN_ON_THE_SPOT
    r_m = kinematics.midpoint_radius(minimum * 1.01)
    assert 0 < r_m < 0.1
    assert deposit_radius(LONG_TRACTOR, r_m) == pytest.approx(minimum * 1.01, abs=1e-12)


def test_wheel_radii_ratio_and_velocities_for_both_turns() -> None:
    inner, outer = wheel_radii(GEOMETRY, 0.5)
    assert (inner, outer) == pytest.approx((0.42, 0.58))  # eqs (10), (11)
    assert wheel_speed_ratio(GEOMETRY, 0.5) == pytest.approx(0.42 / 0.58)  # eq. (12)
    left, right = wheel_angular_velocities(GEOMETRY, 0.5, 0.1)
    # Yaw rate 0.1/0.5 = 0.2 rad/s; wheels at 0.42 and 0.58 m, radius 0.03 m.
    assert (left, right) == pytest.approx((0.2 * 0.42 / 0.03, 0.2 * 0.58 / 0.03))
    left_r, right_r = wheel_angular_velocities(GEOMETRY, -0.5, 0.1)
    assert (left_r, right_r) == pytest.approx((right, left))  # turning right: left is outer
    assert wheel_speed_ratio(GEOMETRY, -0.5) == pytest.approx(wheel_speed_ratio(GEOMETRY, 0.5))
    # Tighter than half the track: the inner wheel runs backwards.
    left, right = wheel_angular_velocities(GEOMETRY, 0.05, 0.1)
    assert left == pytest.approx(0.1 * (1 - 0.08 / 0.05) / 0.03) and left < 0 < right


def test_wheel_velocities_are_vectorized() -> None:
    left, right = wheel_angular_velocities(GEOMETRY, np.array([0.5, -0.5, np.inf]), 0.1)
    assert left == pytest.approx([0.2 * 0.42 / 0.03, 0.2 * 0.58 / 0.03, 0.1 / 0.03])
    assert right == pytest.approx([0.2 * 0.58 / 0.03, 0.2 * 0.42 / 0.03, 0.1 / 0.03])


@pytest.mark.parametrize(
    ("field", "value", "message"),
    [
        ("d_p", 0.0, "d_p must be positive"),
        ("d_tw", -0.1, "d_tw must be positive"),
        ("d_l", -0.04, "d_l must be positive"),
        ("d_w", math.inf, "d_w must be finite"),
        ("wheel_radius", float("nan"), "wheel_radius must be finite"),
        ("d_t", float("nan"), "d_t must be finite"),
        ("d_w", "wide", "d_w must be a number"),
        ("d_p", True, "d_p must be a number"),
    ],
)
def test_geometry_names_the_bad_field(field: str, value: object, message: str) -> None:
    with pytest.raises(ValueError, match=message):
        VehicleGeometry(**{field: value})


def test_lateral_offset_may_be_zero_or_negative() -> None:
    centred = LayerKinematics(VehicleGeometry(d_t=0.0))
    assert centred.minimum_laying_radius("left") == centred.minimum_laying_radius("right") == 0.04
    # d_t < 0 puts the chute on the vehicle's left: the two turns swap roles.
    left_chute = LayerKinematics(VehicleGeometry(d_t=-0.02))
    assert left_chute.minimum_laying_radius("left") == pytest.approx(0.04)
    assert left_chute.minimum_laying_radius("right") == pytest.approx(math.hypot(0.04, 0.02))

"""Deposit paths → wheel schedules, checked against the vehicle simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import LayerKinematics
from dombot_layer.paths import (
    Arc,
    PathError,
    Straight,
    WheelSchedule,
    polyline_segments,
    rig_length,
    schedule_segments,
)
from dombot_layer.vehicle_sim import VehicleSimulator, simulate

GEOMETRY = VehicleGeometry()
KINEMATICS = LayerKinematics(GEOMETRY)


def test_schedule_times_and_wheel_speeds() -> None:
    segments = [Straight(0.5), Arc(0.4, 0.6)]
    schedule = schedule_segments(KINEMATICS, segments, forward_speed=0.1, spacing=0.05)
    assert schedule.start_time[1] == pytest.approx(5.0)
    r_m = KINEMATICS.midpoint_radius(0.4)
    assert schedule.duration - 5.0 == pytest.approx(0.6 / 0.4 * r_m / 0.1)
    assert schedule.command_at(1.0) == pytest.approx((0.1 / 0.03, 0.1 / 0.03))
    left, right = schedule.command_at(6.0)
    assert left / right == pytest.approx((r_m - 0.08) / (r_m + 0.08))
    assert schedule.command_at(schedule.duration + 1) == (0.0, 0.0)
    assert len(schedule.deposit_times) == 23  # 1.1 m at 5 cm, both ends included


def test_schedule_drives_the_simulated_vehicle_along_the_deposit_path() -> None:
    # Straight, then a left quarter circle of deposit radius 0.5 m: the last deposits
    # lie on that circle once the trolley has settled.
    segments = [Straight(1.0), Arc(0.5, 0.5 * math.pi / 2)]
    schedule = schedule_segments(KINEMATICS, segments, forward_speed=0.1, spacing=0.01)
    result = simulate(GEOMETRY, schedule.command_at, schedule.duration, spacing=0.01, max_step=0.02)
    r_m = schedule.midpoint_radius[1]
    # At the start of the arc, M is at (1.0 + offset along the straight) and turns about
    # the point r_m to its left. Straight driving puts M at x = v·t.
    center = np.array([0.1 * schedule.start_time[1], r_m])
    last = np.linalg.norm(result.deposits[-10:] - center, axis=1)
    assert np.max(np.abs(last - 0.5)) < 2e-3
    assert result.deposits.shape[0] == pytest.approx(len(schedule.deposit_times), abs=3)


def circle_centre(simulator: VehicleSimulator, midpoint_radius: float) -> np.ndarray:
    """Centre O of the circle M is about to drive: r_m to the vehicle's left."""
    x, y, heading = simulator.pose()
    return np.array([x, y]) + midpoint_radius * np.array([-math.sin(heading), math.cos(heading)])


def laid_radius_error_per_piece(schedule: WheelSchedule) -> list[float]:
    """Play the schedule piece by piece; for each arc, how far its last dominoes lie from r_d."""
    simulator = VehicleSimulator(GEOMETRY, spacing=0.01)
    errors = []
    for k, r_m in enumerate(schedule.midpoint_radius):
        centre = circle_centre(simulator, r_m) if np.isfinite(r_m) else None
        duration = schedule.start_time[k + 1] - schedule.start_time[k]
        laid = simulator.step(schedule.left[k], schedule.right[k], duration)
        if centre is not None:
            distance = np.linalg.norm(laid[-20:] - centre, axis=1)
            errors.append(float(np.max(np.abs(distance - abs(schedule.deposit_radius[k])))))
    return errors


def test_an_s_curve_lays_both_arcs_on_their_circles() -> None:
    # Three quarters of a turn each way: the trolley settles within each arc, so its
    # last dominoes lie on the requested deposit circle, turning left and then right.
    turn = 0.3 * 1.5 * math.pi
    segments = [Straight(0.3), Arc(0.3, turn), Arc(-0.3, turn)]
    schedule = schedule_segments(KINEMATICS, segments, forward_speed=0.1, spacing=0.01)
    assert schedule.midpoint_radius[1] > 0 > schedule.midpoint_radius[2]
    assert schedule.left[1] < schedule.right[1] and schedule.left[2] > schedule.right[2]
    assert max(laid_radius_error_per_piece(schedule)) < 1e-4


def test_look_ahead_adds_a_rig_length_of_lead_out() -> None:
    segments = [Straight(0.5), Arc(0.4, 0.6)]
    plain = schedule_segments(KINEMATICS, segments, 0.1, 0.05)
    ahead = schedule_segments(KINEMATICS, segments, 0.1, 0.05, look_ahead=True)
    assert rig_length(GEOMETRY) == pytest.approx(0.10 + 0.15 + 0.04)
    assert np.array_equal(ahead.start_time[:-1], plain.start_time)
    assert ahead.duration - plain.duration == pytest.approx(rig_length(GEOMETRY) / 0.1)
    assert np.isinf(ahead.deposit_radius[-1])


def test_too_tight_arc_is_named_by_position() -> None:
    too_tight = r"at 0\.700 m along the path \(segment 2\).*minimum laying radius"
    with pytest.raises(PathError, match=too_tight):
        schedule_segments(KINEMATICS, [Straight(0.5), Arc(1.0, 0.2), Arc(-0.01, 0.1)], 0.1, 0.02)


def test_too_tight_polyline_is_named_by_position() -> None:
    # Half a metre straight, then a loop of radius 3 cm (minimum laying radius 4.5 cm).
    straight = np.column_stack([np.linspace(0.0, 0.5, 60), np.zeros(60)])
    angle = np.linspace(0.0, 2 * math.pi, 40)[1:]
    loop = np.column_stack([0.5 + 0.03 * np.sin(angle), 0.03 - 0.03 * np.cos(angle)])
    segments = polyline_segments(np.vstack([straight, loop]))  # its last point repeats (0.5, 0)
    assert all(math.isfinite(s.radius) for s in segments if isinstance(s, Arc))
    with pytest.raises(PathError, match=r"at 0\.4\d\d m along the path.*minimum laying radius"):
        schedule_segments(KINEMATICS, segments, 0.1, 0.02)


def test_unknown_radius_inside_a_path_is_refused() -> None:
    with pytest.raises(PathError, match=r"segment 1\).*NaN"):
        schedule_segments(KINEMATICS, [Straight(0.5), Arc(math.nan, 0.2)], 0.1, 0.02)
    with pytest.raises(PathError, match="positive, finite length"):
        schedule_segments(KINEMATICS, [Straight(0.5), Arc(0.5, 0.0)], 0.1, 0.02)


@pytest.mark.parametrize("speed", [0.0, -1.0, float("nan")])
def test_bad_speed_is_refused(speed: float) -> None:
    with pytest.raises(PathError, match="forward speed"):
        schedule_segments(KINEMATICS, [Straight(1.0)], speed, 0.02)


def test_polyline_fit_recovers_a_circle_curvature() -> None:
    angles = np.linspace(0.0, math.pi, 25)
    points = 0.6 * np.column_stack([np.sin(angles), 1.0 - np.cos(angles)])
    segments = polyline_segments(points, step=0.01)
    radii = np.array([s.radius for s in segments if isinstance(s, Arc)])
    inner = radii[len(radii) // 5 : -len(radii) // 5]
    assert np.median(inner) == pytest.approx(0.6, rel=1e-3)
    assert sum(s.length for s in segments) == pytest.approx(0.6 * math.pi, rel=1e-4)


def test_polyline_needs_three_finite_points() -> None:
    with pytest.raises(PathError, match="three distinct"):
        polyline_segments(np.array([[0.0, 0.0], [1.0, 0.0], [1.0, 0.0]]))
    with pytest.raises(PathError, match=r"\(n, 2\)"):
        polyline_segments(np.zeros((4, 3)))
    with pytest.raises(PathError, match="finite"):
        polyline_segments(np.array([[0.0, 0.0], [1.0, np.nan], [2.0, 0.0]]))

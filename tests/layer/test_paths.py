"""Deposit paths → wheel schedules, checked against the vehicle simulation."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import LayerKinematics
from dombot_layer.paths import Arc, PathError, Straight, polyline_segments, schedule_segments
from dombot_layer.vehicle_sim import simulate

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


def test_too_tight_arc_is_named_by_position() -> None:
    too_tight = r"at 0\.700 m along the path \(segment 2\).*minimum laying radius"
    with pytest.raises(PathError, match=too_tight):
        schedule_segments(KINEMATICS, [Straight(0.5), Arc(1.0, 0.2), Arc(-0.01, 0.1)], 0.1, 0.02)


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
    with pytest.raises(PathError, match="three"):
        polyline_segments(np.array([[0.0, 0.0], [1.0, 0.0]]))
    with pytest.raises(PathError, match="finite"):
        polyline_segments(np.array([[0.0, 0.0], [1.0, np.nan], [2.0, 0.0]]))

"""Deposit paths (lines, arcs, smoothed polylines) → time-stamped wheel schedules.

The user describes where the dominoes should go (the *deposit* path). Each piece
of constant curvature maps to a vehicle midpoint radius by inverse kinematics; in
steady state the whole vehicle–trolley rig turns rigidly about the centre O, so a
deposit arc of length L and radius r_d takes (L/|r_d|)·|r_m|/v seconds at midpoint
speed v. The schedule is that steady-state plan; the trolley needs a short
distance to settle after each change of curvature (vehicle_sim shows how much).
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.interpolate import splev, splprep

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import (
    LayerKinematics,
    UnreachableRadiusError,
    wheel_angular_velocities,
)


@dataclass(frozen=True)
class Straight:
    length: float  # m


@dataclass(frozen=True)
class Arc:
    radius: float  # m, signed: + turns left
    length: float  # m of deposit path


Segment = Straight | Arc


@dataclass(frozen=True)
class WheelSchedule:
    """Piecewise-constant wheel commands: command k holds from start_time[k] to start_time[k+1]."""

    start_time: np.ndarray  # s, one more entry than commands: the last is the end time
    left: np.ndarray  # rad/s
    right: np.ndarray  # rad/s
    deposit_radius: np.ndarray  # m, signed, inf = straight
    midpoint_radius: np.ndarray  # m, signed
    deposit_times: np.ndarray  # s, when each domino is laid (steady state)

    @property
    def duration(self) -> float:
        return float(self.start_time[-1])

    def command_at(self, t: float) -> tuple[float, float]:
        """Wheel velocities at time t; zero (stopped) outside the schedule."""
        if not 0.0 <= t < self.duration:
            return 0.0, 0.0
        k = int(np.searchsorted(self.start_time, t, side="right")) - 1
        return float(self.left[k]), float(self.right[k])


class PathError(ValueError):
    """A path the vehicle cannot lay; the message says where along the path."""


def rig_length(geometry: VehicleGeometry) -> float:
    """How far the deposit point trails the drive-axle midpoint when driving straight."""
    return geometry.d_p + geometry.d_tw + geometry.d_l


def schedule_segments(
    kinematics: LayerKinematics,
    segments: list[Segment],
    forward_speed: float,
    spacing: float,
    look_ahead: bool = False,
) -> WheelSchedule:
    """Wheel schedule laying dominoes every ``spacing`` metres along the deposit path.

    Without ``look_ahead`` piece k is steered when the deposit point reaches it,
    so every curvature change acts a rig length late at D. With ``look_ahead``
    each piece is steered when the drive axle M reaches it (the path is
    anchored at M's start, a rig length ahead of D), and a final straight of the
    rig length lets the deposit point finish the last piece.
    """
    if not (forward_speed > 0 and math.isfinite(forward_speed)):
        raise PathError(f"forward speed must be a positive number of m/s, got {forward_speed}")
    if not (spacing > 0 and math.isfinite(spacing)):
        raise PathError(f"spacing must be a positive number of metres, got {spacing}")
    if look_ahead:
        segments = [*segments, Straight(rig_length(kinematics.geometry))]
    deposit_r = np.array(
        [math.inf if isinstance(s, Straight) else s.radius for s in segments], dtype=float
    )
    lengths = np.array([s.length for s in segments], dtype=float)
    if not np.all((lengths > 0) & np.isfinite(lengths)):
        raise PathError("every segment needs a positive, finite length")
    midpoint_r = _midpoint_radii_or_raise(kinematics, deposit_r, lengths)
    # Deposit point speed = v·|r_d|/|r_m| (rigid rotation about O); 1·v when straight.
    with np.errstate(invalid="ignore"):  # inf/inf on straights, replaced by 1
        ratio = np.where(np.isinf(deposit_r), 1.0, np.abs(deposit_r) / np.abs(midpoint_r))
    deposit_speed = ratio * forward_speed
    durations = lengths / deposit_speed
    start_time = np.concatenate([[0.0], np.cumsum(durations)])
    left, right = wheel_angular_velocities(kinematics.geometry, midpoint_r, forward_speed)
    path_position = np.arange(0.0, lengths.sum() + 1e-12, spacing)
    deposit_times = np.interp(
        path_position, np.concatenate([[0.0], np.cumsum(lengths)]), start_time
    )
    return WheelSchedule(
        start_time, np.asarray(left), np.asarray(right), deposit_r, midpoint_r, deposit_times
    )


def _midpoint_radii_or_raise(
    kinematics: LayerKinematics, deposit_radii: np.ndarray, lengths: np.ndarray
) -> np.ndarray:
    """r_m for every piece; the first unlayable piece is named by its distance along the path."""
    inverse = kinematics.midpoint_radii(deposit_radii)
    if not np.all(inverse.valid):
        first = int(np.argmin(inverse.valid))
        try:
            kinematics.midpoint_radius(deposit_radii[first])
        except UnreachableRadiusError as error:
            where = f"{float(lengths[:first].sum()):.3f} m along the path (segment {first})"
            raise PathError(f"at {where}: {error}") from error
    return inverse.midpoint_radius


# Polylines (e.g. /layer/path): what a vehicle can lay in one go; larger ones are refused.
MAX_POLYLINE_POINTS = 10_000
MAX_POLYLINE_EXTENT = 100.0  # m, every coordinate
MAX_POLYLINE_LENGTH = 1000.0  # m along the fitted spline
MIN_POLYLINE_STEP = 1e-4  # m: a point closer than this to the previous one repeats it
# bytes of a serialized nav_msgs/Path: MAX_POLYLINE_POINTS poses take 0.7-1 MB (72 bytes a
# pose, more with a frame id), so any allowed path with frame ids under 300 characters fits
MAX_PATH_BYTES = 4 << 20


def path_segments(points: np.ndarray) -> list[Segment]:
    """A path message's points: two distinct ones are one straight, more a polyline; both
    within the polyline limits."""
    points = np.asarray(points, dtype=float)
    if len(points) == 2 and np.all(np.isfinite(points)):
        length = math.hypot(*(points[1] - points[0]))
        if 0 < length <= MAX_POLYLINE_LENGTH:
            return [Straight(length)]
        if length > MAX_POLYLINE_LENGTH:
            raise PathError(f"a path is at most {MAX_POLYLINE_LENGTH} m long, got {length:.3g} m")
    if len(points) < 2:
        raise PathError("a path needs at least two poses")
    return polyline_segments(points)


def polyline_segments(
    points: np.ndarray, step: float = 0.01, smoothing: float = 0.0
) -> list[Segment]:
    """Fit a smooth cubic spline through a polyline and cut it into short constant-curvature arcs.

    ``smoothing`` is scipy's ``splprep`` s (0 interpolates the points). Each
    piece of ``step`` metres gets the spline's curvature at its middle.
    """
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2:
        raise PathError(f"a polyline is an (n, 2) array of points, got shape {points.shape}")
    if not np.all(np.isfinite(points)):
        raise PathError("polyline points must be finite")
    if len(points) > MAX_POLYLINE_POINTS or np.any(np.abs(points) > MAX_POLYLINE_EXTENT):
        raise PathError(
            f"a polyline has at most {MAX_POLYLINE_POINTS} points within "
            f"±{MAX_POLYLINE_EXTENT} m, got {len(points)} up to {np.abs(points).max():.3g} m"
        )
    steps = np.hypot(*np.diff(points, axis=0).T)
    repeated = np.concatenate([[False], steps < MIN_POLYLINE_STEP])
    points = points[~repeated]  # a (nearly) zero-length step has no direction for the spline
    if len(points) < 3:
        raise PathError("a polyline needs at least three distinct (x, y) points")
    try:
        tck, _ = splprep(points.T, s=smoothing, k=min(3, len(points) - 1))
    except ValueError as error:  # FITPACK refuses some degenerate point sets
        raise PathError(f"no spline fits the polyline: {error}") from None
    u = np.linspace(0.0, 1.0, 20001)
    dx, dy = splev(u, tck, der=1)
    ddx, ddy = splev(u, tck, der=2)
    speed = np.hypot(dx, dy)
    arc_length = np.concatenate([[0.0], np.cumsum(0.5 * (speed[1:] + speed[:-1]) * np.diff(u))])
    curvature = (dx * ddy - dy * ddx) / speed**3
    if arc_length[-1] > MAX_POLYLINE_LENGTH:
        raise PathError(
            f"a polyline is at most {MAX_POLYLINE_LENGTH} m long, got {arc_length[-1]:.3g} m"
        )
    count = max(1, round(arc_length[-1] / step))
    edges = np.linspace(0.0, arc_length[-1], count + 1)
    middle_curvature = np.interp(0.5 * (edges[1:] + edges[:-1]), arc_length, curvature)
    piece = arc_length[-1] / count
    return [Straight(piece) if abs(k) < 1e-9 else Arc(1.0 / k, piece) for k in middle_curvature]


def trace_segments(segments: list[Segment], step: float = 0.005) -> np.ndarray:
    """Points (n, 2) along the path, starting at the origin heading +x, every ≤ ``step`` m."""
    position, heading = np.zeros(2), 0.0
    points = [position]
    for segment in segments:
        s = np.linspace(0.0, segment.length, max(2, math.ceil(segment.length / step) + 1))[1:]
        if isinstance(segment, Straight):
            piece = position + np.outer(s, [math.cos(heading), math.sin(heading)])
        else:
            r = segment.radius
            centre = position + r * np.array([-math.sin(heading), math.cos(heading)])
            angle = heading + s / r
            piece = centre + r * np.column_stack([np.sin(angle), -np.cos(angle)])
            heading += segment.length / r
        points.extend(piece)
        position = piece[-1]
    return np.array(points)

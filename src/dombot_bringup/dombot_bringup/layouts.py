"""Domino run layouts: shapes → upright domino poses, and their validation.

A layout is a planar curve sampled by arc length at the run's spacing; each domino
stands upright on it (body x up) facing along the curve (body z = tangent, the
direction it topples). Validation runs before anything moves and names the first
bad domino, because a builder fixes a layout one domino at a time.
"""

from __future__ import annotations

import csv
import io
import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from scipy.interpolate import CubicSpline
from scipy.spatial import cKDTree
from scipy.spatial.transform import Rotation

from dombot_bringup.footprints import footprints_meet

DOMINO_LENGTH = 0.048  # m, standing height
DOMINO_WIDTH = 0.024  # m, across the run
DOMINO_THICKNESS = 0.0075  # m, along the run
DEFAULT_SPACING_RATIO = 0.6  # centre spacing / height, as in the physics tests
MIN_SPACING_RATIO = 0.3  # tighter: the wave stops (0.25 stopped after 3 of 20, bench_wave)
MAX_SPACING_RATIO = 0.9  # looser: a falling domino (reach ~height) may miss the next


class LayoutError(ValueError):
    """A layout cannot be built; the message names the first offending domino."""


@dataclass(frozen=True)
class DominoPlacement:
    """Target pose of one upright domino: position on the table and heading (rad).

    The heading is the direction of the run at this domino; the domino's body z
    axis points along it and its body x axis points up.
    """

    index: int
    x: float
    y: float
    heading: float

    @property
    def z(self) -> float:
        return DOMINO_LENGTH / 2.0

    def quaternion_wxyz(self) -> tuple[float, float, float, float]:
        """World orientation: body x → world z, body z → (cos h, sin h, 0)."""
        return _upright_quaternion(self.heading)


@dataclass(frozen=True)
class BuildArea:
    """Where the arm may build: an axis-aligned box on the table and a reach annulus."""

    x_min: float
    x_max: float
    y_min: float
    y_max: float
    reach_min: float  # m from the arm base axis
    reach_max: float
    base_xy: tuple[float, float] = (0.0, 0.0)

    def contains(self, x: float, y: float) -> bool:
        return self.x_min <= x <= self.x_max and self.y_min <= y <= self.y_max

    def reach_of(self, x: float, y: float) -> float:
        return math.hypot(x - self.base_xy[0], y - self.base_xy[1])

    @property
    def middle(self) -> tuple[float, float]:
        """The box's centre: where a circle or spiral fits by default."""
        return ((self.x_min + self.x_max) / 2, (self.y_min + self.y_max) / 2)


def _upright_quaternion(heading: float) -> tuple[float, float, float, float]:
    # Columns of R are the body axes in world: x_b = up, z_b = tangent, y_b = z_b × x_b.
    tangent = np.array([math.cos(heading), math.sin(heading), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    rotation = np.column_stack([up, np.cross(tangent, up), tangent])
    x, y, z, w = Rotation.from_matrix(rotation).as_quat()
    return (float(w), float(x), float(y), float(z))


def resolve_spacing(spacing: float | None) -> float:
    """Centre spacing along the run; None picks the default fraction of the height."""
    if spacing is None:
        return DEFAULT_SPACING_RATIO * DOMINO_LENGTH
    if not math.isfinite(spacing):
        raise LayoutError(f"spacing must be a finite number of metres, got {spacing}")
    low, high = MIN_SPACING_RATIO * DOMINO_LENGTH, MAX_SPACING_RATIO * DOMINO_LENGTH
    if not low <= spacing <= high:
        raise LayoutError(
            f"spacing {spacing * 1000:.1f} mm would not topple reliably: keep it between "
            f"{low * 1000:.1f} and {high * 1000:.1f} mm ({MIN_SPACING_RATIO:.0%}–"
            f"{MAX_SPACING_RATIO:.0%} of the {DOMINO_LENGTH * 1000:.0f} mm domino height)"
        )
    return spacing


def sample_curve(
    point_at: Callable[[np.ndarray], np.ndarray], length: float, count: int, spacing: float
) -> list[DominoPlacement]:
    """Place ``count`` dominoes at ``spacing`` along an arc-length parametrised curve."""
    if count < 1:
        raise LayoutError(f"a run needs at least one domino, got count={count}")
    needed = (count - 1) * spacing
    if needed > length + 1e-9:
        raise LayoutError(
            f"{count} dominoes at {spacing * 1000:.1f} mm need {needed:.3f} m of curve, "
            f"the shape is only {length:.3f} m long"
        )
    s = np.arange(count) * spacing
    points = point_at(s)
    eps = 1e-6
    ahead = point_at(np.minimum(s + eps, length))
    behind = point_at(np.maximum(s - eps, 0.0))
    tangents = ahead - behind
    headings = np.arctan2(tangents[:, 1], tangents[:, 0])
    return [
        DominoPlacement(index=i, x=float(p[0]), y=float(p[1]), heading=float(h))
        for i, (p, h) in enumerate(zip(points, headings, strict=True))
    ]


def line(
    start: tuple[float, float], heading: float, count: int, spacing: float | None = None
) -> list[DominoPlacement]:
    """A straight run starting at ``start`` towards ``heading`` (rad)."""
    spacing = resolve_spacing(spacing)
    direction = np.array([math.cos(heading), math.sin(heading)])

    def point_at(s: np.ndarray) -> np.ndarray:
        return np.asarray(start) + np.outer(s, direction)

    return sample_curve(point_at, (count - 1) * spacing, count, spacing)


def arc(
    center: tuple[float, float],
    radius: float,
    start_angle: float,
    count: int,
    spacing: float | None = None,
    clockwise: bool = False,
) -> list[DominoPlacement]:
    """An arc of a circle; a full ``circle`` is an arc whose length fits the count."""
    if not radius > 0:
        raise LayoutError(f"arc radius must be positive, got {radius}")
    spacing = resolve_spacing(spacing)
    sign = -1.0 if clockwise else 1.0

    def point_at(s: np.ndarray) -> np.ndarray:
        angle = start_angle + sign * s / radius
        return np.asarray(center) + radius * np.column_stack([np.cos(angle), np.sin(angle)])

    return sample_curve(point_at, 2 * math.pi * radius, count, spacing)


def circle(
    center: tuple[float, float], radius: float, spacing: float | None = None
) -> list[DominoPlacement]:
    """As many dominoes as fit around a full circle, leaving one gap for the strike."""
    spacing = resolve_spacing(spacing)
    count = int(2 * math.pi * radius // spacing)
    return arc(center, radius, 0.0, count, spacing)


def spiral(
    center: tuple[float, float],
    inner_radius: float,
    pitch: float,
    count: int,
    spacing: float | None = None,
) -> list[DominoPlacement]:
    """An Archimedean spiral r = inner_radius + pitch·θ/(2π), walked outwards."""
    if not (inner_radius > 0 and pitch > 0):
        raise LayoutError("spiral needs a positive inner radius and pitch")
    spacing = resolve_spacing(spacing)
    theta = np.linspace(0.0, 40 * math.pi, 20001)
    radii = inner_radius + pitch * theta / (2 * math.pi)
    points = np.asarray(center) + radii[:, None] * np.column_stack([np.cos(theta), np.sin(theta)])
    return _sample_polyline(points, count, spacing, smooth=False)


def s_curve(
    start: tuple[float, float],
    heading: float,
    length: float,
    amplitude: float,
    count: int,
    spacing: float | None = None,
) -> list[DominoPlacement]:
    """One full sine period of ``amplitude`` along ``length`` in direction ``heading``."""
    spacing = resolve_spacing(spacing)
    u = np.linspace(0.0, length, 2001)
    lateral = amplitude * np.sin(2 * math.pi * u / length)
    c, s = math.cos(heading), math.sin(heading)
    points = np.asarray(start) + np.column_stack([u * c - lateral * s, u * s + lateral * c])
    return _sample_polyline(points, count, spacing, smooth=False)


def polyline(
    points: np.ndarray, count: int | None = None, spacing: float | None = None
) -> list[DominoPlacement]:
    """A user's polyline, smoothed by a cubic spline through its vertices."""
    spacing = resolve_spacing(spacing)
    points = np.asarray(points, dtype=float)
    if points.ndim != 2 or points.shape[1] != 2 or len(points) < 2:
        raise LayoutError("a polyline needs at least two (x, y) points")
    if not np.all(np.isfinite(points)):
        raise LayoutError("polyline points must be finite numbers")
    return _sample_polyline(points, count, spacing, smooth=len(points) > 2)


def from_csv(
    path: Path, count: int | None = None, spacing: float | None = None
) -> list[DominoPlacement]:
    """A polyline from a CSV file of ``x,y`` rows in metres (a header row is allowed).

    Read as UTF-8 with an optional byte-order mark (spreadsheets write one: read as
    plain UTF-8 it made the first point look like a header, dropped silently)."""
    try:
        with Path(path).open(newline="", encoding="utf-8-sig") as handle:
            text = handle.read()
        if "\x00" in text:  # UTF-16 without a byte-order mark decodes as UTF-8 with NULs
            raise UnicodeError
        rows = _csv_points(path, list(csv.reader(io.StringIO(text, newline=""))))
    except (OSError, UnicodeError, csv.Error) as error:
        raise LayoutError(f"cannot read --csv {path}: {_reason(error)}") from None
    return polyline(np.array(rows), count, spacing)


def _reason(error: Exception) -> str:
    if isinstance(error, IsADirectoryError):
        return "it is a directory, not a file"
    if isinstance(error, UnicodeError):
        return "it is not UTF-8 text (UTF-16? save it as CSV UTF-8)"
    if isinstance(error, csv.Error):
        return f"it is not plain CSV text ({error})"
    return error.strerror or str(error)


def _csv_points(path: Path, table: list[list[str]]) -> list[tuple[float, float]]:
    rows = []
    for line_number, row in enumerate(table, start=1):
        if not row or row[0].strip().startswith("#"):
            continue
        try:
            rows.append((float(row[0]), float(row[1])))
        except (ValueError, IndexError):
            if line_number == 1:
                continue  # header
            raise LayoutError(
                f"{path}:{line_number}: expected 'x,y' in metres, got {row}"
            ) from None
    return rows


def _sample_polyline(
    points: np.ndarray, count: int | None, spacing: float, smooth: bool
) -> list[DominoPlacement]:
    keep = np.concatenate([[True], np.linalg.norm(np.diff(points, axis=0), axis=1) > 1e-9])
    points = points[keep]
    if len(points) < 2:
        raise LayoutError("the polyline has no length")
    chord = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(points, axis=0), axis=1))])
    if smooth:
        spline = CubicSpline(chord, points, bc_type="natural")
        dense_t = np.linspace(0.0, chord[-1], 50 * len(points) + 1000)
        dense = spline(dense_t)
    else:
        dense = points
    arc_length = np.concatenate([[0.0], np.cumsum(np.linalg.norm(np.diff(dense, axis=0), axis=1))])
    total = float(arc_length[-1])
    if count is None:
        count = int(total // spacing) + 1

    def point_at(s: np.ndarray) -> np.ndarray:
        return np.column_stack([np.interp(s, arc_length, dense[:, k]) for k in range(2)])

    return sample_curve(point_at, total, count, spacing)


def validate(placements: list[DominoPlacement], area: BuildArea) -> None:
    """Raise LayoutError naming the first domino off the area, out of reach or overlapping."""
    if not placements:
        raise LayoutError("the layout has no dominoes")
    for placement in placements:
        where = f"domino {placement.index} at ({placement.x:.3f}, {placement.y:.3f}) m"
        if not area.contains(placement.x, placement.y):
            raise LayoutError(
                f"{where} is outside the build area x∈[{area.x_min}, {area.x_max}], "
                f"y∈[{area.y_min}, {area.y_max}] m"
            )
        reach = area.reach_of(placement.x, placement.y)
        if not area.reach_min <= reach <= area.reach_max:
            raise LayoutError(
                f"{where} is {reach:.3f} m from the arm base; the arm places between "
                f"{area.reach_min} and {area.reach_max} m"
            )
    _check_overlaps(placements)


def safety_gaps(placements: list[DominoPlacement], section: int) -> list[range]:
    """Slots to leave empty until the rest of the run stands, one range a gap: after every
    ``section`` dominoes, a builder's safety gap (``gap_at``), so a domino that falls by
    accident takes down at most its own section. ``section`` 0: none."""
    count = len(placements)
    gaps: list[range] = []
    first = section if section > 0 else count
    while first < count - 1 and (gap := gap_at(placements, first)) is not None:
        gaps.append(gap)
        first = gap.stop + section
    return gaps


def gap_at(placements: list[DominoPlacement], first: int) -> range | None:
    """The safety gap from slot ``first`` on: as many slots as it takes for the dominoes
    either side to stand more than a domino's height plus thickness apart; None when it
    would reach the run's end (nothing behind it to protect)."""
    centres = np.array([[p.x, p.y] for p in placements])
    reach = DOMINO_LENGTH + DOMINO_THICKNESS  # a toppling domino's top lands this far out
    after = first + 1  # the first domino beyond the gap
    while after < len(centres) and np.linalg.norm(centres[after] - centres[first - 1]) <= reach:
        after += 1
    return range(first, after) if first > 0 and after < len(centres) else None


def _footprint_corners(placement: DominoPlacement) -> np.ndarray:
    along = (
        np.array([math.cos(placement.heading), math.sin(placement.heading)]) * DOMINO_THICKNESS / 2
    )
    across = (
        np.array([-math.sin(placement.heading), math.cos(placement.heading)]) * DOMINO_WIDTH / 2
    )
    centre = np.array([placement.x, placement.y])
    return np.array([centre + a + b for a in (along, -along) for b in (across, -across)])


def _check_overlaps(placements: list[DominoPlacement]) -> None:
    centres = np.array([[p.x, p.y] for p in placements])
    reach = math.hypot(DOMINO_WIDTH, DOMINO_THICKNESS)
    pairs = sorted(cKDTree(centres).query_pairs(reach))
    for i, j in pairs:
        if footprints_meet(_footprint_corners(placements[i]), _footprint_corners(placements[j])):
            raise LayoutError(
                f"domino {placements[j].index} at ({placements[j].x:.3f}, {placements[j].y:.3f}) m "
                f"overlaps domino {placements[i].index}"
            )

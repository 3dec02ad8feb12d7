"""Flat dominoes lying side by side show the depth cameras one face at one height: over
two of them, long side to long side, a box fits as well turned 90°, across a half of
each, or straddling the seam, as along either domino. Arc cycles (seed 1, cycle 5)
refitted such a pair so, 12-14 mm and 72-88° off each domino, and three picks closed on
nothing (the pads came down on the pair).

A fit whose face goes on, level, past its long sides (``level_beside``) is suspect. The
colour images may tell: a domino's face is one flat colour, and where two touch a thin
darker seam may run between them (``seam_across``); then each is fitted again from where
it lies, along the seam and a half width either side of it (``pair_seeds``,
``on_its_side``). With no seam seen, where the dominoes lie is unknown
(``placement_check._lying_fit``: not fitted). The simulator's dominoes are plain: a
face with pips would need the pips told from a seam."""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np

from dombot_perception.domino_model import HALF_SIZE
from dombot_perception.frames import CameraView

FLAT = math.cos(math.radians(10.0))  # |face normal · vertical| above this: lying flat
GAP = 0.0015  # m past a long side before its strip starts (the box's own edge points)
BAND = 0.006  # m: how far past a long side the face is looked for
LEVEL = 0.002  # m: points this near the top face's height are on it or on one beside it
AROUND = 0.2  # of the face's own density of points in the strips beside it: it goes on
STEP = 0.001  # m between the lines sampled across the face, and along each
REACH = (0.018, 0.009)  # m from the centre along the length and the width: clear of the edges
TURNS = np.radians(np.arange(-90.0, 90.0, 5.0))  # of the lines from across the face
DARKER = 0.95  # of the lines beside it: a line this dark is a seam
DEPTH_TOLERANCE = 0.003  # m: a sample whose depth differs more is hidden (not the face)
MIN_SAMPLES = 8  # per line: fewer seen leave it out
FULL_LINE = 0.6  # of the longest line's samples: a line across a corner of the face has few
SEAM_SIDE = 0.003  # m: a seam is darker than the lines this far either side of it
SEAM_WIDTH = 0.001  # m: a fit on one side of a seam keeps the points this far past it
SEAM_TURN = math.radians(10.0)  # a domino of a pair lies along its seam within this
SEAM_OFFSET = 0.003  # m: and its centre a half width from it within this


@dataclass(frozen=True)
class Seam:
    """Where a seam crosses a face: a point on it (world) and its direction (unit, world)."""

    point: np.ndarray
    direction: np.ndarray


def is_flat(pose: np.ndarray) -> bool:
    """The box at ``pose`` lies on a face (its thickness axis near vertical)."""
    return abs(float(pose[2, 2])) > FLAT


def level_beside(pose: np.ndarray, points: np.ndarray) -> bool:
    """The top face of the flat box at ``pose`` goes on, level, past its long sides (where
    the pads go) in ``points``: in the strips from GAP to GAP + BAND past them, as long as
    the box and the strips past its ends, the points within LEVEL of the face's height
    come to AROUND of what the face's own density would put there (a neighbour flush
    along one long side, about 0.4; a box across or straddling two dominoes side by side,
    or turned over them, more; one end to end, none)."""
    local = (points - pose[:3, 3]) @ pose[:3, :3]
    level = np.abs(points[:, 2] - (pose[2, 3] + HALF_SIZE[2])) < LEVEL
    outside = np.abs(local[:, :2]) - HALF_SIZE[:2]
    on_face = level & np.all(outside < 0.0, axis=1)
    strips = level & np.all(outside < GAP + BAND, axis=1) & (outside[:, 1] > GAP)
    area = 2 * BAND * 2 * (HALF_SIZE[0] + GAP + BAND)
    expected = on_face.sum() / (4 * HALF_SIZE[0] * HALF_SIZE[1]) * area
    return bool(expected > 0 and strips.sum() >= AROUND * expected)


def seam_across(pose: np.ndarray, views: list[CameraView]) -> Seam | None:
    """A seam on the top face of the flat box at ``pose`` in any of ``views``: of the
    lines over the face (in each of TURNS, STEP apart), the darkest against those beside
    it, when it is DARKER; None when the face is one colour."""
    up = pose[:3, 2] * np.sign(pose[2, 2])
    top = pose[:3, 3] + HALF_SIZE[2] * up
    grid = np.stack(np.meshgrid(*(np.arange(-r, r + STEP / 2, STEP) for r in REACH)), axis=-1)
    grid = grid.reshape(-1, 2)
    samples = top + grid[:, :1] * pose[:3, 0] + grid[:, 1:] * pose[:3, 1]
    best, darkest = None, DARKER
    for view in views:
        brightness = _brightness(samples, view)
        seen = np.isfinite(brightness)
        if seen.sum() < len(samples) / 2:
            continue
        for turn in TURNS:
            found = _darkest_line(grid[seen], brightness[seen], turn)
            if found is not None and found[0] < darkest:
                darkest, offset = found
                along, across = _line_axes(turn)  # (length, width) components
                in_world = pose[:3, :2]
                best = Seam(top + offset * in_world @ across, in_world @ along)
    return best


def pair_seeds(pose: np.ndarray, seam: Seam) -> list[np.ndarray]:
    """The two dominoes either side of ``seam`` on the face of the flat box at ``pose``:
    their length along the seam, their centres a half width from it on each side."""
    up = pose[:3, 2] * np.sign(pose[2, 2])
    length = seam.direction
    width = np.cross(up, length)
    seeds = []
    for sign in (1.0, -1.0):
        seed = np.eye(4)
        seed[:3, :3] = np.column_stack([length, width, up])
        seed[:3, 3] = seam.point + sign * HALF_SIZE[1] * width
        seed[2, 3] = pose[2, 3]
        seeds.append(seed)
    return seeds


def on_its_side(points: np.ndarray, seam: Seam, seed: np.ndarray) -> np.ndarray:
    """Which of ``points`` lie on the side of ``seam`` where the domino at ``seed`` lies
    (``pair_seeds``), within SEAM_WIDTH of it: its fit does not reach past the seam onto
    its neighbour's face, level with its own."""
    away = seed[:3, 3] - seam.point
    away[2] = 0.0
    away /= np.linalg.norm(away)
    return (points - seam.point) @ away > -SEAM_WIDTH


def along_seam(pose: np.ndarray, seam: Seam) -> bool:
    """The box at ``pose`` lies along ``seam`` and beside it, as a domino of the pair
    does: its length within SEAM_TURN of the seam's direction, its centre a half width
    from the seam within SEAM_OFFSET (a fit sliding off its seed onto the neighbour's
    face, level with its own, turned 36° in one scene)."""
    parallel = abs(float(pose[:3, 0] @ seam.direction)) > math.cos(SEAM_TURN)
    offset = pose[:2, 3] - seam.point[:2]
    direction = seam.direction[:2] / np.linalg.norm(seam.direction[:2])
    across = abs(offset[0] * direction[1] - offset[1] * direction[0])
    return parallel and abs(across - HALF_SIZE[1]) < SEAM_OFFSET


def _darkest_line(
    grid: np.ndarray, brightness: np.ndarray, turn: float
) -> tuple[float, float] | None:
    """Of the lines over the face turned ``turn`` from its width axis (``grid``: the seen
    samples' (length, width) offsets, ``brightness``: theirs), the one darkest against
    the lines SEAM_SIDE either side of it (a thin dark line, not a shade or an edge), as
    its brightness over the brighter of theirs and its offset across the lines
    (``_line_axes``); of lines with MIN_SAMPLES and FULL_LINE of the longest one's seen.
    None when there are none."""
    offsets = np.round(grid @ _line_axes(turn)[1] / STEP).astype(int)
    first = int(offsets.min())
    counts = np.bincount(offsets - first)
    sums = np.bincount(offsets - first, weights=brightness)
    full = counts >= max(MIN_SAMPLES, FULL_LINE * counts.max())  # not a corner's few
    means = np.where(full, sums / np.maximum(counts, 1), np.nan)
    side = round(SEAM_SIDE / STEP)
    if len(means) <= 2 * side:
        return None
    beside = np.fmax(means[: -2 * side], means[2 * side :])  # NaN only where both are
    contrast = means[side:-side] / beside
    if np.isnan(contrast).all():
        return None
    k = int(np.nanargmin(contrast))
    return float(contrast[k]), (k + side + first) * STEP


def _line_axes(turn: float) -> tuple[np.ndarray, np.ndarray]:
    """The direction of lines turned ``turn`` from a face's width axis, and the one
    across them, as (length, width) components."""
    return np.array([math.sin(turn), math.cos(turn)]), np.array([math.cos(turn), -math.sin(turn)])


def _brightness(points: np.ndarray, view: CameraView) -> np.ndarray:
    """The grey level of the pixel each of ``points`` (world) projects to, NaN where it
    falls outside the image or something nearer the camera hides it."""
    in_camera = (points - view.X_WC[:3, 3]) @ view.X_WC[:3, :3]
    depth = in_camera[:, 2]
    pixels = in_camera @ np.asarray(view.K).T
    with np.errstate(divide="ignore", invalid="ignore"):
        u = np.round(pixels[:, 0] / depth)
        v = np.round(pixels[:, 1] / depth)
    height, width = view.depth.shape[:2]
    inside = (depth > 0) & (u >= 0) & (u < width) & (v >= 0) & (v < height)
    result = np.full(len(points), np.nan)
    rows, columns = v[inside].astype(int), u[inside].astype(int)
    measured = np.asarray(view.depth, dtype=float).reshape(height, width)[rows, columns]
    visible = np.abs(measured - depth[inside]) < DEPTH_TOLERANCE
    grey = np.asarray(view.rgb[rows, columns, :3], dtype=float).mean(axis=1)
    result[np.flatnonzero(inside)[visible]] = grey[visible]
    return result

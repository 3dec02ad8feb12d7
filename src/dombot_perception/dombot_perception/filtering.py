"""Throw away points and boxes that cannot be one whole, well-seen domino.

Points: radius outlier removal drops points with too few neighbours (stray pixels
from another domino at a mask's border). Boxes: a fit is kept only when its
points lie on the box surface (RMS error), do not spill beyond the domino's size
(two dominoes in one mask) and cover enough of the largest visible face to pin the
pose down (a domino mostly hidden under others is left for a later cycle), and no
camera may see through it (``depth_check``: a box where a camera sees the table
behind is a fit to a fragment, not a domino). The paper filtered by box volume
instead; a one-sided surface has almost no volume, so the observed extents are the
better test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial import cKDTree

from dombot_perception.box_fit import BoxFit
from dombot_perception.domino_model import DOMINO_SIZE


@dataclass(frozen=True)
class FilterConfig:
    outlier_radius: float = 0.003  # m
    outlier_min_neighbours: int = 6
    max_fit_error: float = 0.0015  # m RMS
    size_tolerance: float = 0.005  # m: observed extents beyond the domino's by more: reject
    min_coverage: float = 0.85  # of the domino's length that must be seen
    min_width_coverage: float = 0.75  # of its width (less of it can hide next to the table)
    min_thickness_coverage: float = 0.2  # of its thickness (> 0: a side face must be seen)
    max_see_through: float = 0.05  # of a box's pixels the cameras may see past (depth_check)
    min_points: int = 40
    min_inlier_fraction: float = 0.75  # of the cloud on the fitted box's surface
    table_tolerance: float = 0.002  # m: a box reaching deeper into the table is wrong


def remove_outliers(points: np.ndarray, config: FilterConfig) -> np.ndarray:
    """Indices of the points with at least ``outlier_min_neighbours`` other points within
    the radius: open3d's ``remove_radius_outlier``, counted from scipy's k-d tree pairs in
    half its time."""
    pairs = cKDTree(points).query_pairs(config.outlier_radius, output_type="ndarray")
    neighbours = np.bincount(pairs.ravel(), minlength=points.shape[0])
    return np.flatnonzero(neighbours >= config.outlier_min_neighbours)


def rejection_reason(fit: BoxFit, num_points: int, config: FilterConfig) -> str | None:
    """Why this box is not a trustworthy domino, or None to keep it."""
    if num_points < config.min_points:
        return f"only {num_points} points"
    if fit.fit_error > config.max_fit_error:
        return f"fit error {fit.fit_error * 1000:.1f} mm"
    if np.any(fit.extents > DOMINO_SIZE + config.size_tolerance):
        return f"extents {np.round(fit.extents * 1000, 1)} mm exceed one domino"
    if fit.inlier_fraction < config.min_inlier_fraction:
        return f"only {fit.inlier_fraction:.0%} of the points on the box"
    coverage = np.minimum(fit.extents / DOMINO_SIZE, 1.0)
    if (
        coverage[0] < config.min_coverage
        or coverage[1] < config.min_width_coverage
        or coverage[2] < config.min_thickness_coverage
    ):
        return (
            f"only {coverage[0]:.0%} of its length, {coverage[1]:.0%} of its width and "
            f"{coverage[2]:.0%} of its thickness seen"
        )
    lowest = fit.X_WD[2, 3] - np.abs(fit.X_WD[2, :3]) @ (DOMINO_SIZE / 2.0)
    if lowest < -config.table_tolerance:
        return f"box reaches {-lowest * 1000:.1f} mm into the table"
    return None

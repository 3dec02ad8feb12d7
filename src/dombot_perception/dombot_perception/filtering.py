"""Throw away points and boxes that cannot be one whole, well-seen domino.

Points: open3d's radius outlier removal drops points with too few neighbours (stray
pixels from another domino at a mask's border). Boxes: a fit is kept only when its
points lie on the box surface (RMS error), do not spill beyond the domino's size
(two dominoes in one mask) and cover enough of the largest visible face to pin the
pose down (a domino mostly hidden under others is left for a later cycle), and no
camera may see through it (free-space check: a box where a camera sees the table
behind is a fit to a fragment, not a domino). The
paper filtered by box volume instead; a one-sided surface has almost no volume, so
the observed extents are the better test.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
import open3d as o3d

from dombot_perception.box_fit import BoxFit
from dombot_perception.domino_model import DOMINO_SIZE
from dombot_perception.frames import CameraView


@dataclass(frozen=True)
class FilterConfig:
    outlier_radius: float = 0.003  # m
    outlier_min_neighbours: int = 6
    max_fit_error: float = 0.0015  # m RMS
    size_tolerance: float = 0.005  # m: observed extents beyond the domino's by more: reject
    min_coverage: float = 0.85  # of the domino's length that must be seen
    min_width_coverage: float = 0.75  # of its width (less of it can hide next to the table)
    min_thickness_coverage: float = 0.2  # of its thickness (> 0: a side face must be seen)
    free_space_margin: float = 0.005  # m: a camera seeing this far behind a box face
    max_see_through: float = 0.2  # fraction of a box's visible surface a camera may see behind
    min_points: int = 40
    min_inlier_fraction: float = 0.75  # of the cloud on the fitted box's surface
    table_tolerance: float = 0.002  # m: a box reaching deeper into the table is wrong


def remove_outliers(points: np.ndarray, config: FilterConfig) -> np.ndarray:
    """Indices of the points that have enough neighbours within the radius (open3d)."""
    if points.shape[0] == 0:
        return np.zeros(0, dtype=int)
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    _, kept = cloud.remove_radius_outlier(config.outlier_min_neighbours, config.outlier_radius)
    return np.asarray(kept, dtype=int)


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


def see_through_fraction(pose: np.ndarray, views: list[CameraView], margin: float) -> float:
    """Fraction of the box's camera-facing surface behind which some camera sees further.

    A real domino blocks the view: where a camera's depth lies more than ``margin``
    beyond the fitted box's surface, the box is not really there (free-space check).
    """
    violations, checked = 0, 0
    for view in views:
        camera = view.X_WC[:3, 3]
        world_points = FACE_SAMPLES @ pose[:3, :3].T + pose[:3, 3]
        world_normals = FACE_NORMALS @ pose[:3, :3].T
        rays = camera - world_points
        facing = np.einsum("nk,nk->n", world_normals, rays) / np.linalg.norm(rays, axis=1)
        visible = facing > MIN_VIEW_COSINE  # grazing faces land on the wrong pixels
        local = (world_points[visible] - camera) @ view.X_WC[:3, :3]
        in_front = local[:, 2] > 0
        local = local[in_front]
        cols = np.round(local[:, 0] / local[:, 2] * view.K[0, 0] + view.K[0, 2]).astype(int)
        rows = np.round(local[:, 1] / local[:, 2] * view.K[1, 1] + view.K[1, 2]).astype(int)
        height, width = view.depth.shape
        inside = (cols >= 0) & (cols < width) & (rows >= 0) & (rows < height)
        observed = view.depth[rows[inside], cols[inside]]
        known = np.isfinite(observed)
        violations += int(np.count_nonzero(observed[known] > local[inside, 2][known] + margin))
        checked += int(np.count_nonzero(known))
    return violations / checked if checked else 0.0


def _face_samples(spacing: float = 0.004) -> tuple[np.ndarray, np.ndarray]:
    """Points on the domino's six faces (body frame) and each point's outward normal."""
    half = DOMINO_SIZE / 2.0
    points, normals = [], []
    for axis in range(3):
        others = [a for a in range(3) if a != axis]
        grids = [np.arange(-half[a] + spacing / 2, half[a], spacing) for a in others]
        u, v = (g.ravel() for g in np.meshgrid(*grids, indexing="ij"))
        for sign in (-1.0, 1.0):
            face = np.zeros((u.size, 3))
            face[:, others[0]], face[:, others[1]], face[:, axis] = u, v, sign * half[axis]
            normal = np.zeros((u.size, 3))
            normal[:, axis] = sign
            points.append(face)
            normals.append(normal)
    return np.concatenate(points), np.concatenate(normals)


FACE_SAMPLES, FACE_NORMALS = _face_samples()
MIN_VIEW_COSINE = 0.3  # faces seen more obliquely than ~73 degrees are not checked

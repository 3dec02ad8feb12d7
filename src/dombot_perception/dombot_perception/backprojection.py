"""Pinhole back-projection of depth pixels to world points (the paper's eqs (1)-(3)).

X = z (u - cx) / fx,  Y = z (v - cy) / fy,  Z = z   in the optical frame, then camera_pose.
Vectorized over the whole image; surface normals come from the same organised cloud,
cropped to the window that sees the work region so later stages touch few pixels.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dombot_perception.domino_model import dot3, norm3
from dombot_perception.frames import CameraView


@dataclass(frozen=True)
class WorkRegion:
    """Where dominoes can be: a vertical cylinder above the table (world frame)."""

    center: tuple[float, float] = (0.55, -0.30)
    radius: float = 0.16  # m
    min_height: float = 0.0015  # m above the table: below this is the table itself
    max_height: float = 0.07  # m: above this is the arm, not the pile

    def outline(self, sides: int = 32) -> np.ndarray:
        """Corners (2*sides x 3, world) of a prism around the cylinder: it holds the region."""
        angles = np.linspace(0.0, 2.0 * np.pi, sides, endpoint=False)
        radius = self.radius / np.cos(np.pi / sides)
        ring = np.column_stack(
            [self.center[0] + radius * np.cos(angles), self.center[1] + radius * np.sin(angles)]
        )
        return np.vstack(
            [np.column_stack([ring, np.full(sides, z)]) for z in (self.min_height, self.max_height)]
        )

    def contains(self, points: np.ndarray) -> np.ndarray:
        with np.errstate(invalid="ignore"):
            radial = np.hypot(points[..., 0] - self.center[0], points[..., 1] - self.center[1])
            return (
                (radial < self.radius)
                & (points[..., 2] > self.min_height)
                & (points[..., 2] < self.max_height)
            )


def valid_depth(depth: np.ndarray, depth_range: tuple[float, float]) -> np.ndarray:
    """Pixels with a real return inside the sensor's range (NaN, inf, 0 are no return)."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(depth) & (depth > depth_range[0]) & (depth < depth_range[1])


def backproject(
    depth: np.ndarray, intrinsics: np.ndarray, camera_pose: np.ndarray, top: int = 0, left: int = 0
) -> np.ndarray:
    """HxWx3 world points for every pixel of ``depth`` (NaN where the depth is NaN);
    ``depth`` may be a window of the image whose first pixel is (``top``, ``left``)."""
    height, width = depth.shape
    v, u = np.mgrid[top : top + height, left : left + width]
    z = depth.astype(np.float64)
    z[~np.isfinite(z)] = np.nan  # inf would turn into NaN with a warning below
    x = z * (u - intrinsics[0, 2]) / intrinsics[0, 0]
    y = z * (v - intrinsics[1, 2]) / intrinsics[1, 1]
    points_c = np.stack([x, y, z], axis=-1)
    return points_c @ camera_pose[:3, :3].T + camera_pose[:3, 3]


def image_normals(points: np.ndarray, camera_position: np.ndarray) -> np.ndarray:
    """HxWx3 unit normals from central differences, turned towards the camera.

    NaN where a neighbour is missing; callers treat such pixels as boundaries.
    """
    du = np.full_like(points, np.nan)
    dv = np.full_like(points, np.nan)
    du[:, 1:-1] = points[:, 2:] - points[:, :-2]
    dv[1:-1, :] = points[2:, :] - points[:-2, :]
    normals = np.cross(du, dv)
    with np.errstate(invalid="ignore", divide="ignore"):
        normals /= norm3(normals)[..., None]
        facing = dot3(normals, camera_position - points)
    normals[facing < 0] *= -1.0
    return normals


@dataclass
class OrganisedCloud:
    """World points and normals of one view, cropped to the pixels that see the work region.

    ``valid`` marks crop pixels with a return inside the region and a usable normal.
    Masks everywhere are flat indices into the *full* image; ``full_index`` and
    ``crop_index`` convert.
    """

    top: int
    left: int
    image_width: int
    points: np.ndarray  # hxwx3, world
    normals: np.ndarray  # hxwx3, unit, towards the camera
    valid: np.ndarray  # hxw
    pixel_size: np.ndarray  # hxw: metres one pixel spans at that depth (0 where invalid)

    def full_index(self, crop_flat: np.ndarray) -> np.ndarray:
        rows, cols = np.divmod(crop_flat, self.valid.shape[1])
        return (rows + self.top) * self.image_width + cols + self.left

    def crop_index(self, full_flat: np.ndarray) -> np.ndarray:
        rows, cols = np.divmod(full_flat, self.image_width)
        return (rows - self.top) * self.valid.shape[1] + cols - self.left

    def valid_points(self) -> np.ndarray:
        return self.points[self.valid]


def organised_cloud(
    view: CameraView, region: WorkRegion, depth_range: tuple[float, float]
) -> OrganisedCloud | None:
    """Back-project ``view``, keep the bounding window of pixels ``inside`` the work region.

    Only the pixels within the region's projected outline are back-projected (the pile
    covers a fraction of the image). None when no pixel sees the region.
    """
    height, width = view.depth.shape
    first, last = _height_window(view, region, depth_range, *_projected_window(region, view))
    depth = view.depth[first[0] : last[0], first[1] : last[1]]
    points = backproject(depth, view.K, view.X_WC, first[0], first[1])
    seen = valid_depth(depth, depth_range) & region.contains(points)
    rows, cols = np.nonzero(seen)
    if rows.size == 0:
        return None
    rows, cols = rows + first[0], cols + first[1]
    top, bottom = max(rows.min() - 1, 0), min(rows.max() + 2, height)
    left, right = max(cols.min() - 1, 0), min(cols.max() + 2, width)
    window = np.s_[top - first[0] : bottom - first[0], left - first[1] : right - first[1]]
    points = points[window]
    normals = image_normals(points, view.X_WC[:3, 3])
    valid = seen[window] & np.isfinite(normals[..., 0])
    pixel_size = np.where(valid, view.depth[top:bottom, left:right], 0.0) / view.K[0, 0]
    return OrganisedCloud(int(top), int(left), width, points, normals, valid, pixel_size)


def _height_window(
    view: CameraView,
    region: WorkRegion,
    depth_range: tuple[float, float],
    first: tuple[int, int],
    last: tuple[int, int],
) -> tuple[tuple[int, int], ...]:
    """The part of the window ``first``-``last`` around the pixels whose height above the
    table lies within the region's (1 mm of slack), with a pixel of margin: the table
    around the pile is most of the region's outline, and only the height (one row of the
    camera's rotation) is needed to leave it out before the full back-projection."""
    depth = view.depth[first[0] : last[0], first[1] : last[1]]
    rows, cols = np.mgrid[first[0] : last[0], first[1] : last[1]]
    intrinsics, rotation = view.K, view.X_WC[:3, :3]
    with np.errstate(invalid="ignore"):
        height = view.X_WC[2, 3] + depth * (
            rotation[2, 0] * (cols - intrinsics[0, 2]) / intrinsics[0, 0]
            + rotation[2, 1] * (rows - intrinsics[1, 2]) / intrinsics[1, 1]
            + rotation[2, 2]
        )
        near = (
            valid_depth(depth, depth_range)
            & (height > region.min_height - 0.001)
            & (height < region.max_height + 0.001)
        )
    inside_rows, inside_cols = np.nonzero(near)
    if inside_rows.size == 0:
        return first, first  # nothing there: an empty window
    top = max(first[0] + int(inside_rows.min()) - 1, first[0])
    left = max(first[1] + int(inside_cols.min()) - 1, first[1])
    bottom = min(first[0] + int(inside_rows.max()) + 2, last[0])
    right = min(first[1] + int(inside_cols.max()) + 2, last[1])
    return (top, left), (bottom, right)


def _projected_window(region: WorkRegion, view: CameraView) -> tuple[tuple[int, int], ...]:
    """(top, left) and (bottom, right) of the pixels that can see ``region``, with a
    pixel of margin beyond (the crop keeps one around what it sees); the whole image when
    part of the region lies behind the camera."""
    height, width = view.depth.shape
    local = (region.outline() - view.X_WC[:3, 3]) @ view.X_WC[:3, :3]
    if np.any(local[:, 2] <= 0.0):
        return (0, 0), (height, width)
    pixels = local[:, :2] / local[:, 2:] * np.diag(view.K)[:2] + view.K[:2, 2]
    low, high = np.floor(pixels.min(axis=0)) - 1, np.ceil(pixels.max(axis=0)) + 2
    left, top = np.clip(low, 0, [width, height]).astype(int)
    right, bottom = np.clip(high, 0, [width, height]).astype(int)
    return (top, left), (max(bottom, top), max(right, left))

"""Pinhole back-projection of depth pixels to world points (the paper's eqs (1)-(3)).

X = z (u - cx) / fx,  Y = z (v - cy) / fy,  Z = z   in the optical frame, then camera_pose.
Vectorized over the whole image; surface normals come from the same organised cloud.
"""

from __future__ import annotations

import numpy as np


def valid_depth(depth: np.ndarray, depth_range: tuple[float, float]) -> np.ndarray:
    """Pixels with a real return inside the sensor's range (NaN, inf, 0 are no return)."""
    with np.errstate(invalid="ignore"):
        return np.isfinite(depth) & (depth > depth_range[0]) & (depth < depth_range[1])


def backproject(depth: np.ndarray, intrinsics: np.ndarray, camera_pose: np.ndarray) -> np.ndarray:
    """HxWx3 world points for every pixel (NaN where the depth is NaN)."""
    height, width = depth.shape
    v, u = np.mgrid[0:height, 0:width]
    z = depth.astype(np.float64)
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
        normals /= np.linalg.norm(normals, axis=-1, keepdims=True)
        facing = np.einsum("hwk,hwk->hw", normals, camera_position - points)
    normals[facing < 0] *= -1.0
    return normals

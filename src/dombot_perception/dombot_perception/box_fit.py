"""Fit the known domino box (48 x 24 x 7.5 mm) to one domino's fused surface points.

A minimal bounding box of a partial surface is easily turned the wrong way (the
paper's Fig. 12). Here the box's size is known, so the fit only has to decide which
of the three faces the camera sees most of and how the box is turned in that face's
plane: the dominant normal direction gives the face's normal, the minimum-area
rectangle of the points projected on that face gives the in-plane axes, and the
face whose size best matches the rectangle says which body axis the normal is. A
robust point-to-plane fit of the points to the box's faces then refines all six
degrees of freedom. The box always lies behind the visible surface, seen from the cameras.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.linalg import lapack
from scipy.spatial import ConvexHull, QhullError

from dombot_perception.domino_model import (
    DOMINO_SIZE,
    HALF_SIZE,
    argmax3,
    box_signed_distance,
    dominant_face,
)

RECTANGLE_POINTS = 500  # points whose hull gives the initial in-plane axes
# (long, short) sides of the face normal to body x, y, z
IDENTITY_3, IDENTITY_6 = np.eye(3), np.eye(6)
FACE_SIDES = np.array([np.sort(np.delete(DOMINO_SIZE, axis))[::-1] for axis in range(3)])
# directions (counter-clockwise) whose extreme points span a polygon inside the hull
_ANGLES = np.linspace(0.0, 2.0 * np.pi, 16, endpoint=False)
HULL_DIRECTIONS = np.column_stack([np.cos(_ANGLES), np.sin(_ANGLES)])


@dataclass(frozen=True)
class BoxFitConfig:
    size_tolerance: float = 0.004  # m: observed extents may exceed the domino's by this
    max_fit_points: int = 250  # points used by the least-squares refinement (subsampled)
    inlier_distance: float = 0.002  # m: points further from the box belong to something else
    passes: int = 2  # fits; each after the first uses only the previous fit's inliers
    loss_scale: float = 0.001  # m: residuals beyond this count less (Huber)
    iterations: int = 15  # Gauss-Newton steps of the refinement at most
    damping: float = 1e-3  # relative Levenberg damping: directions no point pins stay put
    seed: int = 0


@dataclass(frozen=True)
class BoxFit:
    X_WD: np.ndarray  # 4x4, body axes in the fit's own order (canonical signs come later)
    fit_error: float  # RMS point-to-box distance [m]
    extents: np.ndarray  # observed extents of the inlier points along body x, y, z [m]
    inlier_fraction: float  # of the points within ``inlier_distance`` of the box surface


class BoxFitError(ValueError):
    """Too few or degenerate points to fit a box."""


def fit_domino_box(points: np.ndarray, normals: np.ndarray, config: BoxFitConfig) -> BoxFit:
    """Pose of the domino whose visible surface is ``points`` (normals face the camera)."""
    if points.shape[0] < 10:
        raise BoxFitError(f"{points.shape[0]} points are too few for a box fit")
    rng = None  # made when first needed: most clouds need no subsampling
    inliers = np.ones(points.shape[0], dtype=bool)
    for _ in range(config.passes):  # fit, drop points off the box (a neighbour's), refit
        pose = initial_pose(points[inliers], normals[inliers], config)
        fitted = points[inliers]
        if fitted.shape[0] > config.max_fit_points:
            rng = rng or np.random.default_rng(config.seed)
            fitted = fitted[rng.choice(fitted.shape[0], config.max_fit_points, replace=False)]
        pose = refine_pose(pose, fitted, config)
        residuals = box_signed_distance((points - pose[:3, 3]) @ pose[:3, :3])
        trimmed = np.abs(residuals) < config.inlier_distance
        if trimmed.sum() < 10 or np.array_equal(trimmed, inliers):
            break
        inliers = trimmed
    return fit_statistics(pose, points, inliers)


def fit_statistics(pose: np.ndarray, points: np.ndarray, inliers: np.ndarray) -> BoxFit:
    """The fit of the box at ``pose`` to ``points``, judged on the ``inliers`` (a mask)."""
    body = (points[inliers] - pose[:3, 3]) @ pose[:3, :3]
    return BoxFit(
        X_WD=pose,
        fit_error=float(np.sqrt(np.mean(box_signed_distance(body) ** 2))),
        extents=body.max(axis=0) - body.min(axis=0),
        inlier_fraction=float(inliers.mean()),
    )


def initial_pose(points: np.ndarray, normals: np.ndarray, config: BoxFitConfig) -> np.ndarray:
    """Box pose from the dominant face and its minimum-area rectangle."""
    face = dominant_face(normals)
    normal = normals[face].mean(axis=0)
    normal /= np.linalg.norm(normal)
    u, v = _plane_basis(normal)
    stride = max(1, points.shape[0] // RECTANGLE_POINTS)  # only a starting guess: ICP refines
    planar = np.column_stack([points[::stride] @ u, points[::stride] @ v])
    center_2d, long_2d, dims_2d = min_area_rectangle(planar)
    face_axis = _which_face(dims_2d, config.size_tolerance)
    in_plane = [axis for axis in range(3) if axis != face_axis]  # longer body axis first
    rotation = np.zeros((3, 3))
    rotation[:, face_axis] = normal
    rotation[:, in_plane[0]] = long_2d[0] * u + long_2d[1] * v
    rotation[:, in_plane[1]] = _cross3(
        rotation[:, (in_plane[1] + 1) % 3], rotation[:, (in_plane[1] + 2) % 3]
    )
    face_offset = np.median(points[face] @ normal)
    center = center_2d[0] * u + center_2d[1] * v + (face_offset - HALF_SIZE[face_axis]) * normal
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = center
    return pose


def min_area_rectangle(planar: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre, unit long-side direction and (long, short) sides of the smallest rectangle."""
    planar = hull_candidates(planar)
    try:
        hull = planar[ConvexHull(planar).vertices]
    except (QhullError, ValueError) as error:
        raise BoxFitError(f"points are degenerate in the face plane: {error}") from None
    edges = np.empty_like(hull)
    edges[:-1] = hull[1:] - hull[:-1]
    edges[-1] = hull[0] - hull[-1]
    angles = np.unique(np.mod(np.arctan2(edges[:, 1], edges[:, 0]), np.pi / 2))
    cos, sin = np.cos(angles), np.sin(angles)
    # hull points along each candidate rectangle's sides (rows: angles, columns: points)
    x, y = hull[:, 0], hull[:, 1]
    px = cos[:, None] * x + sin[:, None] * y
    py = cos[:, None] * y - sin[:, None] * x
    low_x, high_x, low_y, high_y = px.min(axis=1), px.max(axis=1), py.min(axis=1), py.max(axis=1)
    width, height = high_x - low_x, high_y - low_y
    best = np.argmin(width * height)
    axis_x, axis_y = np.array([cos[best], sin[best]]), np.array([-sin[best], cos[best]])
    center = (high_x[best] + low_x[best]) / 2 * axis_x + (high_y[best] + low_y[best]) / 2 * axis_y
    if width[best] >= height[best]:
        return center, axis_x, np.array([width[best], height[best]])
    return center, axis_y, np.array([height[best], width[best]])


def hull_candidates(planar: np.ndarray) -> np.ndarray:
    """The points not strictly inside the polygon of the extreme points along
    ``HULL_DIRECTIONS``: the same convex hull, and Qhull's time grows with its input
    (500 points: four times the time of the ~40 left)."""
    extreme = np.argmax(planar @ HULL_DIRECTIONS.T, axis=0)
    extreme = extreme[extreme != np.concatenate([extreme[-1:], extreme[:-1]])]  # no repeats
    if extreme.size < 3:
        return planar
    corners = planar[extreme]  # counter-clockwise
    edges = np.concatenate([corners[1:], corners[:1]]) - corners
    offsets = planar[:, None, :] - corners[None]
    cross = edges[:, 0] * offsets[..., 1] - edges[:, 1] * offsets[..., 0]
    return planar[~np.all(cross > 1e-12, axis=1)]


def _which_face(dims_2d: np.ndarray, tolerance: float) -> int:
    """Body axis normal to the face whose (long, short) sides best explain ``dims_2d``.

    Sides longer than the face's cost a lot (they cannot be); shorter ones cost a
    little (that part of the face is hidden).
    """
    excess = np.maximum(dims_2d - FACE_SIDES - tolerance, 0.0)
    shortfall = np.maximum(FACE_SIDES - dims_2d, 0.0)
    return int(np.argmin(100.0 * (excess**2).sum(axis=1) + (shortfall**2).sum(axis=1)))


def _plane_basis(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    helper = np.array([1.0, 0.0, 0.0]) if abs(normal[0]) < 0.9 else np.array([0.0, 1.0, 0.0])
    u = _cross3(normal, helper)
    u /= np.linalg.norm(u)
    return u, _cross3(normal, u)


def refine_pose(
    initial: np.ndarray,
    points: np.ndarray,
    config: BoxFitConfig,
    outside: np.ndarray | None = None,
    outside_axis: np.ndarray | None = None,
) -> np.ndarray:
    """Point-to-plane ICP against the box model, 6 DoF, started at ``initial``.

    Each point is paired with the box face it is closest to; one damped, Huber-weighted
    Gauss-Newton step on the point-to-face distances updates the pose. Written out
    (a few lines of numpy) because a general solver costs tens of milliseconds per box.

    ``outside`` are points the box must not contain (where a camera saw past it,
    ``depth_check.DepthEvidence.outside``): while one is inside, the nearest face other
    than the one its ray entered through (``outside_axis``) is pulled onto it, which
    moves the box off the ray without lifting the face the camera saw.
    """
    rotation, centre = initial[:3, :3].copy(), initial[:3, 3].copy()
    for _ in range(config.iterations):
        body = (points - centre) @ rotation
        axis = argmax3(np.abs(body) - HALF_SIZE)
        if outside is not None and outside_axis is not None and outside.shape[0]:
            body, axis = _with_outside(body, axis, (outside - centre) @ rotation, outside_axis)
        signed = body[np.arange(body.shape[0]), axis]
        residual = np.abs(signed) - HALF_SIZE[axis]
        # the face normal is sign * e_axis: the Jacobian row (e_axis x body, -e_axis) times
        # the sign, which squares to 1 in the Hessian and goes into the gradient
        face = IDENTITY_3[axis]
        jacobian = np.empty((body.shape[0], 6))
        _cross_into(face, body, jacobian)
        np.negative(face, out=jacobian[:, 3:])
        weight = np.minimum(1.0, config.loss_scale / np.maximum(np.abs(residual), 1e-12))
        hessian = jacobian.T @ (weight[:, None] * jacobian)
        hessian += config.damping * hessian.trace() / 6.0 * IDENTITY_6
        step = _solve(hessian, -jacobian.T @ (weight * np.sign(signed) * residual))
        centre = centre + rotation @ step[3:]
        rotation = rotation @ _rodrigues(step[:3])
        if _norm(step[3:]) < 1e-5 and _norm(step[:3]) < 1e-4:
            break
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = centre
    return pose


def _with_outside(
    body: np.ndarray, axis: np.ndarray, outside_body: np.ndarray, entry_axis: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """The surface points and their faces, plus each outside point that is inside the box
    paired with its nearest face other than the one its ray entered through."""
    inside = np.all(np.abs(outside_body) < HALF_SIZE, axis=1)
    depth = HALF_SIZE - np.abs(outside_body[inside])
    depth[np.arange(depth.shape[0]), entry_axis[inside]] = np.inf
    return np.vstack([body, outside_body[inside]]), np.concatenate([axis, depth.argmin(axis=1)])


def _cross3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Cross product of two 3-vectors (np.cross costs ten times as much for one pair)."""
    return np.array(
        [a[1] * b[2] - a[2] * b[1], a[2] * b[0] - a[0] * b[2], a[0] * b[1] - a[1] * b[0]]
    )


def _cross_into(a: np.ndarray, b: np.ndarray, out: np.ndarray) -> None:
    """Row-wise a x b into the first three columns of ``out``, column by column (np.cross,
    or fancy-indexed columns, cost more than the rest of an ICP step here)."""
    a0, a1, a2, b0, b1, b2 = a[:, 0], a[:, 1], a[:, 2], b[:, 0], b[:, 1], b[:, 2]
    np.subtract(a1 * b2, a2 * b1, out=out[:, 0])
    np.subtract(a2 * b0, a0 * b2, out=out[:, 1])
    np.subtract(a0 * b1, a1 * b0, out=out[:, 2])


def _rodrigues(rotation_vector: np.ndarray) -> np.ndarray:
    """Rotation matrix of a rotation vector (Rodrigues' formula, written out: numpy's calls
    on a 3-vector cost more than the arithmetic)."""
    x, y, z = rotation_vector.tolist()
    angle = math.sqrt(x * x + y * y + z * z)
    if angle < 1e-12:
        return IDENTITY_3
    x, y, z = x / angle, y / angle, z / angle
    s, c = math.sin(angle), 1.0 - math.cos(angle)
    return np.array(
        [
            [1.0 - c * (y * y + z * z), c * x * y - s * z, c * x * z + s * y],
            [c * x * y + s * z, 1.0 - c * (x * x + z * z), c * y * z - s * x],
            [c * x * z - s * y, c * y * z + s * x, 1.0 - c * (x * x + y * y)],
        ]
    )


def _solve(matrix: np.ndarray, vector: np.ndarray) -> np.ndarray:
    """``np.linalg.solve`` for one small system: LAPACK's gesv, as numpy calls it, without
    numpy's per-call checks (a third of an ICP step)."""
    _, _, solution, info = lapack.dgesv(matrix, vector)
    if info != 0:
        raise np.linalg.LinAlgError("singular matrix")
    return solution


def _norm(vector: np.ndarray) -> float:
    """Length of one short vector (what np.linalg.norm computes, without its checks)."""
    return math.sqrt(float(vector @ vector))

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
from scipy.spatial import ConvexHull, QhullError

from dombot_perception.domino_model import (
    DOMINO_SIZE,
    HALF_SIZE,
    argmax3,
    box_signed_distance,
    dominant_face,
    norm3,
)

RECTANGLE_POINTS = 500  # points whose hull gives the initial in-plane axes
# (long, short) sides of the face normal to body x, y, z
IDENTITY_3, IDENTITY_6 = np.eye(3), np.eye(6)
FACE_SIDES = np.array([np.sort(np.delete(DOMINO_SIZE, axis))[::-1] for axis in range(3)])


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
    fit = fit_domino_boxes([(points, normals)], config)[0]
    if isinstance(fit, BoxFitError):
        raise fit
    return fit


def fit_domino_boxes(
    clouds: list[tuple[np.ndarray, np.ndarray]], config: BoxFitConfig
) -> list[BoxFit | BoxFitError]:
    """``fit_domino_box`` of each (points, normals) cloud, or the error that it raises.

    The refinements of all clouds run as one batch (``refine_poses``): a cold detect fits
    a few hundred boxes, and one at a time most of their cost is numpy's per-call overhead.
    """
    fits: list[BoxFit | BoxFitError | None] = [None] * len(clouds)
    inliers = [np.ones(points.shape[0], dtype=bool) for points, _ in clouds]
    rngs: list[np.random.Generator | None] = [None] * len(clouds)  # most clouds need none
    poses: list[np.ndarray | None] = [None] * len(clouds)
    frames: list[tuple[np.ndarray, np.ndarray] | None] = [None] * len(clouds)  # at the pose
    todo = []
    for index, (points, _) in enumerate(clouds):
        if points.shape[0] < 10:
            fits[index] = BoxFitError(f"{points.shape[0]} points are too few for a box fit")
        else:
            todo.append(index)
    for _ in range(config.passes):  # fit, drop points off the box (a neighbour's), refit
        started, starts, fitted = [], [], []
        subsets = [
            (clouds[index][0][inliers[index]], clouds[index][1][inliers[index]]) for index in todo
        ]
        for index, (subset, _), start in zip(
            todo, subsets, initial_poses(subsets, config), strict=True
        ):
            if isinstance(start, BoxFitError):
                fits[index] = start
                continue
            if subset.shape[0] > config.max_fit_points:
                rngs[index] = rngs[index] or np.random.default_rng(config.seed)
                chosen = rngs[index].choice(subset.shape[0], config.max_fit_points, replace=False)
                subset = subset[chosen]
            started.append(index)
            starts.append(start)
            fitted.append(subset)
        todo = []
        refined = refine_poses(starts, fitted, config)
        seen = _in_box_frames([clouds[index][0] for index in started], refined)
        for index, pose, (body, residuals) in zip(started, refined, seen, strict=True):
            poses[index], frames[index] = pose, (body, residuals)
            trimmed = np.abs(residuals) < config.inlier_distance
            if trimmed.sum() >= 10 and not np.array_equal(trimmed, inliers[index]):
                inliers[index] = trimmed
                todo.append(index)
    for index, pose in enumerate(poses):
        if fits[index] is None:
            fits[index] = _statistics(pose, *frames[index], inliers[index])
    return fits


def fit_statistics(pose: np.ndarray, points: np.ndarray, inliers: np.ndarray) -> BoxFit:
    """The fit of the box at ``pose`` to ``points``, judged on the ``inliers`` (a mask)."""
    return _statistics(pose, *_in_box_frames([points], [pose])[0], inliers)


def _statistics(
    pose: np.ndarray, body: np.ndarray, residuals: np.ndarray, inliers: np.ndarray
) -> BoxFit:
    """``fit_statistics`` from the points in the box frame and their signed distances;
    with no inlier, a fit no check accepts (infinite error, nothing seen: a box slid off
    its points once raised here and failed a whole placement check)."""
    body = body[inliers]
    if not len(body):
        return BoxFit(X_WD=pose, fit_error=math.inf, extents=np.zeros(3), inlier_fraction=0.0)
    return BoxFit(
        X_WD=pose,
        fit_error=float(np.sqrt(np.mean(residuals[inliers] ** 2))),
        extents=body.max(axis=0) - body.min(axis=0),
        inlier_fraction=float(inliers.mean()),
    )


def _in_box_frames(
    clouds: list[np.ndarray], poses: list[np.ndarray]
) -> list[tuple[np.ndarray, np.ndarray]]:
    """Each cloud in its box's frame and its points' signed distances to the box, all
    clouds at once."""
    if not clouds:
        return []
    pose = np.array(poses)
    body = (_padded(clouds) - pose[:, None, :3, 3]) @ pose[:, :3, :3]
    residuals = box_signed_distance(body)
    return [
        (body[box, : cloud.shape[0]], residuals[box, : cloud.shape[0]])
        for box, cloud in enumerate(clouds)
    ]


def initial_pose(points: np.ndarray, normals: np.ndarray, config: BoxFitConfig) -> np.ndarray:
    """Box pose from the dominant face and its minimum-area rectangle."""
    pose = initial_poses([(points, normals)], config)[0]
    if isinstance(pose, BoxFitError):
        raise pose
    return pose


def initial_poses(
    clouds: list[tuple[np.ndarray, np.ndarray]], config: BoxFitConfig
) -> list[np.ndarray | BoxFitError]:
    """``initial_pose`` of each (points, normals) cloud, or the error that it raises.

    Every step but the convex hull (one Qhull call per cloud) runs on all clouds at once,
    padded to one size: one cloud at a time, numpy's per-call overhead was most of it.
    """
    if not clouds:
        return []
    faces = [dominant_face(normals) for _, normals in clouds]
    normal = np.array(
        [normals[face].mean(axis=0) for (_, normals), face in zip(clouds, faces, strict=True)]
    )
    normal /= _norms(normal)[:, None]
    u, v = _plane_bases(normal)
    # only a starting guess: ICP refines
    strided = [points[:: max(1, points.shape[0] // RECTANGLE_POINTS)] for points, _ in clouds]
    padded = _padded(strided)
    planar = np.concatenate([padded @ u[:, :, None], padded @ v[:, :, None]], axis=2)
    rectangles = min_area_rectangles(
        [planar[box, : cloud.shape[0]] for box, cloud in enumerate(strided)]
    )
    poses: list[np.ndarray | BoxFitError] = list(rectangles)
    found = [
        box for box, rectangle in enumerate(rectangles) if not isinstance(rectangle, BoxFitError)
    ]
    if not found:
        return poses
    center_2d, long_2d, dims_2d = (
        np.array([rectangles[box][k] for box in found]) for k in range(3)
    )
    normal, u, v = normal[found], u[found], v[found]
    face_axis = _which_faces(dims_2d, config.size_tolerance)
    first, second = (face_axis + 1) % 3, (face_axis + 2) % 3  # the in-plane body axes
    longer = np.minimum(first, second)  # the longer body axis of the two
    shorter = np.maximum(first, second)
    rows = np.arange(len(found))
    rotation = np.zeros((len(found), 3, 3))
    rotation[rows, :, face_axis] = normal
    rotation[rows, :, longer] = long_2d[:, :1] * u + long_2d[:, 1:] * v
    rotation[rows, :, shorter] = _cross_rows(
        rotation[rows, :, (shorter + 1) % 3], rotation[rows, :, (shorter + 2) % 3]
    )
    face_offset = _medians([clouds[box][0][faces[box]] for box in found], normal)
    center = (
        center_2d[:, :1] * u
        + center_2d[:, 1:] * v
        + (face_offset - HALF_SIZE[face_axis])[:, None] * normal
    )
    for row, box in enumerate(found):
        pose = np.eye(4)
        pose[:3, :3] = rotation[row]
        pose[:3, 3] = center[row]
        poses[box] = pose
    return poses


def min_area_rectangle(planar: np.ndarray) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
    """Centre, unit long-side direction and (long, short) sides of the smallest rectangle."""
    rectangle = min_area_rectangles([planar])[0]
    if isinstance(rectangle, BoxFitError):
        raise rectangle
    return rectangle


def min_area_rectangles(
    planars: list[np.ndarray],
) -> list[tuple[np.ndarray, np.ndarray, np.ndarray] | BoxFitError]:
    """``min_area_rectangle`` of each 2-D point set, or the error that it raises; rotating
    edges over each convex hull (Qhull, one call per set), all sets at once."""
    result: list = [None] * len(planars)
    hulls = []
    for index, planar in enumerate(planars):
        try:
            hulls.append(planar[ConvexHull(planar).vertices])
        except (QhullError, ValueError) as error:
            result[index] = BoxFitError(f"points are degenerate in the face plane: {error}")
    found = [index for index, rectangle in enumerate(result) if rectangle is None]
    if not found:
        return result
    hull = _padded(hulls)  # padded with each hull's first vertex: no new extremes
    sizes = np.array([h.shape[0] for h in hulls])
    edges = np.roll(hull, -1, axis=1) - hull
    angles = np.mod(np.arctan2(edges[..., 1], edges[..., 0]), np.pi / 2)
    padding = np.arange(hull.shape[1]) >= sizes[:, None]
    angles = np.sort(np.where(padding, angles[:, :1], angles), axis=1)  # repeats change no minimum
    cos, sin = np.cos(angles), np.sin(angles)
    # hull points along each candidate rectangle's sides (sets x angles x points)
    x, y = hull[:, None, :, 0], hull[:, None, :, 1]
    px = cos[..., None] * x + sin[..., None] * y
    py = cos[..., None] * y - sin[..., None] * x
    low_x, high_x, low_y, high_y = px.min(axis=2), px.max(axis=2), py.min(axis=2), py.max(axis=2)
    width, height = high_x - low_x, high_y - low_y
    rows, best = np.arange(len(hulls)), np.argmin(width * height, axis=1)
    cos, sin, width, height = (
        cos[rows, best],
        sin[rows, best],
        width[rows, best],
        height[rows, best],
    )
    axis_x, axis_y = np.stack([cos, sin], axis=1), np.stack([-sin, cos], axis=1)
    middle_x = (high_x[rows, best] + low_x[rows, best])[:, None] / 2
    middle_y = (high_y[rows, best] + low_y[rows, best])[:, None] / 2
    center = middle_x * axis_x + middle_y * axis_y
    for row, index in enumerate(found):
        if width[row] >= height[row]:
            result[index] = (center[row], axis_x[row], np.array([width[row], height[row]]))
        else:
            result[index] = (center[row], axis_y[row], np.array([height[row], width[row]]))
    return result


def _which_faces(dims_2d: np.ndarray, tolerance: float) -> np.ndarray:
    """Body axis normal to the face whose (long, short) sides best explain each row of
    ``dims_2d``.

    Sides longer than the face's cost a lot (they cannot be); shorter ones cost a
    little (that part of the face is hidden).
    """
    excess = np.maximum(dims_2d[:, None, :] - FACE_SIDES - tolerance, 0.0)
    shortfall = np.maximum(FACE_SIDES - dims_2d[:, None, :], 0.0)
    return np.argmin(100.0 * (excess**2).sum(axis=2) + (shortfall**2).sum(axis=2), axis=1)


def _plane_bases(normal: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Two unit vectors spanning the plane normal to each row of ``normal``."""
    helper = np.where(
        np.abs(normal[:, :1]) < 0.9, np.array([1.0, 0.0, 0.0]), np.array([0.0, 1.0, 0.0])
    )
    u = _cross_rows(normal, helper)
    u /= _norms(u)[:, None]
    return u, _cross_rows(normal, u)


def _norms(vectors: np.ndarray) -> np.ndarray:
    """``np.linalg.norm`` of each row, to the last bit (a stacked product is BLAS's dot, as
    for one vector; the ICP's pairing of points to faces magnifies a last bit's change)."""
    return np.sqrt((vectors[:, None, :] @ vectors[:, :, None])[:, 0, 0])


def _padded(arrays: list[np.ndarray]) -> np.ndarray:
    """The (non-empty) arrays stacked, each padded to the longest with its first row."""
    stacked = np.empty((len(arrays), max(a.shape[0] for a in arrays), *arrays[0].shape[1:]))
    for index, array in enumerate(arrays):
        stacked[index, : array.shape[0]] = array
        stacked[index, array.shape[0] :] = array[0]
    return stacked


def _medians(points: list[np.ndarray], directions: np.ndarray) -> np.ndarray:
    """``np.median(points[k] @ directions[k])`` of each set k, all at once."""
    counts = np.array([p.shape[0] for p in points])
    heights = np.full((len(points), counts.max()), np.inf)  # sorted last
    for index, (cloud, direction) in enumerate(zip(points, directions, strict=True)):
        heights[index, : cloud.shape[0]] = cloud @ direction
    heights.sort(axis=1)
    rows = np.arange(len(points))
    return (heights[rows, (counts - 1) // 2] + heights[rows, counts // 2]) / 2


def refine_pose(
    initial: np.ndarray,
    points: np.ndarray,
    config: BoxFitConfig,
    outside: np.ndarray | None = None,
    outside_axis: np.ndarray | None = None,
) -> np.ndarray:
    """Point-to-plane ICP against the box model, 6 DoF, started at ``initial``.

    ``outside`` are points the box must not contain (where a camera saw past it,
    ``depth_check.DepthEvidence.outside``): while one is inside, the nearest face other
    than the one its ray entered through (``outside_axis``) is pulled onto it, which
    moves the box off the ray without lifting the face the camera saw.
    """
    if outside is None or outside_axis is None:
        return refine_poses([initial], [points], config)[0]
    return refine_poses([initial], [points], config, [outside], [outside_axis])[0]


def refine_poses(
    initials: list[np.ndarray],
    points: list[np.ndarray],
    config: BoxFitConfig,
    outside: list[np.ndarray] | None = None,
    outside_axis: list[np.ndarray] | None = None,
) -> list[np.ndarray]:
    """``refine_pose`` of each box, all boxes' ICP steps at once (clouds padded to one size).

    Each point is paired with the box face it is closest to; one damped, Huber-weighted
    Gauss-Newton step on the point-to-face distances updates each pose, until its step is
    small. Written out because a general solver costs tens of milliseconds per box.
    """
    count = len(initials)
    if count == 0:
        return []
    outside = outside or [np.zeros((0, 3))] * count
    outside_axis = outside_axis or [np.zeros(0, dtype=np.intp)] * count
    size = max(p.shape[0] + o.shape[0] for p, o in zip(points, outside, strict=True))
    padded = np.zeros((count, size, 3))
    surface = np.zeros((count, size), dtype=bool)  # a visible point (else padding or outside)
    beyond = np.zeros((count, size), dtype=bool)  # a point the box must not contain
    entry = np.zeros((count, size), dtype=np.intp)  # the face an outside point's ray entered
    for box, (cloud, seen, axes) in enumerate(zip(points, outside, outside_axis, strict=True)):
        end = cloud.shape[0] + seen.shape[0]
        padded[box, : cloud.shape[0]] = cloud
        padded[box, cloud.shape[0] : end] = seen
        surface[box, : cloud.shape[0]] = True
        beyond[box, cloud.shape[0] : end] = True
        entry[box, cloud.shape[0] : end] = axes
    any_beyond = bool(beyond.any())
    rotation = np.array([pose[:3, :3] for pose in initials])
    centre = np.array([pose[:3, 3] for pose in initials])
    active = np.arange(count)
    for _ in range(config.iterations):
        step = _icp_step(
            padded[active] - centre[active, None, :],
            rotation[active],
            surface[active],
            (beyond[active], entry[active]) if any_beyond else None,
            config,
        )
        centre[active] += np.einsum("kij,kj->ki", rotation[active], step[:, 3:])
        rotation[active] = rotation[active] @ _rodrigues(step[:, :3])
        moving = (norm3(step[:, 3:]) >= 1e-5) | (norm3(step[:, :3]) >= 1e-4)
        active = active[moving]
        if active.size == 0:
            break
    poses = np.tile(np.eye(4), (count, 1, 1))
    poses[:, :3, :3] = rotation
    poses[:, :3, 3] = centre
    return list(poses)


def _icp_step(
    offsets: np.ndarray,
    rotation: np.ndarray,
    surface: np.ndarray,
    beyond: tuple[np.ndarray, np.ndarray] | None,
    config: BoxFitConfig,
) -> np.ndarray:
    """One Gauss-Newton step (rotation vector, translation in the body frame) per box;
    ``offsets`` are the points minus the box centre (boxes x points x 3, padded)."""
    body = offsets @ rotation
    excess = np.abs(body) - HALF_SIZE
    axis = argmax3(excess)
    used = surface
    if beyond is not None:  # outside points inside the box, paired with their nearest face
        outside, entry = beyond
        depth = HALF_SIZE - np.abs(body)
        inside = outside & np.all(depth > 0.0, axis=-1)
        np.put_along_axis(depth, entry[..., None], np.inf, axis=-1)
        axis = np.where(outside, depth.argmin(axis=-1), axis)
        used = surface | inside
    # the face normal is sign * e_axis: the Jacobian row (e_axis x body, -e_axis) times
    # the sign, which squares to 1 in the Hessian and goes into the gradient; e_axis as
    # three masks (numpy multiplies them as 1.0 and 0.0), cheaper than gathered rows
    x, y, z = axis == 0, axis == 1, axis == 2
    b0, b1, b2 = body[..., 0], body[..., 1], body[..., 2]
    signed = np.where(x, b0, np.where(y, b1, b2))
    residual = np.where(x, excess[..., 0], np.where(y, excess[..., 1], excess[..., 2]))
    jacobian = np.empty((*body.shape[:2], 6))
    np.subtract(y * b2, z * b1, out=jacobian[..., 0])
    np.subtract(z * b0, x * b2, out=jacobian[..., 1])
    np.subtract(x * b1, y * b0, out=jacobian[..., 2])
    for column, mask in enumerate((x, y, z), start=3):
        np.multiply(mask, -1.0, out=jacobian[..., column])
    weight = np.minimum(1.0, config.loss_scale / np.maximum(np.abs(residual), 1e-12)) * used
    transposed = jacobian.transpose(0, 2, 1)
    hessian = transposed @ (weight[..., None] * jacobian)
    trace = np.trace(hessian, axis1=1, axis2=2)
    hessian += config.damping * trace[:, None, None] / 6.0 * IDENTITY_6
    gradient = transposed @ (weight * np.sign(signed) * residual)[..., None]
    return np.linalg.solve(hessian, -gradient)[..., 0]


def _cross_rows(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise cross product of 3-vectors (np.cross costs ten times as much)."""
    a0, a1, a2, b0, b1, b2 = a[..., 0], a[..., 1], a[..., 2], b[..., 0], b[..., 1], b[..., 2]
    return np.stack([a1 * b2 - a2 * b1, a2 * b0 - a0 * b2, a0 * b1 - a1 * b0], axis=-1)


def _rodrigues(rotation_vectors: np.ndarray) -> np.ndarray:
    """Rotation matrices of rotation vectors (k x 3), Rodrigues' formula."""
    angle = norm3(rotation_vectors)
    still = angle < 1e-12
    axis = rotation_vectors / np.where(still, 1.0, angle)[:, None]
    x, y, z = axis[:, 0], axis[:, 1], axis[:, 2]
    s, c = np.sin(angle), 1.0 - np.cos(angle)
    matrices = np.empty((angle.size, 3, 3))
    matrices[:, 0, 0] = 1.0 - c * (y * y + z * z)
    matrices[:, 0, 1] = c * x * y - s * z
    matrices[:, 0, 2] = c * x * z + s * y
    matrices[:, 1, 0] = c * x * y + s * z
    matrices[:, 1, 1] = 1.0 - c * (x * x + z * z)
    matrices[:, 1, 2] = c * y * z - s * x
    matrices[:, 2, 0] = c * x * z - s * y
    matrices[:, 2, 1] = c * y * z + s * x
    matrices[:, 2, 2] = 1.0 - c * (x * x + y * y)
    matrices[still] = IDENTITY_3
    return matrices

"""The known domino: its size, its box distance function and its symmetries."""

from __future__ import annotations

import numpy as np

from dombot_description import DOMINO_SIZE as _SIZE
from dombot_description.grasp import excess_signed_distance

DOMINO_SIZE = np.asarray(_SIZE, dtype=float)  # m: length (x), width (y), thickness (z)
HALF_SIZE = DOMINO_SIZE / 2.0

# The box looks the same after a half turn about any body axis: the four proper
# rotations of its symmetry group (identity, Rx(pi), Ry(pi), Rz(pi)).
SYMMETRIES = np.array(
    [
        np.diag([1.0, 1.0, 1.0]),
        np.diag([1.0, -1.0, -1.0]),
        np.diag([-1.0, 1.0, -1.0]),
        np.diag([-1.0, -1.0, 1.0]),
    ]
)


# Cell centres of a 16 x 8 x 3 grid over the box (3 x 3 x 2.5 mm cells): volume samples.
_GRID = np.stack(
    np.meshgrid(
        *[np.linspace(-h, h, 2 * n + 1)[1::2] for h, n in zip(HALF_SIZE, (16, 8, 3), strict=True)],
        indexing="ij",
    ),
    axis=-1,
).reshape(-1, 3)


def face_areas() -> np.ndarray:
    """Area of the faces whose normal is body x, y, z [m^2]."""
    length, width, thickness = DOMINO_SIZE
    return np.array([width * thickness, length * thickness, length * width])


def box_signed_distance(points_body: np.ndarray, half_size: np.ndarray = HALF_SIZE) -> np.ndarray:
    """Signed distance of body-frame points to the box surface (negative inside)."""
    return excess_signed_distance(np.abs(points_body) - half_size)


def argmax3(vectors: np.ndarray) -> np.ndarray:
    """``vectors.argmax(axis=-1)`` for 3-vectors (the first of equal maxima, as numpy)."""
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    return np.where(z > np.maximum(x, y), 2, (y > x).astype(np.intp))


def norm3(vectors: np.ndarray) -> np.ndarray:
    """``np.linalg.norm(vectors, axis=-1)`` for 3-vectors: numpy reduces an axis of 3 element
    by element, ten times slower than three whole-array operations."""
    x, y, z = vectors[..., 0], vectors[..., 1], vectors[..., 2]
    return np.sqrt(x * x + y * y + z * z)


def dot3(a: np.ndarray, b: np.ndarray) -> np.ndarray:
    """Row-wise dot product of 3-vectors (``einsum("...k,...k->...")``, three times faster)."""
    return a[..., 0] * b[..., 0] + a[..., 1] * b[..., 1] + a[..., 2] * b[..., 2]


def overlap_fraction(first: np.ndarray, second: np.ndarray, margin: float = 0.0) -> float:
    """Share of the ``first`` box's volume (pose 4x4) lying more than ``margin`` deep inside
    the ``second`` box; the larger of the two directions."""

    def inside(a: np.ndarray, b: np.ndarray) -> float:
        body = (_GRID @ a[:3, :3].T + a[:3, 3] - b[:3, 3]) @ b[:3, :3]
        return float(np.mean(np.all(np.abs(body) < HALF_SIZE - margin, axis=1)))

    return max(inside(first, second), inside(second, first))


def dominant_face(normals: np.ndarray, cos_limit: float = 0.94, samples: int = 120) -> np.ndarray:
    """Mask of the normals that agree with the most common normal direction.

    Votes among an evenly strided subset (deterministic, cheap: samples^2 products).
    """
    voters = normals[:: max(1, normals.shape[0] // samples)]
    support = (voters @ voters.T > cos_limit).sum(axis=1)
    return normals @ voters[np.argmax(support)] > cos_limit


def orientation_error(estimated: np.ndarray, truth: np.ndarray) -> float:
    """Angle [rad] between two domino orientations, modulo the box symmetries."""
    relative = truth.T @ estimated
    traces = np.einsum("sij,ji->s", SYMMETRIES, relative)
    return float(np.arccos(np.clip((traces.max() - 1.0) / 2.0, -1.0, 1.0)))

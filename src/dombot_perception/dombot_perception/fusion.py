"""Merge the masks of several cameras that see the same domino.

Two masks from different cameras belong to one domino when many of their points lie
on the same surface: for each pair of cameras, every point of one camera finds its
nearest point of the other (one k-d tree per camera), and the masks with the most
such close pairs are matched, one-to-one and only when each is the other's best.
Mutual best matching keeps a mask that merges two dominoes in one camera from
gluing two separate masks of the other camera together.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.cluster.hierarchy import DisjointSet
from scipy.spatial import cKDTree


@dataclass
class MaskCloud:
    """One mask's surface points in world, with normals turned towards its camera."""

    camera: str
    pixels: np.ndarray  # flat pixel indices in that camera's image
    points: np.ndarray  # Nx3
    normals: np.ndarray  # Nx3


@dataclass
class FusedCloud:
    parts: list[MaskCloud]

    @property
    def points(self) -> np.ndarray:
        return np.concatenate([part.points for part in self.parts])

    @property
    def normals(self) -> np.ndarray:
        return np.concatenate([part.normals for part in self.parts])

    @property
    def cameras(self) -> tuple[str, ...]:
        return tuple(sorted({part.camera for part in self.parts}))


@dataclass(frozen=True)
class FusionConfig:
    match_distance: float = 0.003  # m: points closer than this lie on the same surface
    min_overlap: float = 0.15  # shared fraction of the smaller mask needed to merge


def fuse(masks: list[MaskCloud], config: FusionConfig) -> list[FusedCloud]:
    """Group masks across cameras; every mask ends up in exactly one cloud."""
    cameras = sorted({mask.camera for mask in masks})
    groups = DisjointSet(range(len(masks)))
    for first_index, first in enumerate(cameras):
        for second in cameras[first_index + 1 :]:
            for a, b in _mutual_matches(masks, first, second, config):
                groups.merge(a, b)
    return [FusedCloud([masks[i] for i in sorted(subset)]) for subset in groups.subsets()]


def _mutual_matches(
    masks: list[MaskCloud], first: str, second: str, config: FusionConfig
) -> list[tuple[int, int]]:
    """Index pairs (first-camera mask, second-camera mask) that are each other's best."""
    ids_a = [i for i, mask in enumerate(masks) if mask.camera == first]
    ids_b = [i for i, mask in enumerate(masks) if mask.camera == second]
    if not ids_a or not ids_b:
        return []
    points_a = np.concatenate([masks[i].points for i in ids_a])
    owner_a = np.repeat(np.arange(len(ids_a)), [masks[i].points.shape[0] for i in ids_a])
    points_b = np.concatenate([masks[i].points for i in ids_b])
    owner_b = np.repeat(np.arange(len(ids_b)), [masks[i].points.shape[0] for i in ids_b])
    distance, nearest = cKDTree(points_b).query(
        points_a, distance_upper_bound=config.match_distance
    )
    close = np.isfinite(distance)
    shared = np.zeros((len(ids_a), len(ids_b)))
    np.add.at(shared, (owner_a[close], owner_b[nearest[close]]), 1.0)
    sizes_a = np.bincount(owner_a, minlength=len(ids_a))
    sizes_b = np.bincount(owner_b, minlength=len(ids_b))
    overlap = shared / np.minimum.outer(sizes_a, sizes_b)
    best_b = overlap.argmax(axis=1)
    best_a = overlap.argmax(axis=0)
    return [
        (ids_a[a], ids_b[b])
        for a, b in enumerate(best_b)
        if best_a[b] == a and overlap[a, b] >= config.min_overlap
    ]

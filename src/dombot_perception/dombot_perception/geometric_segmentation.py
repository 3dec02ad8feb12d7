"""Default segmentation backend: depth geometry alone, no learned weights.

Dominoes are boxes, so each one's visible surface is a set of planar faces meeting at
convex edges, while two different dominoes meet at a depth jump (one occludes the
other) or at a concave crease (one rests on the other). Neighbouring pixels are
linked when neither happens; linked regions are the masks. Dominoes lying side by
side at the same height form one coplanar region with no crease at all: a region
larger than one domino is split into as many parts as its area holds dominoes:
k-means first, then boxes of the domino's size fitted to the parts claim the points
on their surfaces (see ``split_oversized``).
"""

from __future__ import annotations

import hashlib
import threading
from collections.abc import Generator
from dataclasses import dataclass
from typing import TypeVar

import numpy as np
from scipy.cluster.vq import kmeans2
from scipy.sparse import coo_matrix
from scipy.sparse.csgraph import connected_components

from dombot_perception.backprojection import OrganisedCloud
from dombot_perception.box_fit import BoxFit, BoxFitConfig, BoxFitError, fit_domino_boxes
from dombot_perception.domino_model import (
    DOMINO_SIZE,
    box_signed_distance,
    dominant_face,
    dot3,
    face_areas,
    norm3,
)
from dombot_perception.frames import CameraView

SPLIT_ROUNDS = 2  # box-fit / reassign rounds when splitting a region
MAX_SPLIT_DEPTH = 3  # a part of a split region may be split again this often
SPLIT_FIT_POINTS = 600  # points of a region used to fit the boxes that split it
SPLIT_GOOD_FIT = 0.9  # share of a region's points on their part's box that ends the search
ON_BOX_DISTANCE = 0.002  # m
T = TypeVar("T")
SPLIT_FIT = BoxFitConfig(max_fit_points=120, iterations=8, passes=1)  # quick: only to split


@dataclass(frozen=True)
class GeometricSegmenterConfig:
    max_step: float = 0.0025  # m: neighbour distance above this (or 3.5 px) is a depth jump
    max_step_pixels: float = 3.5
    max_normal_angle: float = 25.0  # deg: smoother than this is one face
    convex_margin: float = 1e-5  # m: (p-q).(n_p-n_q) above this is a convex edge
    min_pixels: int = 25
    oversize_margin: float = 0.008  # m beyond the domino's extents means several dominoes
    seed: int = 0


class GeometricSegmenter:
    """Masks from depth discontinuities and concave creases; see the module docstring."""

    name = "geometric"

    def __init__(self, config: GeometricSegmenterConfig | None = None) -> None:
        self.config = config or GeometricSegmenterConfig()
        # each camera's regions of the previous frame and their parts, by content: after a
        # pick most of the pile looks as it did, and splitting a region is most of the work.
        # Read and replaced under the lock: perception_node's placement checks segment
        # (camera_2) beside its detects (the pile cameras)
        self._previous: dict[str, dict[bytes, list[np.ndarray]]] = {}
        self._lock = threading.Lock()

    def segment(self, view: CameraView, cloud: OrganisedCloud | None) -> list[np.ndarray]:
        """Flat pixel indices of each mask, one per domino candidate."""
        return self.segment_views([view], [cloud])[0]

    def segment_views(
        self, views: list[CameraView], clouds: list[OrganisedCloud | None]
    ) -> list[list[np.ndarray]]:
        """``segment`` of each view; the oversized regions of all views are split side by
        side (``run_batched``: the fewer, larger batches of box fits, the faster)."""
        found = {
            view.name: self._regions(view, cloud) for view, cloud in zip(views, clouds, strict=True)
        }
        current: dict[str, dict[bytes, list[np.ndarray]]] = {}
        unsplit = []
        with self._lock:
            previous = dict(self._previous)
        for name, regions in found.items():
            if regions is None:
                continue  # nothing to segment: the view's memory stays as it was
            known = previous.get(name, {})
            current[name] = {key: known[key] for key in regions if key in known}
            unsplit += [(name, key) for key in regions if key not in known]
        margin, seed = self.config.oversize_margin, self.config.seed
        splits = [split_steps(*found[name][key], margin, seed) for name, key in unsplit]
        for (name, key), parts in zip(unsplit, run_batched(splits), strict=True):
            current[name][key] = parts
        with self._lock:
            self._previous.update(current)
        minimum = self.config.min_pixels
        return [
            [
                part
                for key in found[view.name] or {}
                for part in current[view.name][key]
                if part.size >= minimum
            ]
            for view in views
        ]

    def _regions(
        self, view: CameraView, cloud: OrganisedCloud | None
    ) -> dict[bytes, tuple[np.ndarray, ...]] | None:
        """The view's linked regions large enough for a mask, by ``_content_key``: each one's
        image pixels, points, normals and surface areas; None when too little is seen."""
        config = self.config
        if cloud is None or cloud.valid.sum() < config.min_pixels:
            return None
        flat_points = cloud.points.reshape(-1, 3)
        flat_normals = cloud.normals.reshape(-1, 3)
        surface_areas = _surface_areas(
            flat_points, flat_normals, cloud.pixel_size.ravel(), view.X_WC[:3, 3]
        )
        regions = {}
        for pixels in _linked_components(cloud, config):
            if pixels.size < config.min_pixels:
                continue  # nor could any of its parts be a mask
            region = (
                cloud.full_index(pixels),  # the image's pixels: the crop may move between frames
                flat_points[pixels],
                flat_normals[pixels],
                surface_areas[pixels],
            )
            regions[_content_key(region)] = region
        return regions


def _content_key(arrays: tuple[np.ndarray, ...]) -> bytes:
    """A digest of everything ``split_oversized`` reads of a region: equal digests, equal
    parts."""
    digest = hashlib.blake2b(digest_size=20)
    for array in arrays:
        digest.update(np.ascontiguousarray(array).data)
    return digest.digest()


def _linked_components(cloud: OrganisedCloud, config: GeometricSegmenterConfig) -> list[np.ndarray]:
    """Connected regions of crop pixels linked right/down when on the same convex surface."""
    points, normals, valid, pixel_size = cloud.points, cloud.normals, cloud.valid, cloud.pixel_size
    height, width = valid.shape
    index = np.arange(height * width).reshape(height, width)
    cos_limit = np.cos(np.radians(config.max_normal_angle))
    sources, targets = [], []
    for here, there in (
        ((slice(None), slice(0, -1)), (slice(None), slice(1, None))),
        ((slice(0, -1), slice(None)), (slice(1, None), slice(None))),
    ):
        p, q = points[here], points[there]
        n_p, n_q = normals[here], normals[there]
        both = valid[here] & valid[there]
        step = p - q
        gap = norm3(step)
        limit = np.maximum(config.max_step, config.max_step_pixels * pixel_size[here])
        smooth = dot3(n_p, n_q) > cos_limit
        convex = dot3(step, n_p - n_q) > config.convex_margin
        with np.errstate(invalid="ignore"):
            linked = both & (gap < limit) & (smooth | convex)
        sources.append(index[here][linked])
        targets.append(index[there][linked])
    source = np.concatenate(sources)
    target = np.concatenate(targets)
    graph = coo_matrix(
        (np.ones(source.size, dtype=np.int8), (source, target)), shape=(height * width,) * 2
    )
    _, labels = connected_components(graph, directed=False)
    labels = np.where(valid.ravel(), labels, -1)
    order = np.argsort(labels, kind="stable")
    sorted_labels = labels[order]
    starts = np.flatnonzero(np.diff(sorted_labels, prepend=-2))
    groups = np.split(order, starts[1:])
    return [group for group in groups if labels[group[0]] >= 0]


def _surface_areas(
    points: np.ndarray, normals: np.ndarray, pixel_size: np.ndarray, camera_position: np.ndarray
) -> np.ndarray:
    """Area [m^2] of the surface patch each pixel sees: its footprint over the view cosine."""
    rays = points - camera_position
    with np.errstate(invalid="ignore", divide="ignore"):
        cosine = np.abs(dot3(normals, rays)) / norm3(rays)
        return pixel_size**2 / np.maximum(cosine, 0.2)


# a computation that yields the clouds it needs box fits of and is sent the fits back
FitSteps = Generator[list[tuple[np.ndarray, np.ndarray]], list[BoxFit | BoxFitError], T]


def run_batched(tasks: list[FitSteps[T]]) -> list[T]:
    """Run the ``tasks`` side by side, the box fits all of them ask for at a step fitted in
    one batch (the fewer, larger batches, the less numpy call overhead per box)."""
    results: list[T | None] = [None] * len(tasks)
    waiting: dict[int, list[tuple[np.ndarray, np.ndarray]]] = {}

    def advance(index: int, fits: list[BoxFit | BoxFitError] | None) -> None:
        try:
            waiting[index] = tasks[index].send(fits)
        except StopIteration as done:
            results[index] = done.value

    for index in range(len(tasks)):
        advance(index, None)
    while waiting:
        asked, waiting = waiting, {}
        fits = fit_domino_boxes([cloud for clouds in asked.values() for cloud in clouds], SPLIT_FIT)
        start = 0
        for index, clouds in asked.items():
            advance(index, fits[start : start + len(clouds)])
            start += len(clouds)
    return results


def split_oversized(
    pixels: np.ndarray,
    points: np.ndarray,
    normals: np.ndarray,
    surface_areas: np.ndarray,
    margin: float,
    seed: int,
) -> list[np.ndarray]:
    """Split a region too big for one domino into k parts, k = its largest face's area
    over a domino's largest face (48 x 24 mm), by seeded k-means on the 3-D points; a
    part still too big (dominoes at different slopes share no dominant face) is split
    again, up to ``MAX_SPLIT_DEPTH`` times."""
    return run_batched([split_steps(pixels, points, normals, surface_areas, margin, seed)])[0]


def split_steps(
    pixels: np.ndarray,
    points: np.ndarray,
    normals: np.ndarray,
    surface_areas: np.ndarray,
    margin: float,
    seed: int,
    depth: int = 0,
) -> FitSteps[list[np.ndarray]]:
    """``split_oversized`` as steps for ``run_batched``."""
    if depth >= MAX_SPLIT_DEPTH or points.shape[0] < 8 or not _too_big(points, margin):
        return [pixels]
    face = dominant_face(normals)
    count = int(np.clip(np.round(surface_areas[face].sum() / face_areas().max()), 2, 6))
    assignment, count = yield from _best_split(points, normals, count, seed)
    parts = []
    for k in range(count):
        part = assignment == k
        if np.any(part):
            parts += yield from split_steps(
                pixels[part],
                points[part],
                normals[part],
                surface_areas[part],
                margin,
                seed,
                depth + 1,
            )
    return parts


def _best_split(
    points: np.ndarray, normals: np.ndarray, count: int, seed: int
) -> FitSteps[tuple[np.ndarray, int]]:
    """Part labels (and how many parts) that put the most points on their part's box.

    The first k-means start usually explains the region; when it leaves more than
    ``SPLIT_GOOD_FIT`` of the points off the boxes, other starts and one more part are
    tried and the best kept.
    """
    best: tuple[float, np.ndarray, int] | None = None
    distances: dict[bytes, np.ndarray] = {}  # a part found again by another start: same box
    for parts, start in ((count, seed), (count, seed + 1), (count, seed + 2), (count + 1, seed)):
        # the points are finite (valid pixels): no check of them in each of its 20 steps
        _, initial = kmeans2(
            points - points.mean(axis=0), parts, minit="++", seed=start, check_finite=False
        )
        assignment, on_box = yield from _assign_to_boxes(points, normals, initial, parts, distances)
        if best is None or on_box > best[0]:
            best = (on_box, assignment, parts)
        if on_box >= SPLIT_GOOD_FIT:
            break
    return best[1], best[2]


def _assign_to_boxes(
    points: np.ndarray,
    normals: np.ndarray,
    assignment: np.ndarray,
    count: int,
    fitted: dict[bytes, np.ndarray],
) -> FitSteps[tuple[np.ndarray, float]]:
    """Refine a k-means split with the domino's shape: fit a box to each part, give each
    point to the box whose surface it lies on, repeat until nothing moves. Also returns
    the share of points within 2 mm of their box.

    k-means cuts between centroids; dominoes side by side are cut along their edges.
    ``fitted`` holds each part's point distances to its box, by the part's points, for the
    parts that stay as they were between rounds and starts.
    """
    stride = max(1, points.shape[0] // SPLIT_FIT_POINTS)  # fit on a subset, assign all
    for _ in range(SPLIT_ROUNDS):
        parts = [np.flatnonzero(assignment == k)[::stride] for k in range(count)]
        keys = [part.tobytes() if part.size >= 10 else None for part in parts]
        new = {
            key: part
            for key, part in zip(keys, parts, strict=True)
            if key is not None and key not in fitted
        }
        if new:
            fits = yield [(points[part], normals[part]) for part in new.values()]
            fitted.update(zip(new, _distances(points, fits), strict=True))
        distances = np.array([fitted[key] if key else _no_box(points) for key in keys])
        nearest = distances.min(axis=0)
        if not np.all(np.isfinite(nearest)):
            return assignment, 0.0
        on_box = float(np.mean(nearest < ON_BOX_DISTANCE))
        updated = distances.argmin(axis=0)
        if np.array_equal(updated, assignment):
            break
        assignment = updated
    return assignment, on_box


def _distances(points: np.ndarray, fits: list[BoxFit | BoxFitError]) -> list[np.ndarray]:
    """Distance of every point to the surface of each fitted box (inf where no box fits),
    all boxes at once."""
    poses = np.array([fit.X_WD for fit in fits if not isinstance(fit, BoxFitError)])
    poses = poses.reshape(-1, 4, 4)
    body = (points - poses[:, None, :3, 3]) @ poses[:, :3, :3]
    distances = iter(np.abs(box_signed_distance(body)))
    return [_no_box(points) if isinstance(fit, BoxFitError) else next(distances) for fit in fits]


def _no_box(points: np.ndarray) -> np.ndarray:
    return np.full(points.shape[0], np.inf)


def _too_big(points: np.ndarray, margin: float) -> bool:
    """Principal extents beyond the domino's own (longest first)."""
    centred = points - points.mean(axis=0)
    _, _, axes = np.linalg.svd(centred, full_matrices=False)
    projected = centred @ axes.T
    extents = projected.max(axis=0) - projected.min(axis=0)
    limits = np.sort(DOMINO_SIZE)[::-1] + margin
    return bool(np.any(extents[:2] > limits[:2]))

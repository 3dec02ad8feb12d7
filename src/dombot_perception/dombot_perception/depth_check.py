"""Check a fitted box against the depth images it came from (model-based verification).

A box fitted to the visible part of a domino is tight on that part, yet may stick out
where the domino is not: the box of a half-hidden domino shifted along its length,
or a box spanning the patches of two dominoes. The depth images say so. Casting each
pixel's ray at the fitted box (known intrinsics and camera pose) predicts the depth
at which the camera should see the box; comparing with the measured depth sorts the
box's pixels into

* *supported*: measured within ``support_tolerance`` of the prediction;
* *occluded*: measured in front (something lies between the camera and the box:
  no evidence either way);
* *see-through*: measured more than ``margin`` behind the box's surface, where a
  solid box would block the view (free-space violation).

Only the interior of the box's silhouette counts (its one-pixel rim is eroded: a
pixel there sees half the box and half its surroundings) and only faces seen less
obliquely than ``MIN_VIEW_COSINE``. Pixels with no depth return are unknown. The
see-through pixels also tell how to correct the box: their ray's entry point on the
box must lie outside it (``box_fit.refine_pose`` takes them as one-sided residuals).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np
from scipy.ndimage import binary_erosion

from dombot_perception.box_fit import BoxFit, BoxFitConfig, fit_statistics, refine_pose
from dombot_perception.domino_model import HALF_SIZE, box_signed_distance, norm3
from dombot_perception.frames import CameraView

MIN_VIEW_COSINE = 0.3  # faces seen more obliquely than ~73 degrees are not checked
CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])


@dataclass(frozen=True)
class DepthCheckConfig:
    support_tolerance: float = 0.002  # m: measured this close to the box surface supports it
    margin: float = 0.003  # m: measured this far behind the box surface sees through it
    correct_above: float = 0.02  # see-through fraction above which the box is corrected
    corrections: int = 3  # rounds of correction at most


@dataclass
class Silhouette:
    """The interior pixels of one camera's view of a box, and what the camera measured there."""

    predicted: np.ndarray  # depth [m] at which the ray enters the box
    measured: np.ndarray  # depth [m] in the image; inf where there is no return
    entry: np.ndarray  # Nx3 entry points of the rays, world
    entry_axis: np.ndarray  # body axis of the face each ray enters through
    window: tuple[int, int, int, int]  # top, bottom, left, right: the depth pixels read


@dataclass
class DepthEvidence:
    """Pixel counts over all cameras (interior of the silhouettes, non-grazing faces) and
    the entry points of the rays that see past the box."""

    supported: int = 0
    occluded: int = 0
    see_through: int = 0
    outside: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))  # world
    outside_axis: np.ndarray = field(default_factory=lambda: np.zeros(0, dtype=int))
    # (camera, window) of every depth window read on the way: the evidence depends on the
    # views only through these pixels (and the camera matrices and poses)
    reads: list[tuple[str, tuple[int, int, int, int]]] = field(default_factory=list)

    @property
    def hidden_fraction(self) -> float:
        """Of the pixels with a depth return, those where something stands in front."""
        known = self.supported + self.occluded + self.see_through
        return self.occluded / known if known else 1.0

    @property
    def see_through_fraction(self) -> float:
        """Of the pixels where the camera could have seen the box, those it saw past."""
        visible = self.supported + self.see_through
        return self.see_through / visible if visible else 0.0


def silhouette(pose: np.ndarray, view: CameraView) -> Silhouette | None:
    """Ray-cast the box at ``pose`` into ``view``; None when it is behind or off the image."""
    rotation_wc, camera = view.X_WC[:3, :3], view.X_WC[:3, 3]
    corners = (CORNERS * HALF_SIZE) @ pose[:3, :3].T + pose[:3, 3]
    local = (corners - camera) @ rotation_wc
    if np.any(local[:, 2] <= 0):
        return None
    intrinsics = view.K
    u = local[:, 0] / local[:, 2] * intrinsics[0, 0] + intrinsics[0, 2]
    v = local[:, 1] / local[:, 2] * intrinsics[1, 1] + intrinsics[1, 2]
    height, width = view.depth.shape
    left, right = max(int(np.floor(u.min())), 0), min(int(np.ceil(u.max())), width - 1)
    top, bottom = max(int(np.floor(v.min())), 0), min(int(np.ceil(v.max())), height - 1)
    if left > right or top > bottom:
        return None
    rows, cols = np.mgrid[top : bottom + 1, left : right + 1]
    # camera rays with unit z: the ray parameter at a hit is the hit's depth
    rays = np.stack(
        [
            (cols - intrinsics[0, 2]) / intrinsics[0, 0],
            (rows - intrinsics[1, 2]) / intrinsics[1, 1],
            np.ones(cols.shape),
        ],
        axis=-1,
    )
    origin = pose[:3, :3].T @ (camera - pose[:3, 3])
    directions = rays @ (rotation_wc.T @ pose[:3, :3])  # body frame
    with np.errstate(divide="ignore", invalid="ignore"):
        first = (-HALF_SIZE - origin) / directions
        second = (HALF_SIZE - origin) / directions
    lower = np.fmin(first, second)
    upper = np.fmax(first, second)
    # fmax/fmin skip NaN as nanmax/nanmin do, without their slow reduction over 3 values
    near = np.fmax(np.fmax(lower[..., 0], lower[..., 1]), lower[..., 2])
    far = np.fmin(np.fmin(upper[..., 0], upper[..., 1]), upper[..., 2])
    hit = (near <= far) & (near > 0)
    interior = binary_erosion(hit, border_value=0)
    axis = np.nanargmax(lower[interior], axis=-1)
    directions = directions[interior]
    cosine = np.abs(directions[np.arange(axis.size), axis]) / norm3(directions)
    facing = cosine > MIN_VIEW_COSINE
    depth = near[interior][facing]
    entry_body = origin + directions[facing] * depth[:, None]
    measured = view.depth[rows[interior][facing], cols[interior][facing]].astype(float)
    with np.errstate(invalid="ignore"):
        measured[~(np.isfinite(measured) & (measured > 0))] = np.nan
    return Silhouette(
        predicted=depth,
        measured=measured,
        entry=entry_body @ pose[:3, :3].T + pose[:3, 3],
        entry_axis=axis[facing],
        window=(top, bottom + 1, left, right + 1),
    )


def depth_evidence(
    pose: np.ndarray, views: list[CameraView], config: DepthCheckConfig
) -> DepthEvidence:
    """How the measured depth agrees with the box at ``pose``, summed over the views."""
    counts = np.zeros(3, dtype=int)
    outside, outside_axis = [np.zeros((0, 3))], [np.zeros(0, dtype=int)]
    reads = []
    for view in views:
        seen = silhouette(pose, view)
        if seen is None:
            reads.append((view.name, (0, 0, 0, 0)))
            continue
        reads.append((view.name, seen.window))
        with np.errstate(invalid="ignore"):
            difference = seen.measured - seen.predicted  # NaN (no return): unknown
            beyond = difference > config.margin
            counts += [
                np.count_nonzero(np.abs(difference) <= config.support_tolerance),
                np.count_nonzero(difference < -config.support_tolerance),
                np.count_nonzero(beyond),
            ]
        outside.append(seen.entry[beyond])
        outside_axis.append(seen.entry_axis[beyond])
    return DepthEvidence(
        *(int(c) for c in counts), np.concatenate(outside), np.concatenate(outside_axis), reads
    )


def correct_box(
    fit: BoxFit,
    points: np.ndarray,
    views: list[CameraView],
    config: DepthCheckConfig,
    fit_config: BoxFitConfig,
) -> tuple[BoxFit, DepthEvidence]:
    """Move a box that cameras see past off those rays, keeping its points on it.

    A domino whose one end is hidden is fitted from the part that shows, and the box
    may then stick out beyond the other end by millimetres; the rays past that end
    pin it. Each round refits the box's inliers with the see-through entry points as
    points that must lie outside (``refine_pose``); a round is kept only when fewer of
    the box's pixels are seen through.
    """
    evidence = depth_evidence(fit.X_WD, views, config)
    reads = evidence.reads
    if evidence.see_through_fraction > config.correct_above:
        fit, evidence, slid_reads = _flush_with_an_end(
            fit, points, views, config, fit_config, evidence
        )
        reads += slid_reads
    for _ in range(config.corrections):
        if evidence.see_through_fraction <= config.correct_above:
            break
        on_box = _on_box(fit.X_WD, points, fit_config.inlier_distance)
        stride = max(1, int(on_box.sum()) // fit_config.max_fit_points)
        pose = refine_pose(
            fit.X_WD, points[on_box][::stride], fit_config, evidence.outside, evidence.outside_axis
        )
        corrected = depth_evidence(pose, views, config)
        reads += corrected.reads
        if corrected.see_through_fraction >= evidence.see_through_fraction:
            break
        fit = fit_statistics(pose, points, _on_box(pose, points, fit_config.inlier_distance))
        evidence = corrected
    evidence.reads = reads
    return fit, evidence


def _flush_with_an_end(
    fit: BoxFit,
    points: np.ndarray,
    views: list[CameraView],
    config: DepthCheckConfig,
    fit_config: BoxFitConfig,
    evidence: DepthEvidence,
) -> tuple[BoxFit, DepthEvidence, list]:
    """The box slid along its length to end where its points end, at one end or the
    other, when the cameras see past less of it there.

    A piece of a domino's face half its length long (the segmentation cuts a struck
    run's shingled dominoes so) leaves the box
    free to sit anywhere along it, and from a box seen past on half its pixels the ICP
    rounds below often stall; its points end where the domino does. On struck arcs
    this located 24 of 40 toppled dominoes instead of 21. A slide that leaves no point on
    the box is no end of it (circle30 seed 6: one such slide failed the check after the
    strike).
    Also returns the depth windows read.
    """
    along = (points - fit.X_WD[:3, 3]) @ fit.X_WD[:3, 0]
    best, best_evidence, reads = fit, evidence, []
    for shift in (along.min() + HALF_SIZE[0], along.max() - HALF_SIZE[0]):
        pose = fit.X_WD.copy()
        pose[:3, 3] += shift * fit.X_WD[:3, 0]
        slid = depth_evidence(pose, views, config)
        reads += slid.reads
        on_box = _on_box(pose, points, fit_config.inlier_distance)
        if slid.see_through_fraction < best_evidence.see_through_fraction and on_box.any():
            best, best_evidence = fit_statistics(pose, points, on_box), slid
    return best, best_evidence, reads


def _on_box(pose: np.ndarray, points: np.ndarray, distance: float) -> np.ndarray:
    return np.abs(box_signed_distance((points - pose[:3, 3]) @ pose[:3, :3])) < distance

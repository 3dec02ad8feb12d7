"""RGB-D views in, ranked domino detections out: every stage in order, each timed.

segmentation -> back-projection (+ outlier removal) -> multi-camera fusion -> box fit
-> filtering -> canonical frame -> grasp scoring. Each stage lives in its own
module; this one only wires them and records how long each took and why anything
was dropped, so a caller can show it.
"""

from __future__ import annotations

import dataclasses
import hashlib
import time
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field

import numpy as np
from scipy.spatial import cKDTree

from dombot_description.scenario import Scenario
from dombot_perception.backprojection import OrganisedCloud, WorkRegion, organised_cloud
from dombot_perception.box_fit import BoxFit, BoxFitConfig, BoxFitError, fit_domino_boxes
from dombot_perception.canonical import canonical_pose, posture
from dombot_perception.depth_check import DepthCheckConfig, correct_box
from dombot_perception.domino_model import (
    DOMINO_SIZE,
    box_signed_distance,
    orientation_error,
    overlap_fraction,
)
from dombot_perception.filtering import FilterConfig, rejection_reason, remove_outliers
from dombot_perception.frames import CameraView, Detection
from dombot_perception.fusion import FusedCloud, FusionConfig, MaskCloud, fuse
from dombot_perception.geometric_segmentation import GeometricSegmenter, GeometricSegmenterConfig
from dombot_perception.grasp_scoring import GraspScoringConfig, score_detections
from dombot_perception.segmentation import Segmenter, SegmenterError

REJOIN_DISTANCE = 0.032  # m: halves of one domino have centres about 24 mm apart
REJOIN_SIDEWAYS = 0.005  # m: and are offset across the length by less than this
PILE_MARGIN = 0.12  # m around the pile disc where dominoes may have slid
STAGES = ("segmentation", "backprojection", "fusion", "box_fit", "scoring")
BACKENDS = ("geometric", "sam")


@dataclass(frozen=True)
class PipelineConfig:
    region: WorkRegion = field(default_factory=WorkRegion)
    depth_range: tuple[float, float] = (0.1, 2.0)
    fusion: FusionConfig = field(default_factory=FusionConfig)
    box_fit: BoxFitConfig = field(default_factory=BoxFitConfig)
    depth_check: DepthCheckConfig = field(default_factory=DepthCheckConfig)
    filtering: FilterConfig = field(default_factory=FilterConfig)
    # two fragments fitted as one must fit tightly and show a side face: a loose fit, or
    # two coplanar patches of buried dominoes, is not one domino
    rejoin_filtering: FilterConfig = field(
        default_factory=lambda: FilterConfig(
            max_fit_error=0.0007, min_inlier_fraction=0.95, min_thickness_coverage=0.5
        )
    )
    scoring: GraspScoringConfig = field(default_factory=GraspScoringConfig)
    duplicate_distance: float = 0.012  # m: boxes closer than this are one domino seen twice
    # solid dominoes do not interpenetrate: of two boxes sharing more than this share of a
    # box's volume deeper than overlap_margin (the pose error where two dominoes touch),
    # one is a box fitted across parts of two dominoes
    max_overlap: float = 0.05
    overlap_margin: float = 0.001  # m
    max_scene_points: int = 15000  # obstacle points kept for the clearance check
    # m: a scene point farther than this from every detected box is on no detected domino
    # (PipelineResult.unexplained); on the pile scenes almost all such points lay on a
    # domino never detected (standing on its edge, or mostly hidden)
    unexplained_margin: float = 0.003
    seed: int = 0


@dataclass
class PipelineResult:
    detections: list[Detection]  # best grasp first
    timings: dict[str, float]  # s per stage, wall
    masks: dict[str, list[np.ndarray]]  # per camera, for debug images
    rejected: list[str] = field(default_factory=list)
    warnings: list[str] = field(default_factory=list)
    # scene points on no detected domino (N×3, world): obstacles a planner has no box for
    unexplained: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # s of this process's CPU per stage: what the wall time is with a core to itself
    cpu_timings: dict[str, float] = field(default_factory=dict)


@dataclass(frozen=True)
class _FitRecord:
    """What ``_fit_one`` made of one cloud, and the depth pixels its checks read."""

    detection: Detection | None
    fit: BoxFit | None
    messages: list[str]
    patches: list[tuple[str, tuple[int, int, int, int], np.ndarray]]  # camera, window, depth

    def still_holds(self, views: dict[str, CameraView]) -> bool:
        """Whether every depth window read is the same in ``views``."""
        return all(
            np.array_equal(views[name].depth[top:bottom, left:right], patch)
            for name, (top, bottom, left, right), patch in self.patches
        )


class PerceptionPipeline:
    def __init__(self, segmenter: Segmenter, config: PipelineConfig | None = None) -> None:
        self.segmenter = segmenter
        self.config = config or PipelineConfig()
        # the fits of the last frame and of this one, by content: after a pick most of the
        # pile looks as it did, and a cloud whose points and depth pixels are unchanged
        # gets its box back instead of being fitted and checked again
        self._previous_fits: dict[bytes, _FitRecord] = {}
        self._fits: dict[bytes, _FitRecord] = {}
        self._previous_kept: dict[bytes, np.ndarray] = {}  # the same for outlier removal
        self._kept: dict[bytes, np.ndarray] = {}

    def run(self, views: list[CameraView]) -> PipelineResult:
        """Detect dominoes in ``views`` (one frame per camera, same instant)."""
        timings = dict.fromkeys(STAGES, 0.0)
        result = PipelineResult([], timings, {}, cpu_timings=dict.fromkeys(STAGES, 0.0))
        usable = []
        for view in views:
            problem = view.check()
            if problem:
                result.warnings.append(problem)
            else:
                usable.append(view)
        if not usable:
            result.warnings.append("no usable camera view")
            return result
        with _timed(result, "backprojection"):
            clouds = {
                view.name: organised_cloud(view, self.config.region, self.config.depth_range)
                for view in usable
            }
        with _timed(result, "segmentation"):
            masks = self.segmenter.segment_views(usable, [clouds[view.name] for view in usable])
            result.masks = {view.name: found for view, found in zip(usable, masks, strict=True)}
        with _timed(result, "backprojection"):
            self._previous_kept, self._kept = self._kept, {}
            mask_clouds = self._mask_clouds(clouds, result.masks)
            scene = self._scene_points(clouds)
        if not mask_clouds:
            result.warnings.append("no domino-like surface above the table in the work region")
            return result
        with _timed(result, "fusion"):
            fused = fuse(mask_clouds, self.config.fusion)
        with _timed(result, "box_fit"):
            self._previous_fits, self._fits = self._fits, {}
            detections = self._fit(fused, usable, result.rejected)
        with _timed(result, "scoring"):
            result.detections = score_detections(detections, scene, self.config.scoring)
            result.unexplained = unexplained_points(
                scene, detections, self.config.unexplained_margin
            )
        return result

    def _mask_clouds(
        self, clouds: dict[str, OrganisedCloud | None], masks: dict[str, list[np.ndarray]]
    ) -> list[MaskCloud]:
        """Each mask's points and normals (from its camera's organised cloud), outliers removed."""
        result = []
        for name, cloud in clouds.items():
            if cloud is None:
                continue
            points = cloud.points.reshape(-1, 3)
            normals = cloud.normals.reshape(-1, 3)
            valid = cloud.valid.ravel()
            size = valid.size
            for pixels in masks[name]:
                local = cloud.crop_index(pixels)
                inside = (local >= 0) & (local < size)
                pixels, local = pixels[inside], local[inside]
                usable = valid[local]
                pixels, local = pixels[usable], local[usable]
                kept = self._inliers(points[local])
                if kept.size:
                    result.append(
                        MaskCloud(name, pixels[kept], points[local[kept]], normals[local[kept]])
                    )
        return result

    def _inliers(self, points: np.ndarray) -> np.ndarray:
        """``remove_outliers`` of ``points``; the last frame's answer for the same points."""
        filtering = self.config.filtering
        digest = hashlib.blake2b(repr(filtering).encode(), digest_size=20)
        digest.update(np.ascontiguousarray(points).data)
        key = digest.digest()
        kept = self._previous_kept.get(key)
        self._kept[key] = remove_outliers(points, filtering) if kept is None else kept
        return self._kept[key]

    def _scene_points(self, clouds: dict[str, OrganisedCloud | None]) -> np.ndarray:
        """Every point seen in the work region (all cameras), subsampled, for clearance checks."""
        seen = [cloud.valid_points() for cloud in clouds.values() if cloud is not None]
        scene = np.concatenate(seen) if seen else np.zeros((0, 3))
        if scene.shape[0] > self.config.max_scene_points:
            rng = np.random.default_rng(self.config.seed)
            scene = scene[rng.choice(scene.shape[0], self.config.max_scene_points, replace=False)]
        return scene

    def _fit(
        self, fused: list[FusedCloud], views: list[CameraView], rejected: list[str]
    ) -> list[Detection]:
        """Box-fit each fused cloud, rejoin fragments, merge duplicates, apply the filters."""
        detections, fragments = [], []
        filtering = self.config.filtering
        for cloud, (detection, fit) in zip(
            fused, self._fit_all(fused, views, rejected), strict=True
        ):
            if detection is not None:
                detections.append(detection)
            elif (
                fit is not None
                and fit.extents[0] < filtering.min_coverage * DOMINO_SIZE[0]
                and fit.fit_error <= filtering.max_fit_error
            ):
                fragments.append((cloud, fit))  # a clean fit, just too short: half a domino?
        detections += self._rejoin(fragments, views, rejected)
        return self._merge_duplicates(detections, rejected)

    def _rejoin(
        self,
        fragments: list[tuple[FusedCloud, BoxFit]],
        views: list[CameraView],
        rejected: list[str],
    ) -> list[Detection]:
        """Fit pairs of fragments as one: a region split once too often leaves two fragments
        of one domino, each too short to pass on its own. Only pairs that line up (same
        orientation, one behind the other along the length) are tried."""
        found: list[Detection] = []
        used: set[int] = set()
        for first, second in _aligned_pairs([fit for _, fit in fragments]):
            if first in used or second in used:
                continue
            joined = FusedCloud(fragments[first][0].parts + fragments[second][0].parts)
            detection, _ = self._fit_all([joined], views, [], self.config.rejoin_filtering)[0]
            if detection is not None:
                used.update((first, second))
                found.append(detection)
                where = np.round(detection.X_WD[:3, 3], 3)
                rejected.append(f"two fragments rejoined into the box at {where}")
        return found

    def _fit_all(
        self,
        clouds: list[FusedCloud],
        views: list[CameraView],
        rejected: list[str],
        filtering: FilterConfig | None = None,
    ) -> list[tuple[Detection | None, BoxFit | None]]:
        """Each cloud's detection (None when rejected, with the reason in ``rejected``) and
        fit; the last frame's when the cloud and the depth pixels its checks read are the
        same. The new boxes are fitted in one batch."""
        filtering = filtering or self.config.filtering
        config = (self.config.box_fit, self.config.depth_check, filtering)
        by_name = {view.name: view for view in views}
        keys = [_fit_key(cloud, views, config) for cloud in clouds]
        records = [self._previous_fits.get(key) for key in keys]
        stale = [
            index
            for index, record in enumerate(records)
            if record is None or not record.still_holds(by_name)
        ]
        fits = fit_domino_boxes(
            [(clouds[index].points, clouds[index].normals) for index in stale],
            self.config.box_fit,
        )
        for index, fit in zip(stale, fits, strict=True):
            records[index] = self._check_fit(clouds[index], fit, views, filtering)
        result = []
        for key, record in zip(keys, records, strict=True):
            self._fits[key] = record
            rejected.extend(record.messages)
            detection = record.detection and dataclasses.replace(record.detection)  # scored later
            result.append((detection, record.fit))
        return result

    def _check_fit(
        self,
        cloud: FusedCloud,
        fit: BoxFit | BoxFitError,
        views: list[CameraView],
        filtering: FilterConfig,
    ) -> _FitRecord:
        """The cloud's box, corrected by the depth check and filtered."""
        if isinstance(fit, BoxFitError):
            return _FitRecord(None, None, [str(fit)], [])
        points = cloud.points
        reason = rejection_reason(fit, points.shape[0], filtering)
        reads = []
        if reason is None:
            fit, evidence = correct_box(
                fit, points, views, self.config.depth_check, self.config.box_fit
            )
            reads = evidence.reads
            reason = rejection_reason(fit, points.shape[0], filtering)
            if reason is None and evidence.see_through_fraction > filtering.max_see_through:
                reason = f"cameras see past {evidence.see_through_fraction:.0%} of it"
        depth = {view.name: view.depth for view in views}
        patches = [
            (name, window, depth[name][window[0] : window[1], window[2] : window[3]].copy())
            for name, window in reads
        ]
        if reason:
            message = f"cloud at {np.round(points.mean(axis=0), 3)}: {reason}"
            return _FitRecord(None, fit, [message], patches)
        pose = canonical_pose(fit.X_WD)
        detection = Detection(
            X_WD=pose,
            size=np.abs(pose[:3, :3].T @ fit.X_WD[:3, :3]) @ fit.extents,
            posture=posture(pose[:3, :3]),
            fit_error=fit.fit_error,
            num_points=points.shape[0],
            cameras=cloud.cameras,
            points=points,
        )
        return _FitRecord(detection, fit, [], patches)

    def _merge_duplicates(
        self, detections: list[Detection], rejected: list[str]
    ) -> list[Detection]:
        """Keep one box per domino and no two boxes in one place: of boxes whose centres
        nearly coincide, or that interpenetrate, the best supported."""
        if len(detections) < 2:
            return detections
        config = self.config
        centres = np.array([d.X_WD[:3, 3] for d in detections])
        order = np.argsort([-d.num_points for d in detections])
        tree = cKDTree(centres)
        dropped = np.zeros(len(detections), dtype=bool)
        for index in order:
            if dropped[index]:
                continue
            where = np.round(centres[index], 3)
            for other in tree.query_ball_point(centres[index], float(np.linalg.norm(DOMINO_SIZE))):
                if other == index or dropped[other]:
                    continue
                if np.linalg.norm(centres[other] - centres[index]) < config.duplicate_distance:
                    dropped[other] = True
                    rejected.append(f"duplicate of the box at {where}")
                    continue
                overlap = overlap_fraction(
                    detections[other].X_WD, detections[index].X_WD, config.overlap_margin
                )
                if overlap > config.max_overlap:
                    dropped[other] = True
                    other_at = np.round(centres[other], 3)
                    rejected.append(f"box at {other_at}: {overlap:.0%} inside the box at {where}")
        return [d for d, drop in zip(detections, dropped, strict=True) if not drop]


def unexplained_points(
    points: np.ndarray, detections: list[Detection], margin: float
) -> np.ndarray:
    """The ``points`` farther than ``margin`` from every detected box (only the points
    within the box's circumscribed sphere + ``margin`` of its centre can be nearer)."""
    if not detections or not points.shape[0]:
        return points
    tree = cKDTree(points)
    reach = float(np.linalg.norm(DOMINO_SIZE)) / 2.0 + margin
    explained = np.zeros(points.shape[0], dtype=bool)
    for detection in detections:
        near = np.asarray(tree.query_ball_point(detection.X_WD[:3, 3], reach), dtype=int)
        local = (points[near] - detection.X_WD[:3, 3]) @ detection.X_WD[:3, :3]
        explained[near[box_signed_distance(local) <= margin]] = True
    return points[~explained]


def _fit_key(cloud: FusedCloud, views: list[CameraView], config: tuple) -> bytes:
    """A digest of everything a fit reads but the depth pixels: the cloud, the ``config``
    (fit, depth check, filters), each camera's name, matrix, pose and image size."""
    digest = hashlib.blake2b(repr(config).encode(), digest_size=20)
    for array in (cloud.points, cloud.normals):
        digest.update(np.ascontiguousarray(array).data)
    for view in views:
        digest.update(f"{view.name}{view.depth.shape}".encode())
        digest.update(np.ascontiguousarray(view.K, dtype=float).data)
        digest.update(np.ascontiguousarray(view.X_WC, dtype=float).data)
    return digest.digest()


@contextmanager
def _timed(result: PipelineResult, stage: str) -> Iterator[None]:
    """Add the wall and CPU time of the block to ``stage`` in ``result``."""
    start, cpu_start = time.perf_counter(), time.process_time()
    try:
        yield
    finally:
        result.timings[stage] += time.perf_counter() - start
        result.cpu_timings[stage] += time.process_time() - cpu_start


def config_for_scenario(scenario: Scenario) -> PipelineConfig:
    """Work region around the scenario's pile and reach hint from its build reach."""
    region = WorkRegion(
        center=(float(scenario.pile_center[0]), float(scenario.pile_center[1])),
        radius=scenario.pile_radius + PILE_MARGIN,
    )
    depth_range = scenario.cameras[0].depth_range if scenario.cameras else (0.1, 2.0)
    return PipelineConfig(
        region=region,
        depth_range=depth_range,
        scoring=GraspScoringConfig(reach=scenario.build_reach),
    )


def build_pipeline(
    scenario: Scenario,
    backend: str = "geometric",
    config: PipelineConfig | None = None,
    **backend_options: object,
) -> PerceptionPipeline:
    """A pipeline for ``scenario`` whose segmenter works in the same region and depth range."""
    config = config or config_for_scenario(scenario)
    segmenter = make_segmenter(backend, **backend_options)
    return PerceptionPipeline(segmenter, config)


def _aligned_pairs(fits: list[BoxFit]) -> list[tuple[int, int]]:
    """Index pairs of fits turned alike (10 degrees) whose centres lie one behind the other
    along the length (sideways and in depth within a few millimetres), nearest first."""
    if len(fits) < 2:
        return []
    centres = np.array([fit.X_WD[:3, 3] for fit in fits])
    pairs = []
    for first, second in cKDTree(centres).query_pairs(REJOIN_DISTANCE):
        rotation = fits[first].X_WD[:3, :3]
        if orientation_error(fits[second].X_WD[:3, :3], rotation) > np.radians(10.0):
            continue
        offset = np.abs(rotation.T @ (centres[second] - centres[first]))
        if offset[1] < REJOIN_SIDEWAYS and offset[2] < REJOIN_SIDEWAYS:
            pairs.append((float(offset[0]), first, second))
    return [(first, second) for _, first, second in sorted(pairs)]


def make_segmenter(
    backend: str,
    geometric: GeometricSegmenterConfig | None = None,
    sam_checkpoint: str = "",
    sam_model_type: str = "vit_b",
    sam_points_per_side: int = 32,
) -> Segmenter:
    """The backend named ``backend`` ('geometric' or 'sam')."""
    if backend == "geometric":
        return GeometricSegmenter(geometric)
    if backend == "sam":
        from dombot_perception.sam_segmentation import SamSegmenter, load_sam  # needs torch

        if not sam_checkpoint:
            raise SegmenterError("backend 'sam' needs a checkpoint path (sam_checkpoint)")
        return SamSegmenter(load_sam(sam_model_type, sam_checkpoint), sam_points_per_side)
    raise SegmenterError(f"unknown segmentation backend {backend!r}; choose one of {BACKENDS}")

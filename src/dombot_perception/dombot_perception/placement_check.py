"""Check a domino run against where its dominoes should stand (``/perception/check_placement``).

Each expected pose is a strong prior, so a standing domino is found by fitting the
known box to the points around its expected place *starting from the expected pose*
(the same point-to-plane ICP as ``box_fit``, with points shared between neighbouring
places handed to the nearest expected box), in each camera's points alone, the first
camera whose fit stands there taken (``_camera_fits``; camera_2, then camera_3 where the
arm hides the place from camera_2). Only the visible part of a domino is needed, which
matters in a run where neighbours hide each other's lower halves (from camera_3, looking
along some runs, more than half: ``min_height_hidden``). A
place where that local fit fails is looked up in the full pipeline's detections,
each detection going to at most one place, the one its foot stands on or fell from
(a fallen domino lies somewhere near); with no detection there either, the place is
MISSING when the cameras see almost nothing above the table there, FALLEN otherwise —
unless something in front hides most of the place from every camera (the arm, just
after placing a domino nearby): then NOT_SEEN, no evidence either way.

A place left FALLEN or MISSING without a pose is fitted once more from where a domino
that stood there must lie (``_tipped_fit``): tipped over an edge of its foot, forward or
back, leaning on the next (``lying_leans``) or flat, the box fitted from there to the
points no pose explains yet. A struck run lies shingled and the segmentation cuts a
domino into pieces no detection keeps: on struck arcs this located 40 of 40 toppled
dominoes instead of 24.

An expected pose that is not upright is a domino seen lying there before (the next
cycle's look at what a strike left, after something near it moved): refitted from that
pose, else from it turned about the vertical (``lying_turns``), FALLEN where it is found
within ``search_radius``; else NOT_SEEN when hidden, FALLEN without a pose while
something no pose explains lies on its footprint, else MISSING.

In hand (``PlacementConfig.in_hand``) the domino is checked before the fingers let go,
anywhere up to above its slot: the pads pinch its top (their lower edges ~29-31 mm above
its foot at the place grasp) and the gripper leans over it, so only its points lower than
``in_hand_fit_height`` above the expected foot are fitted and the fit must cover
``min_height_seen`` of that part only, in each camera's points alone (``_held``). What
the caller needs from it, the foot's horizontal position and the tilt, does not depend on
the hidden top. A place not fitted that way is NOT_SEEN (no evidence): the pipeline's
detections cannot tell a held domino from the pads around it.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np
from scipy.optimize import linear_sum_assignment
from scipy.spatial.transform import Rotation

from dombot_description import tilt_from_vertical, tipped_pose
from dombot_perception.backprojection import WorkRegion, organised_cloud
from dombot_perception.box_fit import BoxFitConfig, fit_statistics, refine_pose
from dombot_perception.depth_check import (
    DepthCheckConfig,
    correct_box,
    depth_evidence,
    silhouette,
)
from dombot_perception.domino_model import DOMINO_SIZE, HALF_SIZE, box_signed_distance
from dombot_perception.frames import CameraView, Detection
from dombot_perception.pipeline import PerceptionPipeline
from dombot_perception.side_by_side import (
    along_seam,
    is_flat,
    level_beside,
    on_its_side,
    pair_seeds,
    seam_across,
)

STANDING, FALLEN, MISSING, NOT_SEEN = 0, 1, 2, 3  # values of dombot_msgs/CheckPlacement
FLAT_HEIGHT_SPREAD = 0.005  # m: ends of the length axis this close in height both touch down


@dataclass(frozen=True)
class PlacementConfig:
    search_radius: float = 0.03  # m around the expected centre (horizontal)
    fit_margin: float = 0.01  # m around the expected box: the points fitted from its pose
    min_fit_height: float = 0.01  # m: the first fit ignores lower points (see _local_fit)
    min_points: int = 30  # on the fitted box (within inlier_distance) to call it there
    inlier_distance: float = 0.002  # m
    max_tilt: float = np.radians(15.0)  # body x from vertical: beyond this it has fallen
    region_margin: float = 0.06  # m around the run for the work region
    # of a domino's length the pipeline's detections must see (its FilterConfig.min_coverage
    # is the pile's 0.85): a struck run lies shingled and the segmentation cuts each face,
    # though seen whole, into pieces of about half its length; at 0.85 a struck 10-domino
    # arc had 1-3 of its 10 found. The depth check sets a box fitted to such a piece right
    min_lying_coverage: float = 0.45
    min_height_seen: float = 0.5  # of the domino's length, along its (vertical) length axis
    # m along its length: enough where the rest of the box is hidden behind something in
    # front (``_rest_hidden``): camera_3 looks along some runs, the neighbour in front
    # hiding the lower ~26 mm of a place (in hand, fits spanning 20-25 mm were within 0.21°)
    min_height_hidden: float = 0.020
    depth_check: DepthCheckConfig = field(default_factory=DepthCheckConfig)
    max_see_through: float = 0.2  # of the box's pixels the camera may see past
    max_hidden: float = 0.5  # of the box's pixels behind something in front: NOT_SEEN
    in_hand: bool = False  # still held at their top by the gripper: fit only below the pads
    in_hand_fit_height: float = 0.025  # m above the expected foot: highest point fitted in hand
    # m (_turn_support): less leaves the tilt unsure. On the planner's real S-curve slots
    # (camera_2) fits with 20-25 mm were within 0.21° and 1.1 mm; below 18 mm up to 4.4° off
    in_hand_min_turn_support: float = 0.020
    in_hand_iterations: int = 100  # of the box fit: a short visible part converges slowly
    # rad from vertical, where a place's domino is sought when nothing else located it
    # (``_tipped_fit``): a struck run's lean on the next (~75°), and flat (the last)
    lying_leans: tuple[float, ...] = (np.radians(75.0), np.radians(90.0))
    # rad about the vertical: a domino seen lying is refitted from its pose turned so too
    # when not found as it was (``_refit``)
    lying_turns: tuple[float, ...] = (np.radians(90.0),)

    @property
    def fitted_length(self) -> float:
        """How much of a standing domino's length can be fitted (from its foot up)."""
        return min(self.in_hand_fit_height, DOMINO_SIZE[0]) if self.in_hand else DOMINO_SIZE[0]


@dataclass
class Placement:
    status: int
    measured: np.ndarray  # 4x4; the expected pose when MISSING or NOT_SEEN
    position_error: float  # m, horizontal
    tilt: float  # rad, body x from vertical


def check_placements(
    expected: list[np.ndarray],
    views: list[CameraView],
    pipeline: PerceptionPipeline,
    config: PlacementConfig,
) -> list[Placement]:
    """What stands at each expected pose, seen through ``views``."""
    if not expected:
        return []
    region = _run_region(expected, pipeline.config.region, config)
    if config.in_hand:
        # held above its slot (the bring-up looks before the descent): the work region's
        # ceiling (the pile's height) would cut the part below the pads off
        ceiling = max(_foot_height(pose) for pose in expected) + config.in_hand_fit_height
        region = replace(region, max_height=max(region.max_height, ceiling + config.fit_margin))
    clouds = [organised_cloud(v, region, pipeline.config.depth_range) for v in views]
    seen = [np.zeros((0, 3)) if c is None else c.valid_points() for c in clouds]
    points = np.concatenate([np.zeros((0, 3)), *seen])
    camera = np.repeat(np.arange(len(seen)), [p.shape[0] for p in seen])  # index in views
    if config.in_hand:
        return [_held(pose, points, camera, views, config) for pose in expected]
    owner = _nearest_expected(points, expected)
    upright = [i for i, pose in enumerate(expected) if tilt_from_vertical(pose) <= config.max_tilt]
    detections: list[Detection] | None = None
    claimed: dict[int, int] = {}  # expected place -> the detection of its domino
    results = []
    for index, pose in enumerate(expected):
        if not any(_in_view(pose, view) for view in views):
            results.append(Placement(NOT_SEEN, pose, 0.0, 0.0))
            continue
        if index not in upright:  # seen lying there: refitted below (``_fit_unlocated``)
            results.append(Placement(MISSING, pose, 0.0, 0.0))
            continue
        near = _around_box(points, pose, config.fit_margin) & (owner == index)
        # the first camera's fit: ``views`` in order of preference
        fitted = next(_camera_fits(pose, points[near], camera[near], views, config), None)
        if fitted is not None:
            results.append(_placement(STANDING, fitted[0], pose))
            continue
        if detections is None:
            filtering = replace(pipeline.config.filtering, min_coverage=config.min_lying_coverage)
            local = replace(pipeline.config, region=region, filtering=filtering)
            detections = PerceptionPipeline(pipeline.segmenter, local).run(views).detections
            found = _claim(detections, [expected[i] for i in upright], config.search_radius)
            claimed = {upright[place]: k for place, k in found.items()}
        mine = detections[claimed[index]] if index in claimed else None
        if mine is None and _hidden(pose, views, config):
            results.append(Placement(NOT_SEEN, pose, 0.0, 0.0))
            continue
        results.append(_from_detections(pose, mine, detections, points, config))
    return _fit_unlocated(expected, results, points, views, config)


def _fit_unlocated(
    expected: list[np.ndarray],
    results: list[Placement],
    points: np.ndarray,
    views: list[CameraView],
    config: PlacementConfig,
) -> list[Placement]:
    """``results`` with each place left FALLEN or MISSING without a pose fitted in the
    points no pose explains (those of the places fitted so far, in order, left out): an
    upright place from where its domino must lie (``_tipped_fit``), a lying one from its
    pose (the domino seen there before, looked at again), else ``_unfitted``; one
    unfitted with something on its footprint then from its pose turned about the vertical
    by each of ``lying_turns`` (a pick or push nearby turns a lying domino, and the fit
    does not come round more than ~50°: one turned 60-120° was down but not fitted, an
    obstacle never picked), after every other place had its fit (a turned pose reaching
    over a neighbour would take its points)."""
    unlocated = [
        i
        for i, r in enumerate(results)
        if r.status in (FALLEN, MISSING) and r.measured is expected[i]
    ]
    if not unlocated:
        return results
    rest = points
    for pose, result in zip(expected, results, strict=True):
        if result.measured is not pose:  # a measured pose (else the expected one)
            rest = rest[~_on(result.measured, rest, config.inlier_distance)]
    for i in unlocated:
        pose = expected[i]
        if tilt_from_vertical(pose) <= config.max_tilt:
            fitted = _tipped_fit(pose, rest, views, config)
        else:
            fitted = _refit(pose, 0.0, rest, views, config)
            if fitted is None:
                results[i] = _unfitted(pose, rest, views, config)
        if fitted is not None:
            results[i] = _placement(FALLEN, fitted, pose)
            rest = rest[~_on(fitted, rest, config.inlier_distance)]
    for turn in config.lying_turns:
        for i in unlocated:
            pose, result = expected[i], results[i]
            if (
                result.status != FALLEN  # nothing there, or hidden
                or result.measured is not pose  # fitted
                or tilt_from_vertical(pose) <= config.max_tilt  # an upright place
            ):
                continue
            fitted = _refit(pose, turn, rest, views, config)
            if fitted is not None:
                results[i] = _placement(FALLEN, fitted, pose)
                rest = rest[~_on(fitted, rest, config.inlier_distance)]
    return results


def _refit(
    expected: np.ndarray,
    turn: float,
    points: np.ndarray,
    views: list[CameraView],
    config: PlacementConfig,
) -> np.ndarray | None:
    """The box of a domino seen lying at ``expected`` fitted to ``points`` from that pose
    turned ``turn`` rad about the vertical, when its centre is within ``search_radius``
    of ``expected``; else None."""
    seed = expected.copy()
    seed[:3, :3] = Rotation.from_rotvec([0.0, 0.0, turn]).as_matrix() @ expected[:3, :3]
    fitted, _ = _lying_fit(seed, points, views, config)
    if fitted is None or _horizontal(fitted, expected) > config.search_radius:
        return None
    return fitted


def _unfitted(
    expected: np.ndarray, points: np.ndarray, views: list[CameraView], config: PlacementConfig
) -> Placement:
    """A lying domino not found where it was seen: NOT_SEEN when most of it is hidden,
    FALLEN (pose unknown) while ``min_points`` of ``points`` lie on its footprint, else
    MISSING."""
    if _hidden(expected, views, config):
        return Placement(NOT_SEEN, expected, 0.0, 0.0)
    footprint = points[_near(points, expected, HALF_SIZE[1])].shape[0]
    return Placement(FALLEN if footprint >= config.min_points else MISSING, expected, 0.0, 0.0)


def _tipped_fit(
    expected: np.ndarray, points: np.ndarray, views: list[CameraView], config: PlacementConfig
) -> np.ndarray | None:
    """The box of a domino that stood at ``expected`` and fell, fitted to ``points`` from
    each of its ``tipped_pose``s (forward and back, each of ``lying_leans``): of the
    ``_lying_fit``s with their foot within ``search_radius`` of the place, the one with
    the most points on it."""
    best, best_count = None, 0
    for forward in (1.0, -1.0):
        for lean in config.lying_leans:
            pose, count = _lying_fit(tipped_pose(expected, lean, forward), points, views, config)
            if (
                pose is not None
                and count > best_count
                and _foot_distance(pose, expected) <= config.search_radius
            ):
                best, best_count = pose, count
    return best


def _lying_fit(
    seed: np.ndarray, points: np.ndarray, views: list[CameraView], config: PlacementConfig
) -> tuple[np.ndarray | None, int]:
    """``_lying_box`` from ``seed``, unless it lies flat with its face going on, level,
    past a long side (``side_by_side``: across two dominoes side by side, or straddling
    one and its neighbour, or beside one): then, with a seam on its face, the one of the
    dominoes either side of the seam with the most points on it, of those fitted along
    the seam with no seam on them; with none, where the dominoes lie is unknown and none
    is fitted (the pads would come down on the face beside it either way)."""
    pose, count = _lying_box(seed, points, views, config)
    if pose is None or not is_flat(pose):
        return pose, count
    if not level_beside(pose, points[_around_box(points, pose, config.fit_margin)]):
        return pose, count
    if (seam := seam_across(pose, views)) is None:
        return None, 0
    fits = [
        _lying_box(s, points[on_its_side(points, seam, s)], views, config)
        for s in pair_seeds(pose, seam)
    ]
    whole = [
        (p, n)
        for p, n in fits
        if p is not None and is_flat(p) and along_seam(p, seam) and not seam_across(p, views)
    ]
    return max(whole, key=lambda fit: fit[1], default=(None, 0))


def _lying_box(
    seed: np.ndarray, points: np.ndarray, views: list[CameraView], config: PlacementConfig
) -> tuple[np.ndarray | None, int]:
    """The box of a domino lying near ``seed`` fitted to the ``points`` around it, and how
    many of them lie on it: set right by the depth check (as the pipeline's detections
    are), with ``min_points`` on it spanning ``min_lying_coverage`` of its length, seen
    through on at most ``max_see_through`` of its pixels, and down (past ``max_tilt``);
    else None."""
    fit_config = BoxFitConfig()
    near = points[_around_box(points, seed, config.fit_margin)]
    if near.shape[0] < config.min_points:
        return None, 0
    pose = refine_pose(seed, near, fit_config)
    on = _on(pose, near, config.inlier_distance)
    if on.sum() < config.min_points:
        return None, 0
    pose = refine_pose(pose, near[on], fit_config)
    fit = fit_statistics(pose, near, _on(pose, near, config.inlier_distance))
    fit, evidence = correct_box(fit, near, views, config.depth_check, fit_config)
    on = _on(fit.X_WD, near, config.inlier_distance)
    lengthwise = (near[on] - fit.X_WD[:3, 3]) @ fit.X_WD[:3, 0]
    if (
        on.sum() < config.min_points
        or np.ptp(lengthwise) < config.min_lying_coverage * DOMINO_SIZE[0]
        or evidence.see_through_fraction > config.max_see_through
        or tilt_from_vertical(fit.X_WD) <= config.max_tilt
    ):
        return None, 0
    return fit.X_WD, int(on.sum())


def _on(pose: np.ndarray, points: np.ndarray, distance: float) -> np.ndarray:
    """Points within ``distance`` of the box at ``pose``'s surface."""
    return np.abs(box_signed_distance((points - pose[:3, 3]) @ pose[:3, :3])) < distance


def _held(
    expected: np.ndarray,
    points: np.ndarray,
    camera: np.ndarray,
    views: list[CameraView],
    config: PlacementConfig,
) -> Placement:
    """A domino still in the gripper, fitted in each camera's points below the pads alone
    (``_camera_fits``): the fit that pins its turn about the pinch axis best
    (``_turn_support``), else NOT_SEEN.

    Every camera, because the gripper leaning over the run's free side hides the domino
    from camera_2 at some slots where another camera sees it. No fit is no evidence
    (NOT_SEEN): the pipeline's detections cannot tell a held domino from the pads around
    it.
    """
    below_pads = points[:, 2] < _foot_height(expected) + config.in_hand_fit_height
    near = _around_box(points, expected, config.fit_margin) & below_pads
    fits = _camera_fits(expected, points[near], camera[near], views, config)
    best = max(fits, key=lambda fit: _turn_support(*fit), default=None)
    if best is None:
        return Placement(NOT_SEEN, expected, 0.0, 0.0)
    return _placement(STANDING, best[0], expected)


def _camera_fits(
    expected: np.ndarray,
    points: np.ndarray,
    camera: np.ndarray,
    views: list[CameraView],
    config: PlacementConfig,
) -> Iterator[tuple[np.ndarray, np.ndarray]]:
    """The box fitted from ``expected`` in each camera's ``points`` alone (``camera``: the
    index in ``views`` of each point's camera) and the points on it, for each camera
    whose image holds the expected centre and whose fit stands there (``_local_fit``,
    seen through by none of its own pixels), in the order of ``views``, each fitted when
    asked for.

    Each camera alone, because each camera's points carry their own ~0.6-0.9 mm offset,
    partly along its view direction: fused from two sides they twisted a held box by up
    to 2° at S-curve slots (each camera alone: within 0.2°), a standing one by up to 1°.
    """
    for index, view in enumerate(views):
        if not _in_view(expected, view):
            continue
        own = points[camera == index]
        fitted = _local_fit(expected, own, [view], config)
        if fitted is not None:
            yield fitted, own[_on(fitted, own, config.inlier_distance)]


def _claim(
    detections: list[Detection], expected: list[np.ndarray], radius: float
) -> dict[int, int]:
    """Expected place -> the detection that stood there: one each (Hungarian assignment).

    A domino tips over its bottom edge, so its foot (``_foot_distance``) stays at its
    place while its centre moves towards the next one: by centres, a run that toppled
    would be claimed one place too far. Pairs further apart than ``radius`` are no
    match.
    """
    if not detections:
        return {}
    cost = np.array([[_foot_distance(d.X_WD, pose) for d in detections] for pose in expected])
    places, found = linear_sum_assignment(np.where(cost <= radius, cost, 1e3))
    return {int(p): int(k) for p, k in zip(places, found, strict=True) if cost[p, k] <= radius}


def _foot_distance(pose: np.ndarray, expected: np.ndarray) -> float:
    """Horizontal distance from the expected place to the detected domino's foot: the
    lower end of its length axis, or the nearer end when it lies flat (a domino that
    tipped over lies with one end where it stood, its centre 28 mm further)."""
    ends = pose[:3, 3] + np.outer([-1.0, 1.0], pose[:3, 0]) * HALF_SIZE[0]
    low = ends[ends[:, 2] <= ends[:, 2].min() + FLAT_HEIGHT_SPREAD]
    return float(np.min(np.hypot(low[:, 0] - expected[0, 3], low[:, 1] - expected[1, 3])))


def _run_region(expected: list[np.ndarray], base: WorkRegion, config: PlacementConfig):
    centres = np.array([pose[:2, 3] for pose in expected])
    middle = centres.mean(axis=0)
    radius = float(np.max(np.linalg.norm(centres - middle, axis=1)))
    return replace(
        base,
        center=(float(middle[0]), float(middle[1])),
        radius=radius + config.search_radius + config.region_margin,
    )


def _in_view(pose: np.ndarray, view: CameraView) -> bool:
    local = (pose[:3, 3] - view.X_WC[:3, 3]) @ view.X_WC[:3, :3]
    if local[2] <= 0:
        return False
    u = local[0] / local[2] * view.K[0, 0] + view.K[0, 2]
    v = local[1] / local[2] * view.K[1, 1] + view.K[1, 2]
    height, width = view.depth.shape
    return 0 <= u < width and 0 <= v < height


def _nearest_expected(points: np.ndarray, expected: list[np.ndarray]) -> np.ndarray:
    """Index of the expected box each point lies closest to."""
    if points.shape[0] == 0:
        return np.zeros(0, dtype=int)
    distances = np.stack(
        [np.abs(box_signed_distance((points - p[:3, 3]) @ p[:3, :3])) for p in expected]
    )
    return distances.argmin(axis=0)


def _around_box(points: np.ndarray, pose: np.ndarray, margin: float) -> np.ndarray:
    """Points within ``margin`` of the box at ``pose`` (in each body direction)."""
    return np.all(np.abs((points - pose[:3, 3]) @ pose[:3, :3]) < HALF_SIZE + margin, axis=1)


def _foot_height(pose: np.ndarray) -> float:
    """Height of the lower end of the box's length axis."""
    return float(pose[2, 3] - abs(pose[2, 0]) * HALF_SIZE[0])


def _near(points: np.ndarray, pose: np.ndarray, radius: float) -> np.ndarray:
    return np.hypot(points[:, 0] - pose[0, 3], points[:, 1] - pose[1, 3]) < radius


def _local_fit(
    expected: np.ndarray, points: np.ndarray, views: list[CameraView], config: PlacementConfig
) -> np.ndarray | None:
    """The box fitted from the expected pose, if it stands there: enough points on it,
    spread over most of its height that can be fitted (``fitted_length``), or over
    ``min_height_hidden`` where the rest of it is hidden (``_rest_hidden``), and no
    camera seeing through it.

    In hand, the ~20 mm below the pads are all there is to fit: the fit runs longer (with
    15 steps a turn in the hand came out 2-6° short) and must pin the turn about the
    pinch axis (``_turn_support``; a camera looking at the domino's narrow side sees
    little of that turn and the fit stays near the expected upright pose).

    The first fit uses only points higher than a lying domino: one that fell and lies
    at this domino's foot would otherwise pull its bottom aside and tilt the box.

    In hand the fit also starts a thickness either side of the expected pose when the
    one from it fails: the points of the one face a camera sees fit a box on either side
    of that face, and a hold a few mm off through its thickness (a 6° turn about the
    pinch axis moves the foot ~4 mm) drew the box from the expected pose onto the far
    side, which the depth check rightly saw through (s_curve30 slot 10: NOT_SEEN though
    camera_3 saw 175 points of it, issue 23).
    """
    high = points[points[:, 2] > config.min_fit_height]
    if high.shape[0] < config.min_points:
        return None
    fit_config = BoxFitConfig()
    starts = [expected]
    if config.in_hand:
        fit_config = replace(fit_config, iterations=config.in_hand_iterations)
        for side in (1.0, -1.0):
            start = expected.copy()
            start[:3, 3] += side * DOMINO_SIZE[2] * expected[:3, 2]
            starts.append(start)
    for start in starts:
        pose = _fit_from(start, expected, points, high, views, config, fit_config)
        if pose is not None:
            return pose
    return None


def _fit_from(
    start: np.ndarray,
    expected: np.ndarray,
    points: np.ndarray,
    high: np.ndarray,
    views: list[CameraView],
    config: PlacementConfig,
    fit_config: BoxFitConfig,
) -> np.ndarray | None:
    """``_local_fit``'s box fitted from ``start``, if it stands at ``expected``."""
    pose = refine_pose(start, high, fit_config)
    on_box = np.abs(box_signed_distance((points - pose[:3, 3]) @ pose[:3, :3]))
    inliers = on_box < config.inlier_distance
    if inliers.sum() < config.min_points:
        return None
    pose = refine_pose(pose, points[inliers], fit_config)
    if config.in_hand and _turn_support(pose, points[inliers]) < config.in_hand_min_turn_support:
        return None
    lengthwise = (points[inliers] - pose[:3, 3]) @ pose[:3, 0]
    span = np.ptp(lengthwise)
    if (
        tilt_from_vertical(pose) > config.max_tilt
        or _horizontal(pose, expected) > config.search_radius
        or span < min(config.min_height_hidden, config.min_height_seen * config.fitted_length)
        or depth_evidence(pose, views, config.depth_check).see_through_fraction
        > config.max_see_through
    ):
        return None
    if span < config.min_height_seen * config.fitted_length and not _rest_hidden(
        pose, lengthwise, views, config
    ):
        return None
    return pose


def _rest_hidden(
    pose: np.ndarray, lengthwise: np.ndarray, views: list[CameraView], config: PlacementConfig
) -> bool:
    """Most of the box's pixels (with a depth return) beyond the span of its points
    along its length (``lengthwise``) see something in front of it: the points are what
    there is to see of it. camera_3 looks along some runs from 45° above: the neighbour in
    front hides the lower ~26 mm of a place (of a circle of 30, the domino at place 12
    alone was called fallen by camera_3, its top 22.6 mm fitted within 0.02°)."""
    occluded = known = 0
    for view in views:
        seen = silhouette(pose, view)
        if seen is None:
            continue
        along = (seen.entry - pose[:3, 3]) @ pose[:3, 0]
        rest = (along < lengthwise.min()) | (along > lengthwise.max())
        with np.errstate(invalid="ignore"):
            difference = seen.measured[rest] - seen.predicted[rest]  # NaN: no return
            occluded += np.count_nonzero(difference < -config.depth_check.support_tolerance)
        known += np.count_nonzero(np.isfinite(difference))
    return known > 0 and occluded > config.max_hidden * known


def _turn_support(pose: np.ndarray, points: np.ndarray) -> float:
    """How firmly ``points`` on the box at ``pose`` pin its turn about its width (y) axis,
    the pinch axis of a held domino [m]: the square root of the information their
    point-to-face distances carry about that turn, the other five degrees of freedom left
    free. A turn of δ rad moves the points δ·support off their faces in root-sum-square,
    so with point errors of σ the turn is known to ~σ/support rad.
    """
    body = (points - pose[:3, 3]) @ pose[:3, :3]
    axis = np.argmax(np.abs(body) - HALF_SIZE, axis=1)
    rows = np.arange(body.shape[0])
    normal = np.zeros_like(body)
    normal[rows, axis] = np.sign(body[rows, axis])
    jacobian = np.hstack([np.cross(body, normal), normal])  # d(distance)/d(turn, shift)
    information = jacobian.T @ jacobian
    free = [0, 2, 3, 4, 5]
    coupled = information[1, free]
    rest = np.linalg.pinv(information[np.ix_(free, free)], rcond=1e-9)
    return float(np.sqrt(max(information[1, 1] - coupled @ rest @ coupled, 0.0)))


def _hidden(expected: np.ndarray, views: list[CameraView], config: PlacementConfig) -> bool:
    """Most of the expected box's pixels see something in front of it: a domino may stand
    there unseen (a standing neighbour in front hides at most its lower fifth)."""
    return depth_evidence(expected, views, config.depth_check).hidden_fraction > config.max_hidden


def _from_detections(
    expected: np.ndarray,
    mine: Detection | None,
    detections: list[Detection],
    points: np.ndarray,
    config: PlacementConfig,
) -> Placement:
    """From the pipeline: the detection of this place's domino, else what its points say.

    Points on any detected box are explained; unexplained points on the place's
    footprint mean something lies there that no box fits (FALLEN, pose unknown).
    """
    if mine is not None:
        status = STANDING if tilt_from_vertical(mine.X_WD) <= config.max_tilt else FALLEN
        return _placement(status, mine.X_WD, expected)
    footprint = points[_near(points, expected, HALF_SIZE[1])]
    for detection in detections:
        local = (footprint - detection.X_WD[:3, 3]) @ detection.X_WD[:3, :3]
        footprint = footprint[np.abs(box_signed_distance(local)) > config.inlier_distance]
    if footprint.shape[0] < config.min_points:
        return Placement(MISSING, expected, 0.0, 0.0)
    return Placement(FALLEN, expected, 0.0, 0.0)


def _placement(status: int, measured: np.ndarray, expected: np.ndarray) -> Placement:
    return Placement(
        status, measured, _horizontal(measured, expected), tilt_from_vertical(measured)
    )


def _horizontal(pose: np.ndarray, expected: np.ndarray) -> float:
    return float(np.hypot(pose[0, 3] - expected[0, 3], pose[1, 3] - expected[1, 3]))

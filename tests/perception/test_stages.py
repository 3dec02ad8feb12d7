"""Each pipeline stage on synthetic data with a known answer (no rendering, no ROS)."""

from __future__ import annotations

import math

import numpy as np
import pytest
from pydrake.math import RigidTransform
from scipy.spatial import ConvexHull
from scipy.spatial.transform import Rotation

from dombot_description.grasp import pick_grasps
from dombot_perception.backprojection import WorkRegion, backproject, image_normals
from dombot_perception.box_fit import (
    BoxFitConfig,
    BoxFitError,
    fit_domino_box,
    fit_statistics,
    initial_pose,
    initial_poses,
    min_area_rectangle,
    min_area_rectangles,
    refine_pose,
)
from dombot_perception.canonical import canonical_rotation, posture
from dombot_perception.domino_model import (
    DOMINO_SIZE,
    HALF_SIZE,
    SYMMETRIES,
    box_signed_distance,
    orientation_error,
    overlap_fraction,
)
from dombot_perception.filtering import FilterConfig, rejection_reason, remove_outliers
from dombot_perception.frames import (
    POSTURE_FLAT,
    POSTURE_TILTED,
    POSTURE_UPRIGHT,
    CameraView,
    Detection,
)
from dombot_perception.fusion import FusionConfig, MaskCloud, fuse
from dombot_perception.grasp_scoring import (
    FREE_SPACE,
    NEIGHBOURHOOD,
    VERTICAL,
    GraspScoringConfig,
    feasible_grasps,
    predicted_success,
    score_detections,
    weighted_geometric_mean,
)
from dombot_perception.pipeline import PerceptionPipeline, unexplained_points
from support.perception_scenes import PILE_CENTRE, domino_pose, flat

RNG_SEED = 11


def visible_surface(pose: np.ndarray, camera: np.ndarray, spacing: float = 0.001):
    """Points and outward normals of the box faces that face ``camera`` (a camera's view)."""
    points, normals = [], []
    for axis in range(3):
        for sign in (-1.0, 1.0):
            normal_body = np.zeros(3)
            normal_body[axis] = sign
            normal = pose[:3, :3] @ normal_body
            centre = pose[:3, 3] + normal * HALF_SIZE[axis]
            if normal @ (camera - centre) <= 0:
                continue
            others = [a for a in range(3) if a != axis]
            grids = [np.arange(-HALF_SIZE[a], HALF_SIZE[a] + 1e-9, spacing) for a in others]
            u, v = np.meshgrid(*grids, indexing="ij")
            local = np.zeros((u.size, 3))
            local[:, others[0]], local[:, others[1]] = u.ravel(), v.ravel()
            local[:, axis] = sign * HALF_SIZE[axis]
            points.append(local @ pose[:3, :3].T + pose[:3, 3])
            normals.append(np.repeat(normal[None], u.size, axis=0))
    return np.concatenate(points), np.concatenate(normals)


CAMERA = np.array([0.55, -0.72, 0.50])  # camera_0's position in the default scenario


def test_backprojection_follows_the_pinhole_equations() -> None:
    intrinsics = np.array([[500.0, 0, 320], [0, 510.0, 240], [0, 0, 1]])
    pose = np.eye(4)
    pose[:3, 3] = [1.0, 2.0, 3.0]
    depth = np.full((480, 640), 2.0, dtype=np.float32)
    depth[0, 0] = np.nan
    points = backproject(depth, intrinsics, pose)
    assert np.allclose(points[100, 400], [1 + 2.0 * 80 / 500, 2 + 2.0 * -140 / 510, 5.0])
    assert np.all(np.isnan(points[0, 0]))
    normals = image_normals(points, camera_position=np.array([1.0, 2.0, 3.0]))
    assert np.allclose(normals[100, 400], [0, 0, -1])  # plane faces the camera


def test_work_region_keeps_only_the_cylinder_above_the_table() -> None:
    region = WorkRegion(center=(0.0, 0.0), radius=0.1, min_height=0.001, max_height=0.05)
    points = np.array([[0.0, 0.0, 0.01], [0.2, 0.0, 0.01], [0.0, 0.0, 0.0], [0, 0, 0.06]])
    assert region.contains(points).tolist() == [True, False, False, False]


def test_box_distance_is_signed() -> None:
    points = np.array([[0, 0, 0], [0.024, 0, 0], [0.03, 0, 0]])
    assert np.allclose(box_signed_distance(points), [-HALF_SIZE[2], 0.0, 0.006])


@pytest.mark.parametrize(
    "rotation",
    [
        Rotation.from_euler("z", 0.7).as_matrix(),  # flat
        Rotation.from_euler("xz", [0.4, 1.9]).as_matrix(),  # tilted
        Rotation.from_euler("yz", [np.pi / 2, 0.3]).as_matrix(),  # upright
    ],
    ids=["flat", "tilted", "upright"],
)
def test_box_fit_recovers_a_pose_from_the_visible_faces_only(rotation) -> None:
    truth = domino_pose((0.55, -0.30, 0.03), rotation)
    points, normals = visible_surface(truth, CAMERA)
    rng = np.random.default_rng(RNG_SEED)
    noisy = points + rng.normal(0.0, 0.0003, points.shape)
    fit = fit_domino_box(noisy, normals, BoxFitConfig())
    assert np.linalg.norm(fit.X_WD[:3, 3] - truth[:3, 3]) < 0.0005
    assert orientation_error(fit.X_WD[:3, :3], truth[:3, :3]) < np.radians(0.5)
    assert fit.fit_error < 0.0006 and fit.inlier_fraction > 0.95


def test_box_fit_trims_a_neighbours_stray_points() -> None:
    truth = flat(0.55, -0.30, 0.2)
    points, normals = visible_surface(truth, CAMERA)
    stray = points[:150] + np.array([0.0, 0.0, 0.02])  # a patch of something 2 cm above
    fit = fit_domino_box(
        np.vstack([points, stray]), np.vstack([normals, normals[:150]]), BoxFitConfig()
    )
    assert np.linalg.norm(fit.X_WD[:3, 3] - truth[:3, 3]) < 0.0005
    assert fit.inlier_fraction < 0.95


def test_min_area_rectangle_of_a_turned_rectangle() -> None:
    rng = np.random.default_rng(RNG_SEED)
    local = rng.uniform([-0.024, -0.012], [0.024, 0.012], size=(500, 2))
    angle = 0.5
    turn = np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])
    centre, direction, sides = min_area_rectangle(local @ turn.T + [0.1, 0.2])
    assert np.allclose(sides, [0.048, 0.024], atol=0.001)
    assert abs(abs(direction @ turn[:, 0]) - 1) < 1e-3
    assert np.allclose(centre, [0.1, 0.2], atol=0.001)


def test_rectangles_of_many_point_sets_at_once_are_each_sets_own() -> None:
    """The batch pads the hulls to one size; each set still gets the rectangle over the
    edges of its own hull (checked against every edge direction of a dense hull), and a
    set with no area an error of its own."""
    rng = np.random.default_rng(RNG_SEED)
    disc = rng.uniform(-0.02, 0.02, size=(500, 2))
    sets = [
        rng.uniform([-0.024, -0.012], [0.024, 0.012], size=(300, 2)) @ _turn(0.5).T,
        disc[np.hypot(*disc.T) < 0.02] + [0.3, -0.1],
        np.column_stack([np.linspace(0, 0.01, 40), 0.5 * np.linspace(0, 0.01, 40)]),  # a line
        rng.uniform([-0.01, -0.003], [0.01, 0.003], size=(12, 2)) @ _turn(-1.2).T,
    ]
    batched = min_area_rectangles(sets)
    assert isinstance(batched[2], BoxFitError)
    with pytest.raises(BoxFitError):
        min_area_rectangle(sets[2])
    for points, rectangle in zip(sets, batched, strict=True):
        if isinstance(rectangle, BoxFitError):
            continue
        for got, alone in zip(rectangle, min_area_rectangle(points), strict=True):
            assert np.array_equal(got, alone)
        hull = points[ConvexHull(points).vertices]
        areas = []
        for edge in np.roll(hull, -1, axis=0) - hull:
            along = hull @ edge / np.linalg.norm(edge)
            across = hull @ np.array([-edge[1], edge[0]]) / np.linalg.norm(edge)
            areas.append(np.ptp(along) * np.ptp(across))
        assert np.isclose(np.prod(rectangle[2]), min(areas), rtol=1e-12, atol=0.0)


def test_initial_poses_of_many_clouds_at_once_are_each_clouds_own() -> None:
    """To the last bit: the ICP's pairing of points to faces magnifies any change."""
    clouds = [
        visible_surface(domino_pose((0.55, -0.30, 0.03), rotation), CAMERA)
        for rotation in (
            Rotation.from_euler("z", 0.7).as_matrix(),
            Rotation.from_euler("xz", [0.4, 1.9]).as_matrix(),
            Rotation.from_euler("yz", [np.pi / 2, 0.3]).as_matrix(),
        )
    ]
    points, normals = clouds[0]
    clouds.append((points[:30], normals[:30]))  # a few points of one face
    config = BoxFitConfig()
    for (points, normals), pose in zip(clouds, initial_poses(clouds, config), strict=True):
        assert np.array_equal(pose, initial_pose(points, normals, config))


def _turn(angle: float) -> np.ndarray:
    return np.array([[np.cos(angle), -np.sin(angle)], [np.sin(angle), np.cos(angle)]])


def _reference_icp_step(pose: np.ndarray, points: np.ndarray, config: BoxFitConfig):
    """One damped, Huber-weighted Gauss-Newton step on the point-to-face distances, written
    plainly: the signed face normal, np.cross, np.linalg.solve, scipy's rotation vector."""
    body = (points - pose[:3, 3]) @ pose[:3, :3]
    axis = np.argmax(np.abs(body) - HALF_SIZE, axis=1)
    signed = body[np.arange(len(body)), axis]
    normal = np.eye(3)[axis] * np.sign(signed)[:, None]
    residual = np.abs(signed) - HALF_SIZE[axis]
    jacobian = np.hstack([np.cross(normal, body), -normal])
    weight = np.minimum(1.0, config.loss_scale / np.abs(residual))
    hessian = jacobian.T @ (weight[:, None] * jacobian)
    hessian += config.damping * np.trace(hessian) / 6.0 * np.eye(6)
    step = np.linalg.solve(hessian, -jacobian.T @ (weight * residual))
    stepped = np.eye(4)
    stepped[:3, :3] = pose[:3, :3] @ Rotation.from_rotvec(step[:3]).as_matrix()
    stepped[:3, 3] = pose[:3, 3] + pose[:3, :3] @ step[3:]
    return stepped


def test_icp_step_is_the_plain_gauss_newton_step() -> None:
    turn = Rotation.from_euler("xyz", [0.3, -0.2, 1.1]).as_matrix()
    truth = domino_pose((0.55, -0.30, 0.03), turn)
    points, _ = visible_surface(truth, CAMERA)
    start = truth.copy()
    start[:3, :3] = Rotation.from_rotvec([0.03, -0.02, 0.05]).as_matrix() @ truth[:3, :3]
    start[:3, 3] += [0.002, -0.001, 0.001]
    config = BoxFitConfig(iterations=1)
    assert not np.allclose(refine_pose(start, points, config), start, atol=1e-4)
    assert np.allclose(
        refine_pose(start, points, config), _reference_icp_step(start, points, config), atol=1e-12
    )


def test_canonical_rotation_picks_one_of_the_four_equivalents() -> None:
    position = np.array([0.55, -0.30, 0.0])
    for rotation in (
        Rotation.from_euler("z", 2.5).as_matrix(),
        Rotation.from_euler("yz", [np.pi / 2, 1.0]).as_matrix(),
        Rotation.from_euler("xz", [np.pi / 2, -2.0]).as_matrix(),
        Rotation.from_euler("xyz", [0.5, 0.3, 0.2]).as_matrix(),
    ):
        chosen = {
            tuple(np.round(canonical_rotation(rotation @ s, position), 9).ravel())
            for s in SYMMETRIES
        }
        assert len(chosen) == 1
        canonical = canonical_rotation(rotation, position)
        up_axis = int(np.argmax(np.abs(canonical[2])))
        reference = 2 if up_axis == 0 else 0
        assert canonical[2, up_axis] > 0
        assert canonical[:, reference] @ [position[0], position[1], 0] >= 0
        assert np.isclose(np.linalg.det(canonical), 1.0)


def test_posture_from_the_most_vertical_axis() -> None:
    assert posture(np.eye(3)) == POSTURE_FLAT
    assert posture(Rotation.from_euler("y", 90, degrees=True).as_matrix()) == POSTURE_UPRIGHT
    assert posture(Rotation.from_euler("x", 40, degrees=True).as_matrix()) == POSTURE_TILTED


def test_orientation_error_ignores_the_box_symmetries() -> None:
    rotation = Rotation.from_euler("xyz", [0.3, 0.2, 1.0]).as_matrix()
    for symmetry in SYMMETRIES:
        assert orientation_error(rotation @ symmetry, rotation) < 1e-6
    turned = rotation @ Rotation.from_euler("z", 5, degrees=True).as_matrix()
    assert np.isclose(np.degrees(orientation_error(turned, rotation)), 5.0)


def test_overlap_fraction_of_touching_and_crossing_boxes() -> None:
    base = flat(*PILE_CENTRE, yaw=0.2)
    assert np.isclose(overlap_fraction(base, base), 1.0)
    beside = base.copy()  # side by side, 0.5 mm into each other (pose error)
    beside[:3, 3] += base[:3, 1] * (DOMINO_SIZE[1] - 0.0005)
    assert overlap_fraction(beside, base, margin=0.001) == 0.0
    beside[:3, 3] -= base[:3, 1] * 0.004  # 4.5 mm into each other
    assert 0.1 < overlap_fraction(beside, base, margin=0.001) < 0.2
    crossing = flat(*PILE_CENTRE, yaw=0.2 + np.pi / 2)  # turned a quarter on the same place
    crossing[:3, 3] += base[:3, 0] * 0.012
    assert 0.3 < overlap_fraction(crossing, base, margin=0.001) <= 0.5


def test_of_two_interpenetrating_boxes_the_better_supported_stays() -> None:
    base = flat(*PILE_CENTRE, yaw=0.2)
    crossing = flat(*PILE_CENTRE, yaw=0.2 + np.pi / 2)  # across parts of two dominoes
    crossing[:3, 3] += base[:3, 0] * 0.015
    stacked = base.copy()  # on top of the first, half a length along, touching it
    stacked[:3, 3] += base[:3, 0] * 0.024 + np.array([0.0, 0.0, DOMINO_SIZE[2] - 0.0005])
    apart = flat(PILE_CENTRE[0] + 0.1, PILE_CENTRE[1], yaw=0.0)
    detections = [_detection(base), _detection(crossing), _detection(stacked), _detection(apart)]
    detections[1].num_points = 300
    rejected: list[str] = []
    kept = PerceptionPipeline(None)._merge_duplicates(detections, rejected)  # type: ignore[arg-type]
    assert [d.X_WD[0, 3] for d in kept] == [base[0, 3], stacked[0, 3], apart[0, 3]]
    assert len(rejected) == 1 and "inside the box at" in rejected[0]


def test_fusion_merges_the_same_domino_seen_by_two_cameras_only() -> None:
    a_points, a_normals = visible_surface(flat(0.50, -0.30, 0.0), CAMERA)
    b_points, b_normals = visible_surface(flat(0.60, -0.30, 0.0), CAMERA)
    shifted = np.array([0.0003, 0.0, 0.0])  # the second camera samples other surface points
    masks = [
        MaskCloud("camera_0", np.arange(len(a_points)), a_points, a_normals),
        MaskCloud("camera_0", np.arange(len(b_points)), b_points, b_normals),
        MaskCloud("camera_1", np.arange(len(a_points)), a_points + shifted, a_normals),
        MaskCloud("camera_1", np.arange(len(b_points)), b_points + shifted, b_normals),
    ]
    fused = fuse(masks, FusionConfig())
    assert sorted(len(cloud.parts) for cloud in fused) == [2, 2]
    assert all(cloud.cameras == ("camera_0", "camera_1") for cloud in fused)


def test_fusion_does_not_glue_two_masks_through_a_merged_one() -> None:
    a_points, a_normals = visible_surface(flat(0.55, -0.312, 0.0), CAMERA)
    b_points, b_normals = visible_surface(flat(0.55, -0.288, 0.0), CAMERA)
    both = np.vstack([a_points, b_points])
    masks = [
        MaskCloud("camera_0", np.arange(len(both)), both, np.vstack([a_normals, b_normals])),
        MaskCloud("camera_1", np.arange(len(a_points)), a_points, a_normals),
        MaskCloud("camera_1", np.arange(len(b_points)), b_points, b_normals),
    ]
    assert len(fuse(masks, FusionConfig())) == 2


def test_radius_outlier_removal_drops_isolated_points() -> None:
    points, _ = visible_surface(flat(0.55, -0.30, 0.0), CAMERA)
    lonely = np.array([[0.7, -0.3, 0.05]])
    kept = remove_outliers(np.vstack([points, lonely]), FilterConfig())
    assert kept.size == len(points) and len(points) not in kept


def test_outlier_removal_keeps_what_open3d_keeps() -> None:
    """A sparse cloud, where many points have about six neighbours within 3 mm: the same
    points as open3d's remove_radius_outlier (which the pipeline used before)."""
    import open3d as o3d

    rng = np.random.default_rng(RNG_SEED)
    points = rng.uniform([0.5, -0.3, 0.0], [0.53, -0.27, 0.01], size=(800, 3))
    config = FilterConfig()
    cloud = o3d.geometry.PointCloud(o3d.utility.Vector3dVector(points))
    _, kept = cloud.remove_radius_outlier(config.outlier_min_neighbours, config.outlier_radius)
    ours = remove_outliers(points, config)
    assert 0 < ours.size < len(points)
    assert np.array_equal(ours, np.asarray(kept))
    assert remove_outliers(np.zeros((0, 3)), config).size == 0


def test_filter_rejects_boxes_that_cannot_be_one_well_seen_domino() -> None:
    points, normals = visible_surface(flat(0.55, -0.30, 0.0), CAMERA)
    config = FilterConfig()
    good = fit_domino_box(points, normals, BoxFitConfig())
    assert rejection_reason(good, len(points), config) is None
    assert "points" in rejection_reason(good, 10, config)
    half = points[:, 0] < 0.55
    partial = fit_domino_box(points[half], normals[half], BoxFitConfig())
    assert "of its length" in rejection_reason(partial, int(half.sum()), config)


def _detection(pose: np.ndarray) -> Detection:
    return Detection(pose, DOMINO_SIZE.copy(), POSTURE_FLAT, 0.0, 500, ("camera_0",))


def test_a_neighbour_beside_the_long_face_blocks_the_fingers() -> None:
    alone = flat(*PILE_CENTRE, yaw=0.3)
    crowded = flat(PILE_CENTRE[0] + 0.1, PILE_CENTRE[1], yaw=0.3)
    rotation = crowded[:3, :3]
    neighbours = [crowded.copy(), crowded.copy()]
    for neighbour, side in zip(neighbours, (1.0, -1.0), strict=True):
        neighbour[:3, 3] += rotation @ np.array([0.0, side * 0.027, 0.0])  # 3 mm gaps
    scene = np.vstack([visible_surface(p, CAMERA)[0] for p in (alone, crowded, *neighbours)])
    config = GraspScoringConfig()
    ranked = score_detections([_detection(crowded), _detection(alone)], scene, config)
    assert np.allclose(ranked[0].X_WD, alone)
    assert ranked[0].clearance > 0.01 and predicted_success(ranked[0], config)
    assert ranked[1].clearance < config.min_clearance
    assert not predicted_success(ranked[1], config)
    assert ranked[1].score < 0.5 * ranked[0].score


def test_a_domino_tucked_in_the_fingers_gap_blocks_their_close() -> None:
    """Seen points 4 mm beside a long face (a domino on its edge, undetected): clear of
    the open pads, but in their stroke as they close (arc seed 6 missed so, twice)."""
    pose = flat(*PILE_CENTRE, yaw=0.3)
    x, z = np.meshgrid(np.arange(-0.022, 0.0221, 0.001), np.arange(-0.003, 0.0031, 0.001))
    gap = np.stack([x.ravel(), np.full(x.size, HALF_SIZE[1] + 0.004), z.ravel()], axis=1)
    tucked = gap @ pose[:3, :3].T + pose[:3, 3]
    config = GraspScoringConfig()
    (detection,) = score_detections(
        [_detection(pose)], np.vstack([visible_surface(pose, CAMERA)[0], tucked]), config
    )
    assert detection.clearance < 0.0
    assert detection.score == 0.0 and not predicted_success(detection, config)
    (alone,) = score_detections([_detection(pose)], visible_surface(pose, CAMERA)[0], config)
    assert alone.score > 0.5 and predicted_success(alone, config)


def _straightforward_choice(pose: np.ndarray, scene: np.ndarray, config: GraspScoringConfig):
    """The grasp scoring's choice measured the plain way: every pad-path box against every
    obstacle point, each grasp on its own; the first that clears, else the clearest (the
    first of a finger-swapped twin, whose pads pass through the same space); none from
    above the table: -1."""
    nearby = scene[np.linalg.norm(scene - pose[:3, 3], axis=1) <= NEIGHBOURHOOD]
    own = box_signed_distance((nearby - pose[:3, 3]) @ pose[:3, :3]) <= config.own_surface
    obstacles = nearby[~own]
    candidates = pick_grasps(RigidTransform(pose), base_xy=config.base_xy)
    grasps = feasible_grasps(candidates, config)
    if not grasps:
        return candidates[0], -1.0
    clearances = [
        min(
            FREE_SPACE,
            *(
                float(box.signed_distance(obstacles).min())
                for box in grasp.pad_paths(config.approach_distance, VERTICAL)
            ),
        )
        for grasp in grasps
    ]
    clear = [k for k, c in enumerate(clearances) if c >= config.min_clearance]
    best = (
        clear[0]
        if clear
        else min(k for k, c in enumerate(clearances) if c >= max(clearances) - 1e-12)
    )
    return grasps[best], clearances[best]


def test_scoring_measures_clearances_as_the_straightforward_way_does() -> None:
    """A crowded, seeded patch of dominoes (some touching, some clear, some tilted onto a
    neighbour): the pruned clearances are the plain ones to the last bit, same grasps."""
    rng = np.random.default_rng(RNG_SEED)
    poses = []
    for row in range(3):
        for col in range(3):
            x = PILE_CENTRE[0] + 0.032 * col + rng.uniform(-0.004, 0.004)
            y = PILE_CENTRE[1] + 0.05 * row + rng.uniform(-0.004, 0.004)
            tilt = Rotation.from_euler("zx", [rng.uniform(-0.5, 0.5), rng.uniform(-0.2, 0.2)])
            poses.append(domino_pose((x, y, 0.006 + 0.004 * (row == 1)), tilt.as_matrix()))
    scene = np.vstack([visible_surface(pose, CAMERA, spacing=0.002)[0] for pose in poses])
    config = GraspScoringConfig()
    detections = score_detections([_detection(pose) for pose in poses], scene, config)
    clearances = []
    for detection in detections:
        grasp, clearance = _straightforward_choice(detection.X_WD, scene, config)
        assert detection.clearance == clearance
        assert np.array_equal(detection.grasp_pose, grasp.pose.GetAsMatrix4())
        clearances.append(clearance)
    assert min(clearances) < 0.0 < config.min_clearance < max(clearances)  # both kinds


def test_points_on_no_detected_domino_are_unexplained() -> None:
    """What a planner has no box for: the points of a domino perception did not detect,
    not those within the margin of a detected one (its pose is off by ~1 mm)."""
    seen = flat(*PILE_CENTRE, yaw=0.3)
    missed = flat(PILE_CENTRE[0] + 0.1, PILE_CENTRE[1], yaw=-0.5)
    detected = seen.copy()
    detected[:3, 3] += [0.001, 0.0, 0.0]
    points_seen = visible_surface(seen, CAMERA)[0]
    points_missed = visible_surface(missed, CAMERA)[0]
    left = unexplained_points(
        np.vstack([points_seen, points_missed]), [_detection(detected)], margin=0.003
    )
    assert left.shape == points_missed.shape and np.array_equal(left, points_missed)


def test_flatness_alone_would_pick_the_blocked_domino() -> None:
    """The paper's rule ranks by flatness only; a blocked flat domino must lose to a
    slightly tilted free one under our score."""
    free = domino_pose((0.50, -0.30, 0.012), Rotation.from_euler("xz", [0.15, 0.3]).as_matrix())
    blocked = flat(0.60, -0.30, 0.3)
    wall = blocked.copy()
    wall[:3, 3] += blocked[:3, :3] @ np.array([0.0, 0.026, 0.0])
    scene = np.vstack([visible_surface(p, CAMERA)[0] for p in (free, blocked, wall)])
    ranked = score_detections([_detection(blocked), _detection(free)], scene, GraspScoringConfig())
    assert abs(blocked[2, 2]) > abs(free[2, 2])
    assert np.allclose(ranked[0].X_WD, free)


def test_weighted_geometric_mean_is_zero_when_any_term_is() -> None:
    weights = {"a": 1.0, "b": 2.0}
    assert weighted_geometric_mean({"a": 1.0, "b": 0.0}, weights) == 0.0
    assert np.isclose(weighted_geometric_mean({"a": 0.25, "b": 1.0}, weights), 0.25 ** (1 / 3))


def test_camera_view_check_names_the_problem() -> None:
    rgb = np.zeros((4, 4, 3), np.uint8)
    depth = np.ones((4, 4), np.float32)
    bad_pose = np.eye(4)
    bad_pose[0, 0] = 2.0
    assert "orthonormal" in CameraView("c", rgb, depth, np.eye(3), bad_pose).check()
    assert "differ" in CameraView("c", rgb, depth[:2], np.eye(3), np.eye(4)).check()
    assert CameraView("c", rgb, depth, np.eye(3), np.eye(4)).check() is None


def test_height_only_ranks_free_dominoes() -> None:
    low = flat(0.50, -0.30, 0.3)
    high = flat(0.60, -0.30, 0.3)
    high[2, 3] += 0.02  # resting on something 2 cm up
    scene = np.vstack([visible_surface(p, CAMERA)[0] for p in (low, high)])
    ranked = score_detections([_detection(low), _detection(high)], scene, GraspScoringConfig())
    assert np.allclose(ranked[0].X_WD, high)
    assert ranked[1].score > 0.5, "the lowest free domino is still a good pick"


def test_a_box_with_no_point_on_it_is_a_fit_no_check_accepts() -> None:
    """A box slid off its points (the depth check's slide to an end) has no inlier: its fit
    is infinitely bad and sees nothing, where it raised and failed the whole placement
    check after a 30-domino circle's strike."""
    points = np.random.default_rng(0).uniform(-0.01, 0.01, (50, 3))
    fit = fit_statistics(np.eye(4), points, np.zeros(len(points), dtype=bool))
    assert fit.fit_error == math.inf and fit.inlier_fraction == 0.0
    assert not fit.extents.any()

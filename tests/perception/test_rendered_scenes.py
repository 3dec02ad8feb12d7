"""The whole pipeline on scenes the simulator renders: poses, separation, postures."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dombot_description.scenario import load_scenario
from dombot_perception import backprojection, geometric_segmentation
from dombot_perception import pipeline as pipeline_module
from dombot_perception.backprojection import backproject, organised_cloud
from dombot_perception.box_fit import (
    BoxFitConfig,
    BoxFitError,
    fit_domino_box,
    fit_domino_boxes,
    fit_statistics,
)
from dombot_perception.depth_check import (
    DepthCheckConfig,
    correct_box,
    depth_evidence,
    silhouette,
)
from dombot_perception.domino_model import HALF_SIZE, orientation_error
from dombot_perception.frames import POSTURE_FLAT, POSTURE_ON_EDGE, POSTURE_UPRIGHT, CameraView
from dombot_perception.pipeline import build_pipeline
from support.perception_scenes import FLAT_HEIGHT, PILE_CENTRE, domino_pose, flat

X0, Y0 = PILE_CENTRE
POSITION_TOLERANCE = 0.003  # m: 2 mm accuracy plus the scenario's half-pixel K offset
ANGLE_TOLERANCE = np.radians(3.0)


@pytest.fixture(scope="module")
def pipeline():
    return build_pipeline(load_scenario())


def closest(detections, truth: np.ndarray):
    return min(detections, key=lambda d: np.linalg.norm(d.X_WD[:3, 3] - truth[:3, 3]))


def assert_found(detections, truth: np.ndarray) -> None:
    found = closest(detections, truth)
    assert np.linalg.norm(found.X_WD[:3, 3] - truth[:3, 3]) < POSITION_TOLERANCE
    assert orientation_error(found.X_WD[:3, :3], truth[:3, :3]) < ANGLE_TOLERANCE


def test_single_flat_domino_is_found_with_its_pose_and_canonical_signs(pipeline, render_scene):
    truth = flat(X0, Y0, yaw=2.6)  # body x pointing back towards the arm base
    result = pipeline.run(render_scene({0: truth}))
    assert len(result.detections) == 1, result.rejected
    detection = result.detections[0]
    assert_found(result.detections, truth)
    assert detection.posture == POSTURE_FLAT
    assert detection.cameras == ("camera_0", "camera_1")
    rotation = detection.X_WD[:3, :3]
    assert rotation[2, 2] > 0.99, "flat: body z points up"
    assert rotation[:, 0] @ np.array([X0, Y0, 0.0]) > 0, "body x points away from the base"
    assert np.allclose(detection.size, [0.048, 0.024, 0.0075], atol=0.004)
    assert detection.fit_error < 0.001
    assert detection.score > 0.5 and detection.clearance > 0.004  # nothing near it


def test_two_touching_dominoes_side_by_side_are_separated(pipeline, render_scene):
    yaw = 0.3
    rotation = Rotation.from_euler("z", yaw).as_matrix()
    first = flat(X0, Y0, yaw)
    second = first.copy()
    second[:3, 3] += rotation @ np.array([0.012, 0.024, 0.0])  # long faces touching
    result = pipeline.run(render_scene({0: first, 1: second}))
    assert len(result.detections) == 2, result.rejected
    assert_found(result.detections, first)
    assert_found(result.detections, second)
    for detection in result.detections:
        assert detection.clearance < 0.004, "the neighbour leaves no room for a finger"


def test_two_dominoes_touching_end_to_end_are_separated(pipeline, render_scene):
    first, second = flat(X0 - 0.024, Y0, 0.0), flat(X0 + 0.024, Y0, 0.0)
    result = pipeline.run(render_scene({0: first, 1: second}))
    assert len(result.detections) == 2, result.rejected
    assert_found(result.detections, first)
    assert_found(result.detections, second)


def test_after_a_pick_unchanged_regions_keep_their_parts_unsplit(
    pipeline, render_scene, monkeypatch
):
    """The segmenter remembers the last frame's regions: a pair left as it was is not split
    again, and every mask is what a segmenter that never saw the first frame finds."""
    first = flat(X0, Y0, 0.3)
    second = first.copy()
    second[:3, 3] += Rotation.from_euler("z", 0.3).as_matrix() @ np.array([0.012, 0.024, 0.0])
    picked = flat(X0 - 0.06, Y0 + 0.06, 1.0)
    config = pipeline.config

    def masks(segmenter, view) -> list[tuple[int, ...]]:
        cloud = organised_cloud(view, config.region, config.depth_range)
        return sorted(tuple(mask) for mask in segmenter.segment(view, cloud))

    remembering = geometric_segmentation.GeometricSegmenter()
    for view in render_scene({0: first, 1: second, 2: picked}):
        assert len(masks(remembering, view)) == 3  # the pair was split
    splits = []
    split = geometric_segmentation.split_steps
    monkeypatch.setattr(
        geometric_segmentation,
        "split_steps",
        lambda *args: splits.append(args[0].size) or split(*args),
    )
    for view in render_scene({0: first, 1: second}):
        remembered = masks(remembering, view)
        assert not splits, "the pair's region was split again"
        assert remembered == masks(geometric_segmentation.GeometricSegmenter(), view)
        assert splits, "a segmenter that never saw the first frame splits it"
        splits.clear()


def test_the_height_window_leaves_the_organised_cloud_as_it_was(
    pipeline, render_scene, monkeypatch
):
    """organised_cloud back-projects only the rows and columns around the pixels at the
    work region's heights; the cloud is the one of the whole projected outline, to the bit."""
    scene = {
        0: flat(X0, Y0, 0.3),
        1: domino_pose(
            (X0 - 0.06, Y0 + 0.05, 0.024), Rotation.from_euler("y", -np.pi / 2).as_matrix()
        ),
        2: flat(X0 + 0.1, Y0 - 0.08, 2.0),
    }
    region, depth_range = pipeline.config.region, pipeline.config.depth_range
    views = render_scene(scene)
    cropped = [organised_cloud(view, region, depth_range) for view in views]
    monkeypatch.setattr(
        backprojection, "_height_window", lambda view, r, d, first, last: (first, last)
    )
    for view, cloud in zip(views, cropped, strict=True):
        whole = organised_cloud(view, region, depth_range)
        assert (cloud.top, cloud.left, cloud.image_width) == (
            whole.top,
            whole.left,
            whole.image_width,
        )
        for name in ("points", "normals", "valid", "pixel_size"):
            assert np.array_equal(getattr(cloud, name), getattr(whole, name), equal_nan=True), name


def test_views_split_side_by_side_get_each_views_own_masks(pipeline, render_scene, monkeypatch):
    """segment_views advances the splits of both cameras' regions in one run_batched: each
    view's masks are those a segmenter given that view alone finds, and a view with
    nothing in the work region gets none without disturbing the other."""
    yaw = 0.3
    first = flat(X0, Y0, yaw)
    second = first.copy()
    second[:3, 3] += Rotation.from_euler("z", yaw).as_matrix() @ np.array([0.012, 0.024, 0.0])
    views = render_scene({0: first, 1: second, 2: flat(X0 - 0.05, Y0 + 0.05, 1.0)})
    config = pipeline.config
    clouds = [organised_cloud(view, config.region, config.depth_range) for view in views]
    runs = []
    batched = geometric_segmentation.run_batched
    monkeypatch.setattr(
        geometric_segmentation,
        "run_batched",
        lambda tasks: runs.append(len(tasks)) or batched(tasks),
    )
    together = geometric_segmentation.GeometricSegmenter().segment_views(views, clouds)
    assert runs == [4], "the two regions of each of the two views in one run"
    for view, cloud, masks in zip(views, clouds, together, strict=True):
        alone = geometric_segmentation.GeometricSegmenter().segment(view, cloud)
        assert len(masks) == 3
        assert sorted(map(tuple, masks)) == sorted(map(tuple, alone))
    one_empty = geometric_segmentation.GeometricSegmenter().segment_views(views, [clouds[0], None])
    assert one_empty[1] == []
    assert sorted(map(tuple, one_empty[0])) == sorted(map(tuple, together[0]))


def _detected(result) -> list[tuple]:
    return sorted(
        (tuple(d.X_WD.ravel()), d.score, d.clearance, tuple(d.grasp_pose.ravel()))
        for d in result.detections
    )


def test_after_a_pick_unchanged_clouds_keep_their_boxes(render_scene, monkeypatch):
    """The pipeline remembers the last frame's fits: a domino whose points and depth pixels
    are as they were is not fitted again, one whose depth window changed is, and every
    detection is what a pipeline that never saw the first frame finds."""
    lone, other = flat(X0 + 0.05, Y0 - 0.04, 0.3), flat(X0 - 0.04, Y0 + 0.03, 2.0)
    picked = flat(X0 - 0.06, Y0 - 0.06, 1.0)
    remembering = build_pipeline(load_scenario())
    assert len(remembering.run(render_scene({0: lone, 1: other, 2: picked})).detections) == 3
    fits = []
    fit = pipeline_module.fit_domino_boxes
    monkeypatch.setattr(
        pipeline_module, "fit_domino_boxes", lambda *args: fits.extend(args[0]) or fit(*args)
    )
    views = render_scene({0: lone, 1: other})
    remembered = remembering.run(views)
    assert not fits, "an unchanged domino was fitted again"
    fresh = build_pipeline(load_scenario()).run(views)
    assert fits, "a pipeline that never saw the first frame fits them"
    assert _detected(remembered) == _detected(fresh) and len(fresh.detections) == 2
    fits.clear()
    # a table pixel at a corner of the lone domino's silhouette window: its cloud is the
    # same, but its depth check read that pixel, so it is checked again
    changed = [CameraView(v.name, v.rgb, v.depth.copy(), v.K, v.X_WC) for v in views]
    top, _, left, _ = silhouette(closest(fresh.detections, lone).X_WD, changed[0]).window
    changed[0].depth[top, left] += 0.0005
    again = remembering.run(changed)
    assert len(fits) == 1, "only the domino whose depth window changed is fitted again"
    assert _detected(again) == _detected(fresh)


def test_boxes_fitted_in_one_batch_are_the_boxes_fitted_one_by_one(render_scene, monkeypatch):
    """The clouds a pipeline fits (the parts its segmenter tries while splitting touching
    dominoes, and the fused clouds) get the same boxes, or the same error, in one batch as
    one at a time: the batch pads the clouds but computes each box on its own points."""
    yaw = 0.3
    first = flat(X0, Y0, yaw)
    second = first.copy()
    second[:3, 3] += Rotation.from_euler("z", yaw).as_matrix() @ np.array([0.012, 0.024, 0.0])
    tilted = domino_pose(
        (X0 - 0.05, Y0 + 0.05, 0.012), Rotation.from_euler("xz", [0.35, 1.0]).as_matrix()
    )
    batches = []
    for module in (geometric_segmentation, pipeline_module):
        fit = module.fit_domino_boxes
        monkeypatch.setattr(
            module, "fit_domino_boxes", lambda *args, fit=fit: batches.append(args) or fit(*args)
        )
    scene = {0: first, 1: second, 2: tilted, 3: flat(X0 + 0.05, Y0 - 0.04, 2.0)}
    build_pipeline(load_scenario()).run(render_scene(scene))
    clouds = [(cloud, config) for batch, config in batches for cloud in batch]
    assert len(clouds) > 10 and max(len(batch) for batch, _ in batches) >= 3
    for batch, config in batches:
        for (points, normals), batched in zip(batch, fit_domino_boxes(batch, config), strict=True):
            try:
                alone = fit_domino_box(points, normals, config)
            except BoxFitError as error:
                assert isinstance(batched, BoxFitError) and str(batched) == str(error)
                continue
            assert np.allclose(batched.X_WD, alone.X_WD, rtol=0.0, atol=1e-9)
            assert np.allclose(batched.extents, alone.extents, rtol=0.0, atol=1e-9)
            assert abs(batched.fit_error - alone.fit_error) < 1e-12
            assert batched.inlier_fraction == alone.inlier_fraction


def test_upright_domino_is_classified_upright(pipeline, render_scene):
    rotation = (
        Rotation.from_euler("y", -90, degrees=True) * Rotation.from_euler("x", 30, degrees=True)
    ).as_matrix()
    truth = domino_pose((X0, Y0, 0.024), rotation)
    result = pipeline.run(render_scene({0: truth}))
    assert len(result.detections) == 1, result.rejected
    detection = result.detections[0]
    assert detection.posture == POSTURE_UPRIGHT
    assert detection.X_WD[2, 0] > 0.99, "upright: body x points up"
    assert_found(result.detections, truth)


def test_domino_on_edge_is_classified_on_edge(pipeline, render_scene):
    truth = domino_pose((X0, Y0, 0.012), Rotation.from_euler("x", 90, degrees=True).as_matrix())
    result = pipeline.run(render_scene({0: truth}))
    assert [d.posture for d in result.detections] == [POSTURE_ON_EDGE]
    assert_found(result.detections, truth)


def test_stacked_dominoes_are_both_found_and_the_top_one_ranks_first(pipeline, render_scene):
    lower = flat(X0, Y0, 0.0)
    upper = flat(X0 + 0.01, Y0 + 0.005, 0.8)
    upper[2, 3] = 3 * FLAT_HEIGHT
    result = pipeline.run(render_scene({0: lower, 1: upper}))
    assert_found(result.detections, upper)
    assert np.linalg.norm(result.detections[0].X_WD[:3, 3] - upper[:3, 3]) < POSITION_TOLERANCE
    assert result.detections[0].score_terms["uncovered"] == 1.0


def test_empty_table_gives_no_detections_and_says_why(pipeline, render_scene):
    result = pipeline.run(render_scene({}))
    assert result.detections == []
    assert result.warnings


@pytest.mark.parametrize(
    "garbage",
    [
        lambda depth, rng: np.full_like(depth, np.nan),
        lambda depth, rng: rng.uniform(0.0, 3.0, depth.shape).astype(np.float32),
        lambda depth, rng: np.where(rng.random(depth.shape) < 0.5, np.inf, -depth),
    ],
    ids=["no_returns", "noise", "inf_and_negative"],
)
def test_garbage_depth_gives_no_crash(pipeline, render_scene, garbage):
    rng = np.random.default_rng(3)
    views = render_scene({0: flat(X0, Y0, 0.0)})
    broken = [
        CameraView(v.name, v.rgb, garbage(v.depth, rng).astype(np.float32), v.K, v.X_WC)
        for v in views
    ]
    result = pipeline.run(broken)
    assert all(d.fit_error < 0.0015 for d in result.detections)
    assert len(result.detections) <= 1


def test_malformed_view_is_skipped_with_a_warning(pipeline, render_scene):
    good, other = render_scene({0: flat(X0, Y0, 0.0)})
    bad = CameraView(other.name, other.rgb, other.depth, np.full((3, 3), np.nan), other.X_WC)
    result = pipeline.run([good, bad])
    assert any("camera matrix" in w for w in result.warnings)
    assert len(result.detections) == 1
    assert result.detections[0].cameras == (good.name,)


def test_a_box_where_the_cameras_see_the_table_fails_the_free_space_check(render_scene) -> None:
    truth = flat(X0, Y0, 0.3)
    views = render_scene({0: truth})
    config = DepthCheckConfig()
    assert depth_evidence(truth, views, config).see_through_fraction < 0.02
    phantom = flat(X0 + 0.06, Y0, 0.3)  # nothing there: both cameras see the table behind
    assert depth_evidence(phantom, views, config).see_through_fraction > 0.95


def test_a_box_sticking_out_past_the_visible_surface_is_pulled_back(render_scene) -> None:
    truth = flat(X0, Y0, 0.3)
    views = render_scene({0: truth})
    seen = np.concatenate([backproject(v.depth, v.K, v.X_WC).reshape(-1, 3) for v in views])
    body = (seen - truth[:3, 3]) @ truth[:3, :3]
    # only the middle of the top face: these points leave the box free to slide lengthwise
    middle = (np.abs(body[:, 0]) < 0.015) & (np.abs(body[:, 1]) < HALF_SIZE[1])
    points = seen[middle & (np.abs(body[:, 2] - HALF_SIZE[2]) < 0.0005)]
    shifted = truth.copy()
    shifted[:3, 3] += 0.004 * truth[:3, 0]  # 4 mm over the end: the cameras see the table
    fit = fit_statistics(shifted, points, np.ones(points.shape[0], dtype=bool))
    config = DepthCheckConfig()
    corrected, evidence = correct_box(fit, points, views, config, BoxFitConfig())
    assert depth_evidence(shifted, views, config).see_through_fraction > 0.05
    assert evidence.see_through_fraction < 0.02
    assert np.linalg.norm(corrected.X_WD[:3, 3] - truth[:3, 3]) < 0.001
    assert orientation_error(corrected.X_WD[:3, :3], truth[:3, :3]) < np.radians(1.0)

"""perception_node's parameters, what makes a set of them wrong, and the pipeline they
configure: the node builds its pipeline here at start-up and on every update, and a
rejected update never reaches it."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, replace

import numpy as np
from rclpy.qos import QoSProfile, qos_profile_sensor_data
from scipy.spatial.transform import Rotation

from dombot_adapters.parameters import described
from dombot_description.scenario import Scenario
from dombot_perception.pipeline import PerceptionPipeline, build_pipeline

START_UP_PARAMETERS = ("cameras", "scenario", "extrinsics_from_tf", "image_reliability")
IMAGE_QOS = {
    "reliable": QoSProfile(depth=qos_profile_sensor_data.depth),
    "best_effort": qos_profile_sensor_data,
}


@dataclass(frozen=True)
class PerceptionParameters:
    """perception_node's parameters (START_UP_PARAMETERS are read at start-up only); the
    pipeline checks the values when it is built from them."""

    scenario: str = described("", "scenario file; empty: dombot_description's default")
    cameras: tuple[str, ...] = described(
        ("camera_0", "camera_1", "camera_2", "camera_3"), "cameras to subscribe (/<name>/...)"
    )
    detect_cameras: tuple[str, ...] = described(
        ("camera_0", "camera_1"), "cameras that watch the pile"
    )
    placement_cameras: tuple[str, ...] = described(
        ("camera_2", "camera_3"),
        "cameras of placement checks, in order of preference (each fitted alone; the first "
        "camera's fit taken)",
    )
    in_hand_cameras: tuple[str, ...] = described(
        ("camera_0", "camera_1", "camera_2", "camera_3"),
        "cameras of in_hand placement checks (each fitted alone; the gripper hides the held "
        "domino from some)",
    )
    backend: str = described("geometric", "segmentation backend: geometric | sam")
    sam_checkpoint: str = described("", "path of a SAM checkpoint (.pth), needed by backend sam")
    sam_model_type: str = described(
        "vit_b", "SAM model type of the checkpoint: vit_b | vit_l | vit_h"
    )
    sam_points_per_side: int = described(32, "SAM prompt grid: points per image side")
    continuous: bool = described(True, "process new frames at 'rate' without being asked")
    rate: float = described(1.0, "continuous processing rate [Hz]")
    max_frame_age: float = described(5.0, "frames older than this [s] count as a stopped camera")
    fresh_frame_timeout: float = described(
        10.0,
        "[s] (wall) a request with not_before waits this long for frames stamped after it: on "
        "a loaded CPU the images arrive well after the joint states that told the caller",
    )
    sync_tolerance: float = described(0.05, "colour and depth stamps may differ by this [s]")
    max_fit_error: float = described(
        0.0015, "reject boxes whose RMS point distance exceeds this [m]"
    )
    min_coverage: float = described(0.85, "fraction of a large face that must be seen")
    min_clearance: float = described(
        0.0015, "finger clearance below this predicts a failed grasp [m]"
    )
    work_region_center: tuple[float, float] = described(
        (0.0, 0.0), "region centre [x y] in world; [0 0]: the pile's"
    )
    work_region_radius: float = described(
        0.0, "region radius [m]; 0: scenario pile radius + margin"
    )
    publish_debug_image: bool = described(True, "publish /perception/debug_image")
    image_reliability: str = described(
        "reliable",
        "image and camera_info subscriptions: reliable | best_effort (sensor-data QoS, for "
        "a best-effort camera driver); read at start-up",
    )
    extrinsics_from_tf: bool = described(
        False,
        "camera poses from /tf and /tf_static (world → the images' frame_id) instead of the "
        "scenario; read at start-up",
    )


def default_settings(values: PerceptionParameters) -> PerceptionParameters:
    """The declared defaults, but ``values``' scenario and cameras (in use once the node
    has read them): what the node runs with when its start-up parameters are wrong."""
    return replace(PerceptionParameters(), scenario=values.scenario, cameras=values.cameras)


def configured_pipeline(scenario: Scenario, values: PerceptionParameters) -> PerceptionPipeline:
    """A pipeline for these parameter values; raises ValueError naming a bad one."""
    if values.image_reliability not in IMAGE_QOS:
        raise ValueError(
            f"image_reliability must be one of {sorted(IMAGE_QOS)}, "
            f"got {values.image_reliability!r}"
        )
    for name in (
        "rate",
        "max_frame_age",
        "fresh_frame_timeout",
        "sync_tolerance",
        "max_fit_error",
        "min_coverage",
    ):
        value = getattr(values, name)
        if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
            raise ValueError(f"{name} must be a positive number, got {value!r}")
    if not 0 < values.min_coverage <= 1:
        raise ValueError(f"min_coverage must be in (0, 1], got {values.min_coverage}")
    pipeline = build_pipeline(
        scenario,
        backend=values.backend,
        sam_checkpoint=values.sam_checkpoint,
        sam_model_type=values.sam_model_type,
        sam_points_per_side=int(values.sam_points_per_side),
    )
    config = pipeline.config
    region = config.region
    centre = [float(v) for v in values.work_region_center]
    if len(centre) != 2 or not np.all(np.isfinite(centre)):
        raise ValueError(f"work_region_center needs two finite numbers, got {centre}")
    if any(centre):
        region = replace(region, center=(centre[0], centre[1]))
    if values.work_region_radius > 0:
        region = replace(region, radius=float(values.work_region_radius))
    pipeline.config = replace(
        config,
        region=region,
        filtering=replace(
            config.filtering,
            max_fit_error=float(values.max_fit_error),
            min_coverage=float(values.min_coverage),
        ),
        scoring=replace(config.scoring, min_clearance=float(values.min_clearance)),
    )
    return pipeline


def optical_pose(name: str, values: Sequence[float]) -> np.ndarray:
    """X_WC from camera ``name``'s ``optical_pose`` parameter [x y z qx qy qz qw]; raises
    ValueError when it is not 7 finite numbers with a unit quaternion."""
    if len(values) != 7 or not np.all(np.isfinite(values)):
        raise ValueError(f"{name}.optical_pose needs 7 finite numbers [x y z qx qy qz qw]")
    quaternion = np.asarray(values[3:], dtype=float)
    if abs(np.linalg.norm(quaternion) - 1.0) > 1e-3:
        raise ValueError(f"{name}.optical_pose quaternion is not unit length")
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_quat(quaternion).as_matrix()
    pose[:3, 3] = values[:3]
    return pose

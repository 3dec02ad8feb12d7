"""perception_node: camera images in, domino poses and ranked grasps out.

A thin ROS adapter over ``pipeline``: it keeps the latest synchronised colour/depth/
camera_info of each camera, runs the pipeline continuously at ``rate`` (when
``continuous``) and on demand through ``/perception/detect``, and publishes
``/domino_poses`` (best grasp first), ``/domino_detections`` and a debug picture. Camera
poses come from the scenario file, from ``<camera>.optical_pose`` parameters, or
(``extrinsics_from_tf``) from /tf and /tf_static: world → the images' frame, a real
cell's calibration. Images are subscribed reliable by default (``image_reliability``):
a best-effort reader drops a whole image whenever one of its fragments is lost, which
starved the placement checks under load; ``best_effort`` (sensor-data QoS) is for a
best-effort camera driver such as realsense-ros. With ``continuous`` off the camera
topics are subscribed only while a request waits for frames: a simulator (or a lazy
driver) then renders nothing while nobody looks, and a streaming camera serves just the
same. Missing, stale or malformed images give an empty result and a warning; the node
keeps serving.
``/perception/check_placement`` looks at where the dominoes of a run should stand
(``placement_check``), with the build-area camera by default.
"""

from __future__ import annotations

import math
import threading
import time
import traceback
from collections import Counter, deque
from collections.abc import Iterator
from contextlib import contextmanager
from dataclasses import dataclass, field, replace

import numpy as np
import rclpy
from geometry_msgs.msg import Point, PoseArray, Vector3
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from scipy.spatial.transform import Rotation
from sensor_msgs.msg import CameraInfo, Image
from tf2_msgs.msg import TFMessage

from dombot_adapters.node_shutdown import spin_until_shutdown
from dombot_adapters.parameters import DataclassParameters, described
from dombot_adapters.pose_messages import pose_matrix, pose_message
from dombot_description import tilt_from_vertical
from dombot_description.allocator import tune_allocator
from dombot_description.scenario import ScenarioError, load_scenario
from dombot_msgs.msg import DominoDetection, DominoDetectionArray
from dombot_msgs.srv import CheckPlacement, DetectDominoes
from dombot_perception.debug_image import draw_detections, mask_overlay
from dombot_perception.frames import CameraView, Detection
from dombot_perception.pipeline import PerceptionPipeline, PipelineResult, build_pipeline
from dombot_perception.placement_check import PlacementConfig, check_placements
from dombot_perception.repeat_filter import RepeatFilter
from dombot_perception.segmentation import SegmenterError
from dombot_perception.transforms import TransformBuffer

DEFAULT_SEARCH_RADIUS = PlacementConfig().search_radius
MAX_IN_HAND_TILT = math.degrees(PlacementConfig().max_tilt)  # expected poses when in_hand
SYNC_BUFFER = 5  # messages kept per stream to find matching colour/depth stamps
SYNC_WAIT = 1.0  # s to wait for a matching pair when a loaded CPU delivered one stream late
# s (wall) to wait for a camera's first frames after subscribing (discovery, first render)
FIRST_FRAME_WAIT = 10.0
# s (wall) to wait for frames stamped after a request's not_before: on a loaded CPU the
# images of a frame arrive well after the joint states that tell the caller its time has
# come (a stale frame from before a placement once made a standing domino MISSING)
FRESH_WAIT = 10.0
WARNING_REPEAT = 10.0  # s: a warning repeated request after request is logged once per this
STAMP_SLACK = 1e-3  # s: stamps this much before not_before still count (rounding)
MAX_EXPECTED = 500  # poses a placement check takes (a run in the build area has < 200)
# s a request's not_before may lie after the newest frame; later ones are refused at once
# (a frame that far ahead does not come within FRESH_WAIT, even from a fast simulation)
MAX_NOT_BEFORE_AHEAD = 60.0
DEPTH_ENCODINGS = {"32FC1": (np.float32, 1.0), "16UC1": (np.uint16, 0.001)}  # → metres
WORLD_FRAME = "world"
# tf2_ros's listener QoS: /tf reliable, volatile; /tf_static reliable, transient local
TF_QOS = QoSProfile(depth=100)
TF_STATIC_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)
START_UP_PARAMETERS = ("cameras", "scenario", "extrinsics_from_tf", "image_reliability")
IMAGE_QOS = {
    "reliable": QoSProfile(depth=qos_profile_sensor_data.depth),
    "best_effort": qos_profile_sensor_data,
}


@dataclass
class CameraInput:
    """The last few messages of one camera and when a colour image last arrived."""

    colors: deque = field(default_factory=lambda: deque(maxlen=SYNC_BUFFER))
    depths: deque = field(default_factory=lambda: deque(maxlen=SYNC_BUFFER))
    info: CameraInfo | None = None
    received: float = -math.inf

    def latest_pair(
        self, tolerance: float, not_before: float = -math.inf
    ) -> tuple[Image, Image] | None:
        """The newest colour and depth images whose stamps agree within ``tolerance`` s,
        stamped at or after ``not_before``."""
        for color in reversed(self.colors):
            stamp = _seconds(color.header.stamp)
            if stamp < not_before - STAMP_SLACK:
                return None
            for depth in reversed(self.depths):
                if abs(_seconds(depth.header.stamp) - stamp) <= tolerance:
                    return color, depth
        return None


@dataclass(frozen=True)
class PerceptionParameters:
    """perception_node's parameters (START_UP_PARAMETERS are read at start-up only); the
    pipeline checks the values when it is built from them."""

    scenario: str = described("", "scenario file; empty: dombot_description's default")
    cameras: tuple[str, ...] = described(
        ("camera_0", "camera_1", "camera_2"), "cameras to subscribe (/<name>/...)"
    )
    detect_cameras: tuple[str, ...] = described(
        ("camera_0", "camera_1"), "cameras that watch the pile"
    )
    placement_cameras: tuple[str, ...] = described(
        ("camera_2",), "cameras that watch the build area"
    )
    in_hand_cameras: tuple[str, ...] = described(
        ("camera_0", "camera_1", "camera_2"),
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


class PerceptionNode(Node):
    def __init__(self) -> None:
        super().__init__("perception_node")
        self.parameters = DataclassParameters(self, PerceptionParameters)
        self.settings = self.parameters.read()
        self.scenario = load_scenario(self.settings.scenario or None)
        self.camera_names: list[str] = list(self.settings.cameras)
        for name in self.camera_names:
            self.declare_parameter(
                f"{name}.optical_pose",
                Parameter.Type.DOUBLE_ARRAY,
                ParameterDescriptor(
                    description="optical frame in world [x y z qx qy qz qw]; unset: scenario"
                ),
            )
        self.inputs = {name: CameraInput() for name in self.camera_names}
        self._input_lock = threading.Lock()
        self._camera_subscriptions: dict[str, list] = {}  # camera → its topics' subscriptions
        self._holders: Counter[str] = Counter()  # requests (and continuous) holding each camera
        self._streaming = False  # all cameras held for continuous processing
        self._inputs_group = ReentrantCallbackGroup()
        try:
            self.pipeline = self._build_pipeline(self.settings)
        except (ValueError, SegmenterError, OSError, RuntimeError) as error:
            self.get_logger().error(f"bad parameters ({error}); using the default settings")
            self.pipeline = build_pipeline(self.scenario)
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.poses_pub = self.create_publisher(PoseArray, "domino_poses", 10)
        self.detections_pub = self.create_publisher(DominoDetectionArray, "domino_detections", 10)
        self.debug_pub = self.create_publisher(Image, "perception/debug_image", 2)
        self._follow_continuous()
        self.transforms = TransformBuffer()
        if self.settings.extrinsics_from_tf:
            for topic, qos in (("/tf", TF_QOS), ("/tf_static", TF_STATIC_QOS)):
                self.create_subscription(
                    TFMessage, topic, self._on_transforms, qos, callback_group=self._inputs_group
                )
        work = MutuallyExclusiveCallbackGroup()
        self.create_service(
            DetectDominoes, "perception/detect", self._on_detect, callback_group=work
        )
        self.create_service(
            CheckPlacement,
            "perception/check_placement",
            self._on_check_placement,
            callback_group=work,
        )
        self.last_processed: dict[str, float] = {}
        self.repeated_warnings = RepeatFilter(WARNING_REPEAT)
        self.timer = self.create_timer(
            1.0 / self.settings.rate, self._on_timer, callback_group=work
        )
        mode = f"continuous at {self.settings.rate} Hz" if self.settings.continuous else ""
        extrinsics = "/tf" if self.settings.extrinsics_from_tf else "the scenario"
        self.get_logger().info(
            f"ready: backend {self.pipeline.segmenter.name}, cameras {self.camera_names} "
            f"(extrinsics from {extrinsics}), {mode or 'on demand only'}; "
            "services /perception/detect, /perception/check_placement"
        )

    # ------------------------------------------------------------------ parameters
    def _build_pipeline(self, values: PerceptionParameters) -> PerceptionPipeline:
        """A pipeline for these parameter values; raises ValueError naming a bad one."""
        if values.image_reliability not in IMAGE_QOS:
            raise ValueError(
                f"image_reliability must be one of {sorted(IMAGE_QOS)}, "
                f"got {values.image_reliability!r}"
            )
        for name in ("rate", "max_frame_age", "sync_tolerance", "max_fit_error", "min_coverage"):
            value = getattr(values, name)
            if isinstance(value, bool) or not isinstance(value, int | float) or not value > 0:
                raise ValueError(f"{name} must be a positive number, got {value!r}")
        if not 0 < values.min_coverage <= 1:
            raise ValueError(f"min_coverage must be in (0, 1], got {values.min_coverage}")
        pipeline = build_pipeline(
            self.scenario,
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

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        changed = {p.name: p.value for p in parameters}
        fixed = [name for name in START_UP_PARAMETERS if name in changed]
        if fixed:
            reason = f"{', '.join(fixed)}: read at start-up; restart the node to change them"
            self.get_logger().error(f"rejected parameter update: {reason}")
            return SetParametersResult(successful=False, reason=reason)
        try:
            settings = self.parameters.read(parameters)
            pipeline = self._build_pipeline(settings)
        except (ValueError, TypeError, SegmenterError, OSError, RuntimeError) as error:
            self.get_logger().error(f"rejected parameter update: {error}")
            return SetParametersResult(successful=False, reason=str(error))
        self.settings, self.pipeline = settings, pipeline
        self.get_logger().info(f"parameters updated: {changed}")
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ inputs
    @contextmanager
    def _watching(self, names: list[str]) -> Iterator[None]:
        """Subscribe to ``names`` (unless already) for as long as the block runs."""
        self._hold(names)
        try:
            yield
        finally:
            self._release(names)

    def _hold(self, names: list[str]) -> None:
        with self._input_lock:
            for name in names:
                self._holders[name] += 1
                if name not in self._camera_subscriptions:
                    self._camera_subscriptions[name] = self._subscribe(name)

    def _release(self, names: list[str]) -> None:
        """Unsubscribe cameras nobody holds any more; their old frames go with them (a
        later request must not take a frame from before it was asked)."""
        with self._input_lock:
            for name in names:
                self._holders[name] -= 1
                if self._holders[name] > 0:
                    continue
                for subscription in self._camera_subscriptions.pop(name, []):
                    self.destroy_subscription(subscription)
                self.inputs[name] = CameraInput()

    def _follow_continuous(self) -> None:
        """Hold every camera while ``continuous`` is on, none otherwise."""
        continuous = bool(self.settings.continuous)
        if continuous and not self._streaming:
            self._hold(self.camera_names)
        elif self._streaming and not continuous:
            self._release(self.camera_names)
        self._streaming = continuous

    def _subscribe(self, name: str) -> list:
        camera = self.inputs[name]
        # a bad value was reported with the other parameters: the default then
        qos = IMAGE_QOS.get(self.settings.image_reliability, IMAGE_QOS["reliable"])

        def on_color(message: Image) -> None:
            # the time first: a request on another thread that sees the image must not
            # read the -inf of a camera that never sent one ("the camera stopped publishing")
            camera.received = self._seconds_now()
            camera.colors.append(message)

        def on_depth(message: Image) -> None:
            camera.depths.append(message)

        def on_info(message: CameraInfo) -> None:
            camera.info = message

        # No QoS event handlers: rclpy's executor does not guard an event handler destroyed
        # (by _release, on a service thread) while it builds its wait set, and the node died
        # of InvalidHandle (rclpy issues 1206, 1284). A QoS mismatch is said instead where
        # no frames came (``_nothing_received``).
        quiet = SubscriptionEventCallbacks(use_default_callbacks=False)
        return [
            self.create_subscription(
                kind, topic, callback, qos, callback_group=self._inputs_group, event_callbacks=quiet
            )
            for topic, kind, callback in (
                (f"{name}/color/image_raw", Image, on_color),
                (f"{name}/depth/image_raw", Image, on_depth),
                (f"{name}/color/camera_info", CameraInfo, on_info),
            )
        ]

    def _on_transforms(self, message: TFMessage) -> None:
        for stamped in message.transforms:
            t, q = stamped.transform.translation, stamped.transform.rotation
            self.transforms.set(
                stamped.header.frame_id,
                stamped.child_frame_id,
                (t.x, t.y, t.z),
                (q.x, q.y, q.z, q.w),
            )

    def _warn(self, warnings: list[str]) -> None:
        """Log each warning, a repeated one once per WARNING_REPEAT s (the response of
        every request carries it)."""
        for warning in warnings:
            admitted = self.repeated_warnings.admit(warning)
            if admitted:
                self.get_logger().warning(admitted)

    def _known(self, names: list[str]) -> list[str]:
        return [name for name in names if name in self.inputs]

    def _seconds_now(self) -> float:
        """The node clock: simulated time under use_sim_time, so a simulator running slower
        than real time does not look like a camera that stopped."""
        return self.get_clock().now().nanoseconds * 1e-9

    def _is_stale(self, camera: CameraInput) -> bool:
        return self._seconds_now() - camera.received > float(self.settings.max_frame_age)

    def _views(
        self, names: list[str], not_before: float = -math.inf
    ) -> tuple[list[CameraView], list[str]]:
        """Usable synchronised views of ``names`` (stamped at or after ``not_before``) and
        the warnings about the others; subscribed to for the time it takes."""
        with self._watching(names):
            self._await_first_frames(names)
            return self._collect_views(names, not_before)

    def _await_first_frames(self, names: list[str]) -> None:
        """Wait (FIRST_FRAME_WAIT at most) until each camera has sent colour, depth and
        camera_info: just subscribed, the first frames take discovery and a render."""
        deadline = time.monotonic() + FIRST_FRAME_WAIT
        while (
            time.monotonic() < deadline
            and self.context.ok()  # stopping: the callback returns, the node is drained
            and not all(
                self.inputs[name].colors and self.inputs[name].depths and self.inputs[name].info
                for name in names
            )
        ):
            time.sleep(0.02)  # the input callbacks run on the executor's other thread

    def _collect_views(
        self, names: list[str], not_before: float
    ) -> tuple[list[CameraView], list[str]]:
        views, warnings = [], []
        max_age = float(self.settings.max_frame_age)
        for name in names:
            camera = self.inputs[name]
            if not camera.colors or not camera.depths or camera.info is None:
                warnings.append(f"{name}: {self._nothing_received(name)}")
                continue
            age = self._seconds_now() - camera.received
            if age > max_age:
                warnings.append(
                    f"{name}: last frame {age:.1f} s old; the camera stopped publishing"
                )
                continue
            try:
                views.append(self._view(name, camera, not_before))
            except ValueError as error:
                warnings.append(f"{name}: {error}")
        return views, warnings

    def _nothing_received(self, name: str) -> str:
        """Why a camera sent nothing, as far as the graph tells: no publisher, or only
        best-effort ones that a reliable subscription gets nothing from."""
        topic = self.resolve_topic_name(f"{name}/color/image_raw")
        publishers = self.get_publishers_info_by_topic(topic)
        if not publishers:
            return f"no colour, depth and camera_info received yet: nothing publishes {topic}"
        reliable = self.settings.image_reliability == "reliable"
        if reliable and all(
            p.qos_profile.reliability == ReliabilityPolicy.BEST_EFFORT for p in publishers
        ):
            return (
                f"no colour, depth and camera_info received: {topic} is published best effort, "
                "which a reliable subscription gets nothing from (set image_reliability "
                "best_effort)"
            )
        return "no colour, depth and camera_info received yet"

    def _view(self, name: str, camera: CameraInput, not_before: float) -> CameraView:
        ahead = not_before - _seconds(camera.colors[-1].header.stamp)
        if ahead > MAX_NOT_BEFORE_AHEAD:
            raise ValueError(
                f"not_before is {ahead:.3g} s after the newest frame "
                f"(at most {MAX_NOT_BEFORE_AHEAD} s are waited for)"
            )
        tolerance = float(self.settings.sync_tolerance)
        pair = camera.latest_pair(tolerance, not_before)
        deadline = time.monotonic() + (SYNC_WAIT if math.isinf(not_before) else FRESH_WAIT)
        while pair is None and time.monotonic() < deadline and self.context.ok():
            time.sleep(0.02)  # the input callbacks run on the executor's other thread
            pair = camera.latest_pair(tolerance, not_before)
        if pair is None:
            fresh = "" if math.isinf(not_before) else f", stamped after {not_before:.2f} s"
            raise ValueError(f"no colour and depth images with stamps within {tolerance} s{fresh}")
        color, depth = pair
        view = CameraView(
            name,
            rgb_array(color),
            depth_array(depth),
            np.asarray(camera.info.k, dtype=float).reshape(3, 3),
            self._camera_pose(name, color.header.frame_id or f"{name}_optical"),
        )
        problem = view.check()
        if problem:
            raise ValueError(problem)
        return view

    def _camera_pose(self, name: str, frame_id: str) -> np.ndarray:
        """X_WC of camera ``name`` whose images are in ``frame_id``: its optical_pose
        parameter, else /tf (extrinsics_from_tf), else the scenario."""
        try:
            values = self.get_parameter(f"{name}.optical_pose").value
        except ParameterUninitializedException:
            values = None
        if values is not None and len(values) > 0:
            if len(values) != 7 or not np.all(np.isfinite(values)):
                raise ValueError(f"{name}.optical_pose needs 7 finite numbers [x y z qx qy qz qw]")
            quaternion = np.asarray(values[3:], dtype=float)
            if abs(np.linalg.norm(quaternion) - 1.0) > 1e-3:
                raise ValueError(f"{name}.optical_pose quaternion is not unit length")
            pose = np.eye(4)
            pose[:3, :3] = Rotation.from_quat(quaternion).as_matrix()
            pose[:3, 3] = values[:3]
            return pose
        if self.settings.extrinsics_from_tf:
            try:
                return self.transforms.lookup(WORLD_FRAME, frame_id)
            except LookupError as error:
                raise ValueError(f"no {WORLD_FRAME} → {frame_id} on /tf: {error}") from None
        for spec in self.scenario.cameras:
            if spec.name == name:
                return spec.pose()
        raise ValueError(f"camera {name} is not in the scenario and has no optical_pose")

    # ------------------------------------------------------------------ processing
    def _on_timer(self) -> None:
        self._follow_continuous()
        if not self.settings.continuous:
            return
        names = self._known(self.settings.detect_cameras)
        fresh = {
            name: _seconds(self.inputs[name].colors[-1].header.stamp)
            for name in names
            if self.inputs[name].colors
        }
        if not fresh or fresh == self.last_processed:
            silent = [name for name in names if self._is_stale(self.inputs[name])]
            if silent:
                self.get_logger().warning(
                    f"no new frames from {silent}; waiting", throttle_duration_sec=10.0
                )
            return
        self.last_processed = fresh
        self._detect(names)

    def _on_detect(
        self, request: DetectDominoes.Request, response: DetectDominoes.Response
    ) -> DetectDominoes.Response:
        names = list(request.cameras) or list(self.settings.detect_cameras)
        unknown = [name for name in names if name not in self.inputs]
        if unknown:
            response.success = False
            response.message = f"unknown cameras {unknown}; configured: {self.camera_names}"
            self.get_logger().error(response.message)
            return response
        result, message = self._detect(names, not_before_of(request))
        response.success = result is not None
        response.message = message
        response.detections = self._detection_array(result.detections if result else [])
        if result is not None:
            response.unexplained_points = [
                Point(x=x, y=y, z=z) for x, y, z in result.unexplained.tolist()
            ]
        return response

    def _on_check_placement(
        self, request: CheckPlacement.Request, response: CheckPlacement.Response
    ) -> CheckPlacement.Response:
        default = "in_hand_cameras" if request.in_hand else "placement_cameras"
        names = list(request.cameras) or list(getattr(self.settings, default))
        problem = self._placement_request_problem(request, names)
        if problem:
            response.success, response.message = False, problem
            held = " (in hand)" if request.in_hand else ""
            self.get_logger().error(f"check_placement{held} rejected: {problem}")
            return response
        config = PlacementConfig(
            search_radius=request.search_radius or DEFAULT_SEARCH_RADIUS, in_hand=request.in_hand
        )
        expected = [pose_matrix(pose) for pose in request.expected]
        started = time.perf_counter()
        framed = started
        try:
            views, warnings = self._views(names, not_before_of(request))
            framed = time.perf_counter()
            placements = check_placements(expected, views, self.pipeline, config) if views else []
        except Exception as error:  # one bad frame set must never take the node down
            if not self.context.ok():
                raise  # stopping: the graph went away, and the executor drains this quietly
            self.get_logger().error(f"placement check failed: {error!r}\n{traceback.format_exc()}")
            views, warnings, placements = [], [f"placement check failed: {error!r}"], []
        self._warn(warnings)
        if not views:
            response.success = False
            response.message = "; ".join(["no usable camera for the placement check", *warnings])
            return response
        response.success = True
        response.status = [p.status for p in placements]
        response.measured = [pose_message(p.measured) for p in placements]
        response.position_error = [p.position_error for p in placements]
        response.tilt = [p.tilt for p in placements]
        counts = np.bincount(response.status, minlength=4)
        response.message = "; ".join(
            [
                f"{counts[0]} standing, {counts[1]} fallen, {counts[2]} missing, "
                f"{counts[3]} not seen",
                *warnings,
            ]
        )
        held = " held in the gripper" if request.in_hand else ""
        # where its wall time went: waiting for the frames (subscribing, the render, the
        # transfer) and the fits
        spent = f"frames {framed - started:.2f} s, fits {time.perf_counter() - framed:.2f} s"
        self.get_logger().info(
            f"placement check of {len(expected)}{held}: {response.message} ({spent})"
        )
        return response

    def _placement_request_problem(
        self, request: CheckPlacement.Request, names: list[str]
    ) -> str | None:
        unknown = [name for name in names if name not in self.inputs]
        if unknown:
            return f"unknown cameras {unknown}; configured: {self.camera_names}"
        if not math.isfinite(request.search_radius) or request.search_radius < 0:
            return f"search_radius must be >= 0, got {request.search_radius}"
        if len(request.expected) > MAX_EXPECTED:
            return f"{len(request.expected)} expected poses, at most {MAX_EXPECTED} are checked"
        for index, pose in enumerate(request.expected):
            q = pose.orientation
            values = [pose.position.x, pose.position.y, pose.position.z, q.x, q.y, q.z, q.w]
            if not all(math.isfinite(v) for v in values):
                return f"expected pose {index} is not finite"
            if abs(math.sqrt(q.x**2 + q.y**2 + q.z**2 + q.w**2) - 1.0) > 1e-3:
                return f"expected pose {index}: quaternion is not unit length (within 1e-3)"
            if request.in_hand:  # fitted from the expected foot up to below the pads
                tilt = math.degrees(tilt_from_vertical(pose_matrix(pose)))
                if tilt > MAX_IN_HAND_TILT:
                    return (
                        f"in_hand: expected pose {index} is not upright "
                        f"(body x {tilt:.0f}° from vertical)"
                    )
        return None

    def _detect(
        self, names: list[str], not_before: float = -math.inf
    ) -> tuple[PipelineResult | None, str]:
        """Run the pipeline on the latest frames of ``names`` (stamped at or after
        ``not_before``); publish; say what happened."""
        started = time.perf_counter()
        framed = started
        try:
            views, warnings = self._views(names, not_before)
            framed = time.perf_counter()
            result = self.pipeline.run(views) if views else None
        except Exception as error:  # one bad frame set must never take the node down
            if not self.context.ok():
                raise  # stopping: the graph went away, and the executor drains this quietly
            self.get_logger().error(f"perception failed: {error!r}\n{traceback.format_exc()}")
            views, warnings, result = [], [f"perception failed on this frame set: {error!r}"], None
        if result is not None:
            warnings += result.warnings
            timings = {"frames": framed - started, **result.timings}
            stages = ", ".join(f"{k} {v * 1000:.0f}" for k, v in timings.items())
            self.get_logger().info(
                f"{len(result.detections)} dominoes from {[v.name for v in views]} in "
                f"{time.perf_counter() - started:.2f} s ({stages} ms); "
                f"{len(result.rejected)} candidates rejected"
            )
        self._warn(warnings)
        detections = result.detections if result else []
        self._publish(detections)
        if result is not None and self.settings.publish_debug_image:
            self.debug_pub.publish(self._debug_image(views, result))
        summary = f"{len(detections)} dominoes found"
        return result, "; ".join([summary, *warnings])

    # ------------------------------------------------------------------ outputs
    def _publish(self, detections: list[Detection]) -> None:
        array = self._detection_array(detections)
        poses = PoseArray(header=array.header, poses=[d.pose for d in array.detections])
        self.poses_pub.publish(poses)
        self.detections_pub.publish(array)

    def _detection_array(self, detections: list[Detection]) -> DominoDetectionArray:
        array = DominoDetectionArray()
        array.header.frame_id = "world"
        array.header.stamp = self.get_clock().now().to_msg()
        array.detections = [detection_message(i, d) for i, d in enumerate(detections)]
        return array

    def _debug_image(self, views: list[CameraView], result: PipelineResult) -> Image:
        tiles = [
            draw_detections(
                mask_overlay(view, result.masks.get(view.name, [])), view, result.detections
            )
            for view in views
        ]
        height = max(tile.shape[0] for tile in tiles)
        tiles = [np.pad(t, ((0, height - t.shape[0]), (0, 0), (0, 0))) for t in tiles]
        picture = np.concatenate(tiles, axis=1)
        message = Image(height=picture.shape[0], width=picture.shape[1], encoding="rgb8")
        message.header.frame_id = "world"
        message.header.stamp = self.get_clock().now().to_msg()
        message.step = picture.shape[1] * 3
        message.data = picture.tobytes()
        return message


def _seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def not_before_of(request) -> float:
    """A request's not_before [s]; zero (unset): any frame, the latest."""
    return _seconds(request.not_before) or -math.inf


def rgb_array(message: Image) -> np.ndarray:
    if message.encoding not in ("rgb8", "bgr8"):
        raise ValueError(f"colour encoding {message.encoding!r} is not rgb8 or bgr8")
    rows = _rows(message, np.uint8, 3)
    return rows[:, :, ::-1] if message.encoding == "bgr8" else rows


def depth_array(message: Image) -> np.ndarray:
    """Depth in metres (float32); 16UC1 millimetres are converted, 0 becomes NaN."""
    if message.encoding not in DEPTH_ENCODINGS:
        raise ValueError(f"depth encoding {message.encoding!r} is not 32FC1 or 16UC1")
    dtype, scale = DEPTH_ENCODINGS[message.encoding]
    depth = _rows(message, dtype, 1)[:, :, 0].astype(np.float32) * np.float32(scale)
    depth[depth <= 0] = np.nan
    return depth


def _rows(message: Image, dtype: type, channels: int) -> np.ndarray:
    """The image as an HxWxC array, honouring the row step; ValueError when inconsistent."""
    item = np.dtype(dtype).itemsize * channels
    if message.height == 0 or message.width == 0:
        raise ValueError("empty image")
    if message.step < message.width * item or len(message.data) < message.step * message.height:
        raise ValueError(
            f"{message.width}x{message.height} {message.encoding} image has step "
            f"{message.step} and {len(message.data)} bytes"
        )
    data = np.frombuffer(bytes(message.data), dtype=np.uint8).reshape(message.height, -1)
    row_bytes = data[:, : message.width * item].copy()
    return row_bytes.view(dtype).reshape(message.height, message.width, channels)


def detection_message(index: int, detection: Detection) -> DominoDetection:
    return DominoDetection(
        id=index,
        pose=pose_message(detection.X_WD),
        size=_vector(detection.size),
        posture=detection.posture,
        score=float(detection.score),
        fit_error=float(detection.fit_error),
        clearance=float(detection.clearance),
        num_points=int(detection.num_points),
        num_cameras=len(detection.cameras),
        grasp_pose=pose_message(detection.grasp_pose),
        grasp_width=float(detection.grasp_width),
    )


def _vector(values: np.ndarray) -> Vector3:
    return Vector3(x=float(values[0]), y=float(values[1]), z=float(values[2]))


def main(args: list[str] | None = None) -> None:
    tune_allocator()
    rclpy.init(args=args)
    try:
        node = PerceptionNode()
    except (ScenarioError, SegmenterError, ValueError) as error:
        print(f"perception_node: cannot start: {error}", flush=True)
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    spin_until_shutdown(node, num_threads=2)


if __name__ == "__main__":
    main()

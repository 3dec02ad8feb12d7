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
(``placement_check``), with the build-area camera by default; it is served beside a
running detect, not after it (callback groups of their own). The parameters and the
pipeline they configure are in ``perception_parameters``, the conversions to and from
messages in ``perception_messages``.
"""

from __future__ import annotations

import math
import threading
import time
import traceback
from collections import Counter
from collections.abc import Iterator
from contextlib import contextmanager

import numpy as np
import rclpy
from geometry_msgs.msg import Point, PoseArray
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.exceptions import ParameterUninitializedException
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from sensor_msgs.msg import CameraInfo, Image
from tf2_msgs.msg import TFMessage

from dombot_adapters.node_shutdown import DrainingExecutor, spin_until_shutdown
from dombot_adapters.parameters import DataclassParameters
from dombot_adapters.pose_messages import pose_matrix
from dombot_description.allocator import tune_allocator
from dombot_description.scenario import ScenarioError, load_scenario
from dombot_msgs.msg import DominoDetectionArray
from dombot_msgs.srv import CheckPlacement, DetectDominoes
from dombot_perception.frames import CameraView, Detection
from dombot_perception.perception_messages import (
    WORLD_FRAME,
    CameraInput,
    debug_image,
    depth_array,
    detection_array,
    expected_poses_problem,
    fill_placement_response,
    not_before_of,
    placement_config,
    rgb_array,
    stamp_seconds,
)
from dombot_perception.perception_parameters import (
    IMAGE_QOS,
    START_UP_PARAMETERS,
    PerceptionParameters,
    configured_pipeline,
    default_settings,
    optical_pose,
)
from dombot_perception.pipeline import PipelineResult, build_pipeline
from dombot_perception.placement_check import check_placements
from dombot_perception.repeat_filter import RepeatFilter
from dombot_perception.segmentation import SegmenterError
from dombot_perception.transforms import TransformBuffer

SYNC_WAIT = 1.0  # s to wait for a matching pair when a loaded CPU delivered one stream late
# s (wall) to wait for a camera's first frames after subscribing (discovery, first render)
FIRST_FRAME_WAIT = 10.0
WARNING_REPEAT = 10.0  # s: a warning repeated request after request is logged once per this
# s a request's not_before may lie after the newest frame; later ones are refused at once
# (a frame that far ahead does not come within fresh_frame_timeout, even from a fast
# simulation)
MAX_NOT_BEFORE_AHEAD = 60.0
# a detect, a placement check and the camera inputs they wait for, at once (each request
# waits for frames on its own thread: with one thread fewer the inputs starve until the
# request's fresh_frame_timeout runs out)
EXECUTOR_THREADS = 3
# tf2_ros's listener QoS: /tf reliable, volatile; /tf_static reliable, transient local
TF_QOS = QoSProfile(depth=100)
TF_STATIC_QOS = QoSProfile(depth=100, durability=DurabilityPolicy.TRANSIENT_LOCAL)


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
            self.pipeline = configured_pipeline(self.scenario, self.settings)
        except (ValueError, SegmenterError, OSError, RuntimeError) as error:
            self.get_logger().error(f"bad parameters ({error}); using the default settings")
            self.settings = default_settings(self.settings)
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
        # A detect (and the continuous timer, which runs the same pipeline and its caches)
        # and a placement check are served side by side: the bring-up asks the in-hand check
        # while the look at the pile for the next pick runs. A check shares no mutable state
        # with a detect but the camera inputs (``_input_lock``), the segmenter's memory
        # (locked in it) and the warning filter (thread-safe): docs/ARCHITECTURE.md.
        looking, checking = MutuallyExclusiveCallbackGroup(), MutuallyExclusiveCallbackGroup()
        self.create_service(
            DetectDominoes, "perception/detect", self._on_detect, callback_group=looking
        )
        self.create_service(
            CheckPlacement,
            "perception/check_placement",
            self._on_check_placement,
            callback_group=checking,
        )
        self.last_processed: dict[str, float] = {}
        self.repeated_warnings = RepeatFilter(WARNING_REPEAT)
        self.timer = self.create_timer(
            1.0 / self.settings.rate, self._on_timer, callback_group=looking
        )
        mode = f"continuous at {self.settings.rate} Hz" if self.settings.continuous else ""
        extrinsics = "/tf" if self.settings.extrinsics_from_tf else "the scenario"
        self.get_logger().info(
            f"ready: backend {self.pipeline.segmenter.name}, cameras {self.camera_names} "
            f"(extrinsics from {extrinsics}), {mode or 'on demand only'}; "
            "services /perception/detect, /perception/check_placement"
        )

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        changed = {p.name: p.value for p in parameters}
        fixed = [name for name in START_UP_PARAMETERS if name in changed]
        if fixed:
            reason = f"{', '.join(fixed)}: read at start-up; restart the node to change them"
            self.get_logger().error(f"rejected parameter update: {reason}")
            return SetParametersResult(successful=False, reason=reason)
        try:
            settings = self.parameters.read(parameters)
            pipeline = configured_pipeline(self.scenario, settings)
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
            time.sleep(0.02)  # the input callbacks run on another executor thread

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
        ahead = not_before - stamp_seconds(camera.colors[-1].header.stamp)
        if ahead > MAX_NOT_BEFORE_AHEAD:
            raise ValueError(
                f"not_before is {ahead:.3g} s after the newest frame "
                f"(at most {MAX_NOT_BEFORE_AHEAD} s are waited for)"
            )
        tolerance = float(self.settings.sync_tolerance)
        pair = camera.latest_pair(tolerance, not_before)
        # frames stamped after not_before: on a loaded CPU the images of a frame arrive well
        # after the joint states that tell the caller its time has come (a stale frame from
        # before a placement once made a standing domino MISSING)
        wait = SYNC_WAIT if math.isinf(not_before) else float(self.settings.fresh_frame_timeout)
        deadline = time.monotonic() + wait
        while pair is None and time.monotonic() < deadline and self.context.ok():
            time.sleep(0.02)  # the input callbacks run on another executor thread
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
            return optical_pose(name, values)
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
            name: stamp_seconds(self.inputs[name].colors[-1].header.stamp)
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
        problem = self._unknown_cameras(names)
        if problem:
            response.success, response.message = False, problem
            self.get_logger().error(problem)
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
        problem = self._unknown_cameras(names) or expected_poses_problem(request)
        if problem:
            response.success, response.message = False, problem
            held = " (in hand)" if request.in_hand else ""
            self.get_logger().error(f"check_placement{held} rejected: {problem}")
            return response
        config = placement_config(request)
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
        fill_placement_response(response, placements, warnings)
        held = " held in the gripper" if request.in_hand else ""
        # where its wall time went: waiting for the frames (subscribing, the render, the
        # transfer) and the fits
        spent = f"frames {framed - started:.2f} s, fits {time.perf_counter() - framed:.2f} s"
        self.get_logger().info(
            f"placement check of {len(expected)}{held}: {response.message} ({spent})"
        )
        return response

    def _unknown_cameras(self, names: list[str]) -> str | None:
        unknown = [name for name in names if name not in self.inputs]
        return f"unknown cameras {unknown}; configured: {self.camera_names}" if unknown else None

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
            self.debug_pub.publish(debug_image(views, result, self.get_clock().now().to_msg()))
        summary = f"{len(detections)} dominoes found"
        return result, "; ".join([summary, *warnings])

    # ------------------------------------------------------------------ outputs
    def _publish(self, detections: list[Detection]) -> None:
        array = self._detection_array(detections)
        poses = PoseArray(header=array.header, poses=[d.pose for d in array.detections])
        self.poses_pub.publish(poses)
        self.detections_pub.publish(array)

    def _detection_array(self, detections: list[Detection]) -> DominoDetectionArray:
        return detection_array(detections, self.get_clock().now().to_msg())


def main(args: list[str] | None = None) -> None:
    tune_allocator()
    rclpy.init(args=args)
    try:
        node = PerceptionNode()
    except (ScenarioError, SegmenterError, ValueError) as error:
        print(f"perception_node: cannot start: {error}", flush=True)
        rclpy.try_shutdown()
        raise SystemExit(2) from None
    spin_until_shutdown(node, DrainingExecutor(num_threads=EXECUTOR_THREADS))


if __name__ == "__main__":
    main()

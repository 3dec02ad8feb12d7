"""sim_node: the simulated DOM-BOT cell exposed over ROS 2 as a real cell would be.

Publishes ``/clock``, ``/joint_states``, per camera colour, depth and camera_info, and
``/sim/domino_ground_truth`` (evaluation only); serves the arm and gripper actions at
ros2_control's names (``control_msgs`` FollowJointTrajectory at ``TRAJECTORY_ACTION``,
GripperCommand at ``GRIPPER_ACTION``, its position the finger opening) and
``/sim/reset``. The simulation runs in the main thread, paced to ``real_time_factor``;
ROS callbacks run on a multi-threaded executor and reach the world under one lock.
After each trajectory and gripper goal it logs the dominoes that moved ``log_moved_mm``
or more meanwhile (the truth, for whoever reads the log; nothing else sees it).

Frames, as robot_state_publisher and a calibrated camera mount would give them: ``/tf``
(arm and gripper links at ``tf_rate``, the dominoes at ``domino_tf_rate``),
``/tf_static`` (arm base, table, fixed links, the cameras' optical frames) and
``/robot_description``, both transient local.
"""

from __future__ import annotations

import math
import queue
import sys
import threading
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass
from pathlib import Path
from typing import TypeVar

import numpy as np
import rclpy
from control_msgs.action import FollowJointTrajectory, GripperCommand
from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Twist, Vector3
from pydrake.math import RigidTransform
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header, String
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectoryPoint

from dombot_description.allocator import tune_allocator
from dombot_description.node_shutdown import stop_quietly_on_shutdown
from dombot_description.pose_messages import pose_message, seconds_of, time_message
from dombot_description.robot_description import robot_urdf
from dombot_msgs.msg import DominoState, DominoStateArray
from dombot_msgs.srv import ResetSim
from dombot_sim.cameras import CameraFrame
from dombot_sim.frames import FrameTransform, camera_transforms
from dombot_sim.motion_watch import describe_motion, take_snapshot
from dombot_sim.sleeping import SleepSettings
from dombot_sim.trajectory import INVALID_JOINTS, TrajectoryError, build_trajectory
from dombot_sim.world import CONTACT_APPROXIMATIONS, CellWorld, WorldConfig

T = TypeVar("T")
MAX_DOMINOES = 200
# ros2_control's names: joint_trajectory_controller "arm_controller", gripper action
# controller "gripper_controller".
TRAJECTORY_ACTION = "/arm_controller/follow_joint_trajectory"
GRIPPER_ACTION = "/gripper_controller/gripper_cmd"
FEEDBACK_PERIOD = 0.1  # s wall between action feedback messages
DEFAULT_GOAL_TOLERANCE = 0.01  # rad
GOAL_SETTLE_TIME = 0.5  # s simulated allowed after the trajectory ends, by default
GRIPPER_STALL_SPEED = 1e-3  # m/s
GRIPPER_STALL_TIME = 0.1  # s simulated below that speed
# s a finished goal (and so its request) is kept for its result: rclpy's default, 900 s,
# kept every 100,000-point goal of a fuzz run alive, 1.3 GB after 1,000 goals
RESULT_TIMEOUT = 60.0
RATE_FIELDS = {
    "joint_state_rate": "joint_states",
    "camera_rate": "cameras",
    "ground_truth_rate": "ground_truth",
    "tf_rate": "tf",
    "domino_tf_rate": "domino_tf",
    "real_time_factor": "real_time_factor",
}
RESTART_PARAMETERS = (
    "scenario",
    "time_step",
    "contact_approximation",
    "cameras",
    "meshcat",
    "meshcat_recording_path",
    "sleeping",
)
RATES = ("joint_state_rate", "camera_rate", "ground_truth_rate", "tf_rate", "domino_tf_rate")
# Images and camera_info: RELIABLE keep-last 5 (sensor data's depth). A reliable writer
# serves reliable readers and best-effort ones (perception subscribes with sensor-data QoS,
# as it must for a best-effort camera driver); a best-effort writer would serve only
# best-effort readers. docs/ARCHITECTURE.md, "Quality of service".
CAMERA_QOS = QoSProfile(depth=5)
TF_QOS = QoSProfile(depth=100)  # tf2_ros TransformBroadcaster
# tf2_ros StaticTransformBroadcaster and robot_state_publisher's /robot_description: the
# last message, kept for subscribers that come later
LATCHED_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


class WorldLock:
    """The world's lock, with priority for ROS callbacks over the simulation loop.

    A plain lock starves callbacks when the loop runs as fast as possible: the loop
    releases and re-acquires it before a waiting thread wakes. The loop therefore steps
    aside (``loop_turn``) while any callback is waiting.
    """

    def __init__(self) -> None:
        self._lock = threading.RLock()
        self._waiting = 0
        self._count_lock = threading.Lock()

    @contextmanager
    def loop_turn(self) -> Iterator[None]:
        while self._waiting:
            time.sleep(0.0005)
        with self._lock:
            yield

    def __enter__(self) -> None:
        with self._count_lock:
            self._waiting += 1
        self._lock.acquire()
        with self._count_lock:
            self._waiting -= 1

    def __exit__(self, *exc) -> None:
        self._lock.release()


@dataclass(frozen=True)
class Rates:
    joint_states: float
    cameras: float
    ground_truth: float
    tf: float
    domino_tf: float
    real_time_factor: float


class SimNode(Node):
    def __init__(self) -> None:
        super().__init__("sim_node")
        self._declare_parameters()
        self._lock = WorldLock()
        self._loop_tasks: queue.Queue[Callable[[], None]] = queue.Queue()
        self._generation = 0  # bumped by reset and by new trajectory goals (preemption)
        self._resets = 0
        self.rates = self._read_rates()
        config = WorldConfig(
            scenario_path=self._param("scenario") or None,
            time_step=self._param("time_step"),
            contact_approximation=self._param("contact_approximation"),
            cameras=self._param("cameras"),
            meshcat=self._param("meshcat"),
            domino_capacity=self._param("domino_count"),
            sleep=SleepSettings(enabled=self._param("sleeping")),
        )
        self.world = CellWorld(config)
        self.world.trouble_listener = self.get_logger().warning
        if self.world.meshcat_url():
            self.get_logger().info(f"Meshcat: {self.world.meshcat_url()}")
            if self._param("meshcat_recording_path"):
                self.world.start_meshcat_recording()
        self._make_interfaces()
        self._publish_description()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._reset(self._param("domino_count"), self._param("seed"))

    # ------------------------------------------------------------------ parameters
    def _declare_parameters(self) -> None:
        defaults = {
            "scenario": "",
            "domino_count": 30,
            "seed": 0,
            "time_step": 0.001,
            "contact_approximation": "similar",
            "real_time_factor": 1.0,
            "joint_state_rate": 100.0,
            "camera_rate": 2.0,
            "ground_truth_rate": 2.0,
            "tf_rate": 100.0,  # at most one /tf message per tick (joint_state_rate)
            "domino_tf_rate": 2.0,  # 0: no domino_N frames
            "cameras": True,
            "meshcat": False,
            # with meshcat: record what Meshcat shows, written here as HTML on shutdown
            "meshcat_recording_path": "",
            "sleeping": True,
            "log_moved_mm": 1.0,  # 0: no log of the dominoes that moved during a goal
        }
        for name, value in defaults.items():
            self.declare_parameter(name, value)
        problems = self._parameter_problems(
            {name: self.get_parameter(name).value for name in defaults}
        )
        if problems:
            raise ValueError("; ".join(problems))

    def _param(self, name: str):
        return self.get_parameter(name).value

    @staticmethod
    def _parameter_problems(values: dict) -> list[str]:
        problems = []
        for name in RATES:
            if name in values and not (values[name] >= 0.0 and math.isfinite(values[name])):
                problems.append(f"{name} must be a finite rate >= 0 Hz, got {values[name]}")
        if "joint_state_rate" in values and not values["joint_state_rate"] > 0.0:
            problems.append("joint_state_rate must be > 0 Hz (it is the simulation tick)")
        if "real_time_factor" in values and not values["real_time_factor"] >= 0.0:
            problems.append(
                f"real_time_factor must be >= 0 (0: as fast as possible), "
                f"got {values['real_time_factor']}"
            )
        if "time_step" in values and not 0.0 < values["time_step"] <= 0.01:
            problems.append(f"time_step must be in (0, 0.01] s, got {values['time_step']}")
        approximation = values.get("contact_approximation")
        if approximation is not None and approximation not in CONTACT_APPROXIMATIONS:
            problems.append(
                f"contact_approximation must be one of {sorted(CONTACT_APPROXIMATIONS)}, "
                f"got {approximation!r}"
            )
        if "log_moved_mm" in values and not 0.0 <= values["log_moved_mm"] < math.inf:
            problems.append(
                f"log_moved_mm must be a finite distance >= 0, got {values['log_moved_mm']}"
            )
        if values.get("meshcat_recording_path") and not values.get("meshcat", True):
            problems.append("meshcat_recording_path needs meshcat:=true")
        if "domino_count" in values and not 0 <= values["domino_count"] <= MAX_DOMINOES:
            problems.append(f"domino_count must be 0..{MAX_DOMINOES}, got {values['domino_count']}")
        if "seed" in values and values["seed"] < 0:
            problems.append(f"seed must be >= 0, got {values['seed']}")
        return problems

    def _read_rates(self) -> Rates:
        return Rates(
            joint_states=self._param("joint_state_rate"),
            cameras=self._param("camera_rate"),
            ground_truth=self._param("ground_truth_rate"),
            tf=self._param("tf_rate"),
            domino_tf=self._param("domino_tf_rate"),
            real_time_factor=self._param("real_time_factor"),
        )

    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        fixed = [p.name for p in parameters if p.name in RESTART_PARAMETERS]
        if fixed:
            return SetParametersResult(
                successful=False, reason=f"{', '.join(fixed)} can only be set at start-up"
            )
        problems = self._parameter_problems({p.name: p.value for p in parameters})
        if problems:
            self.get_logger().error("rejected parameters: " + "; ".join(problems))
            return SetParametersResult(successful=False, reason="; ".join(problems))
        current = dict(self.rates.__dict__)
        for parameter in parameters:
            if parameter.name in RATE_FIELDS:
                current[RATE_FIELDS[parameter.name]] = parameter.value
        self.rates = Rates(**current)
        return SetParametersResult(successful=True)

    def save_meshcat_recording(self) -> None:
        """Write Meshcat's recording to ``meshcat_recording_path`` (if asked for)."""
        path = self._param("meshcat_recording_path")
        if not path or self.world.meshcat is None:
            return
        try:
            with self._lock:
                self.world.save_meshcat_recording(Path(path))
            self.get_logger().info(f"Meshcat recording written to {path}")
        except OSError as error:
            self.get_logger().error(f"could not write the Meshcat recording {path}: {error}")

    # ------------------------------------------------------------------ interfaces
    def _make_interfaces(self) -> None:
        group = ReentrantCallbackGroup()
        self._clock_pub = self.create_publisher(Clock, "/clock", 10)
        self._joint_pub = self.create_publisher(JointState, "/joint_states", 10)
        self._truth_pub = self.create_publisher(DominoStateArray, "/sim/domino_ground_truth", 2)
        self._tf_pub = self.create_publisher(TFMessage, "/tf", TF_QOS)
        self._camera_pubs = {}
        for name in self.world.camera_names:
            self._camera_pubs[name] = (
                self.create_publisher(Image, f"/{name}/color/image_raw", CAMERA_QOS),
                self.create_publisher(Image, f"/{name}/depth/image_raw", CAMERA_QOS),
                self.create_publisher(CameraInfo, f"/{name}/color/camera_info", CAMERA_QOS),
                self.create_publisher(CameraInfo, f"/{name}/depth/camera_info", CAMERA_QOS),
            )
        self.create_service(ResetSim, "/sim/reset", self._on_reset, callback_group=group)
        self._trajectory_server = ActionServer(
            self,
            FollowJointTrajectory,
            TRAJECTORY_ACTION,
            execute_callback=self._execute_trajectory,
            goal_callback=lambda _: GoalResponse.ACCEPT,
            cancel_callback=lambda _: CancelResponse.ACCEPT,
            callback_group=group,
            result_timeout=RESULT_TIMEOUT,
        )
        self._gripper_server = ActionServer(
            self,
            GripperCommand,
            GRIPPER_ACTION,
            execute_callback=self._execute_gripper,
            goal_callback=lambda _: GoalResponse.ACCEPT,
            cancel_callback=lambda _: CancelResponse.ACCEPT,
            callback_group=group,
            result_timeout=RESULT_TIMEOUT,
        )

    # ------------------------------------------------------------------ simulation loop
    def run(self, stop: threading.Event) -> None:
        """Advance the world tick by tick, publish, and keep pace with the real-time factor."""
        next_camera = next_truth = next_tf = next_domino_tf = 0.0
        wall_start, sim_start = time.monotonic(), self.world.time
        factor = self.rates.real_time_factor
        while not stop.is_set() and rclpy.ok():
            rates = self.rates
            if rates.real_time_factor != factor:
                wall_start, sim_start, factor = (
                    time.monotonic(),
                    self.world.time,
                    rates.real_time_factor,
                )
            with self._lock.loop_turn():
                while not self._loop_tasks.empty():
                    self._loop_tasks.get()()
                self.world.advance(1.0 / rates.joint_states)
                now = self.world.time
                self._publish_state(now)
                if rates.cameras > 0.0 and now >= next_camera and self.world.camera_names:
                    self._publish_cameras(self.world.render(labels=False))
                    next_camera = now + 1.0 / rates.cameras
                if rates.ground_truth > 0.0 and now >= next_truth:
                    self._publish_truth(now)
                    next_truth = now + 1.0 / rates.ground_truth
                if rates.tf > 0.0 and now >= next_tf:
                    self._publish_tf(now, self.world.link_frames())
                    next_tf = now + 1.0 / rates.tf
                if rates.domino_tf > 0.0 and now >= next_domino_tf:
                    self._publish_tf(now, self.world.domino_frames())
                    next_domino_tf = now + 1.0 / rates.domino_tf
            if factor > 0.0:
                ahead = sim_start + (time.monotonic() - wall_start) * factor
                delay = (now - ahead) / factor
                if delay > 0.0:
                    time.sleep(delay)
                elif delay < -1.0:  # far behind (e.g. after a reset): do not race to catch up
                    wall_start, sim_start = time.monotonic(), now

    # ------------------------------------------------------------------ publishing
    def _publish_state(self, now: float) -> None:
        now_stamp = time_message(now)
        self._clock_pub.publish(Clock(clock=now_stamp))
        sample = self.world.joint_state()
        self._joint_pub.publish(
            JointState(
                header=Header(stamp=now_stamp, frame_id=""),
                name=list(sample.names),
                position=sample.position.tolist(),
                velocity=sample.velocity.tolist(),
                effort=sample.effort.tolist(),
            )
        )

    def _publish_description(self) -> None:
        """/robot_description and /tf_static, once: transient local, so subscribers that
        come later get them (the node keeps the publishers)."""
        latched = {
            topic: self.create_publisher(kind, topic, LATCHED_QOS)
            for topic, kind in (("/robot_description", String), ("/tf_static", TFMessage))
        }
        latched["/robot_description"].publish(String(data=robot_urdf(self.world.scenario)))
        fixed = self.world.fixed_frames() + camera_transforms(self.world.scenario.cameras)
        latched["/tf_static"].publish(tf_message(self.world.time, fixed))

    def _publish_tf(self, now: float, frames: list[FrameTransform]) -> None:
        if frames:
            self._tf_pub.publish(tf_message(now, frames))

    def _publish_cameras(self, frames: dict[str, CameraFrame]) -> None:
        for name, frame in frames.items():
            color_pub, depth_pub, color_info_pub, depth_info_pub = self._camera_pubs[name]
            header = Header(stamp=time_message(frame.time), frame_id=f"{name}_optical")
            height, width = frame.depth.shape
            color_pub.publish(
                Image(
                    header=header,
                    height=height,
                    width=width,
                    encoding="rgb8",
                    is_bigendian=0,
                    step=3 * width,
                    data=frame.rgb.tobytes(),
                )
            )
            depth_pub.publish(
                Image(
                    header=header,
                    height=height,
                    width=width,
                    encoding="32FC1",
                    is_bigendian=0,
                    step=4 * width,
                    data=frame.depth.astype("<f4").tobytes(),
                )
            )
            info = camera_info(frame, header)
            color_info_pub.publish(info)
            depth_info_pub.publish(info)

    def _publish_truth(self, now: float) -> None:
        message = DominoStateArray(header=Header(stamp=time_message(now), frame_id="world"))
        for domino in self.world.domino_truth():
            if domino.in_use:
                message.dominoes.append(
                    DominoState(
                        name=domino.name,
                        pose=pose_message(domino.X_WD),
                        twist=twist_message(domino.velocity),
                        upright=domino.upright,
                    )
                )
        self._truth_pub.publish(message)

    # ------------------------------------------------------------------ reset
    def _on_reset(self, request: ResetSim.Request, response: ResetSim.Response):
        if not 0 <= request.domino_count <= MAX_DOMINOES:
            response.success = False
            response.message = f"domino_count must be 0..{MAX_DOMINOES}, got {request.domino_count}"
            self.get_logger().error(f"/sim/reset refused: {response.message}")
            return response
        try:
            report = self._in_loop(lambda: self._reset(request.domino_count, request.seed))
        except ValueError as error:  # world.reset's checks, before anything changed
            response.success, response.message = False, str(error)
            self.get_logger().error(f"/sim/reset refused: {error}")
            return response
        response.success = report.settled
        response.settle_time = report.settle_time
        response.message = (
            f"poured {report.domino_count} dominoes (seed {report.seed}); "
            + ("settled" if report.settled else "STILL MOVING")
            + f" after {report.settle_time:.2f} s simulated ({report.wall_time:.1f} s wall)"
        )
        return response

    def _in_loop(self, task: Callable[[], T]) -> T:
        """Run ``task`` in the simulation thread and wait for it.

        Resets may rebuild the world, and VTK's render window belongs to the thread that
        renders; a rebuild in a callback thread left the cameras without a GL context.
        """
        done = threading.Event()
        outcome: dict[str, object] = {}

        def wrapped() -> None:
            try:
                outcome["value"] = task()
            except Exception as error:  # handed to the waiting callback
                outcome["error"] = error
            done.set()

        self._loop_tasks.put(wrapped)
        done.wait()
        if "error" in outcome:
            raise outcome["error"]
        return outcome["value"]

    def _reset(self, count: int, seed: int):
        self.get_logger().info(f"pouring {count} dominoes (seed {seed}) ...")
        with self._lock:
            self._generation += 1
            self._resets += 1
            report = self.world.reset(count, seed)
        summary = (
            f"pile of {count} (seed {seed}) %s after {report.settle_time:.2f} s simulated, "
            f"{report.wall_time:.1f} s wall"
        )
        if report.settled:
            self.get_logger().info(summary % "settled")
        else:
            self.get_logger().warning(summary % "STILL MOVING")
        return report

    # ------------------------------------------------------------------ goals, watched
    def _watched(self, motion: str, execute: Callable[[object], T], goal_handle) -> T:
        """Execute the goal; then log which dominoes moved meanwhile (not across a reset)."""
        threshold = self._param("log_moved_mm") * 1e-3
        if threshold <= 0.0:
            return execute(goal_handle)
        with self._lock:
            before, resets = take_snapshot(self.world), self._resets
        result = execute(goal_handle)
        with self._lock:
            after = take_snapshot(self.world) if resets == self._resets else None
        if after is None:
            return result
        moved = describe_motion(before, after, threshold)
        if moved:
            self.get_logger().info(f"during the {motion}: " + "; ".join(moved))
        return result

    def _execute_trajectory(self, goal_handle) -> FollowJointTrajectory.Result:
        return self._watched("trajectory", self._follow_trajectory, goal_handle)

    def _execute_gripper(self, goal_handle) -> GripperCommand.Result:
        return self._watched("gripper motion", self._move_gripper, goal_handle)

    # ------------------------------------------------------------------ trajectory action
    def _follow_trajectory(self, goal_handle) -> FollowJointTrajectory.Result:
        goal = goal_handle.request
        points = goal.trajectory.points
        with self._lock:
            try:
                _check_no_multi_dof(goal.multi_dof_trajectory.joint_names)
                spline = build_trajectory(
                    goal.trajectory.joint_names,
                    [seconds_of(p.time_from_start) for p in points],
                    [list(p.positions) for p in points],
                    [list(p.velocities) for p in points]
                    if _all_have(points, "velocities")
                    else None,
                    self.world.joint_state().position[:7],
                    self.world.arm_limits(),
                    unused={
                        "accelerations": [p.accelerations for p in points],
                        "effort": [p.effort for p in points],
                    },
                )
            except TrajectoryError as error:  # the running goal, if any, goes on
                self.get_logger().error(f"{TRAJECTORY_ACTION} rejected: {error}")
                goal_handle.abort()
                # the handle keeps the request RESULT_TIMEOUT: drop what may be 100,000 points
                goal.trajectory.points, goal.trajectory.joint_names = [], []
                return FollowJointTrajectory.Result(error_code=error.code, error_string=str(error))
            self._generation += 1  # preempts the running goal
            generation = self._generation
            end = self.world.follow_trajectory(spline)
        names = list(self.world.arm_joint_names)
        path_tolerance = tolerances(goal.path_tolerance, names, default=-1.0)
        goal_tolerance = tolerances(goal.goal_tolerance, names, default=DEFAULT_GOAL_TOLERANCE)
        settle = seconds_of(goal.goal_time_tolerance) or GOAL_SETTLE_TIME
        self.get_logger().info(
            f"executing a {spline.end_time():.2f} s trajectory ({len(points)} points)"
        )
        worst, last_feedback = 0.0, 0.0
        while True:
            time.sleep(0.005)
            with self._lock:
                if generation != self._generation:
                    return self._finish(
                        goal_handle, "abort", worst, None, "preempted by a newer goal or a reset"
                    )
                if goal_handle.is_cancel_requested:
                    self.world.hold_arm()
                    return self._finish(goal_handle, "cancel", worst, None, "canceled")
                now = self.world.time
                desired, velocity, acceleration = self.world.desired_arm_state()
                state = self.world.joint_state()
            error = state.position[:7] - desired
            worst = max(worst, float(np.abs(error).max()))
            violated = (path_tolerance > 0.0) & (np.abs(error) > path_tolerance)
            if violated.any():
                with self._lock:
                    self.world.hold_arm()
                j = int(np.argmax(violated))
                return self._finish(
                    goal_handle,
                    "abort",
                    worst,
                    error,
                    f"path tolerance violated on {names[j]}: {abs(error[j]):.4f} rad off the "
                    f"trajectory (allowed {path_tolerance[j]:.4f} rad)",
                    FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED,
                )
            if time.monotonic() - last_feedback > FEEDBACK_PERIOD:
                last_feedback = time.monotonic()
                goal_handle.publish_feedback(
                    feedback_message(names, now, (desired, velocity, acceleration), state)
                )
            if now < end:
                continue
            within = (goal_tolerance <= 0.0) | (np.abs(error) <= goal_tolerance)
            if within.all():
                return self._finish(goal_handle, "succeed", worst, error, "")
            if now > end + settle:
                joint = names[int(np.argmin(within))]
                return self._finish(
                    goal_handle,
                    "abort",
                    worst,
                    error,
                    f"{joint} ended {abs(error[names.index(joint)]):.4f} rad from the goal",
                    FollowJointTrajectory.Result.GOAL_TOLERANCE_VIOLATED,
                )

    def _finish(self, goal_handle, outcome, worst, error, message, code=0):
        """End the goal; ``error_string`` carries the tracking figures the control_msgs
        result has no fields for (largest error along the way, worst joint at the end)."""
        getattr(goal_handle, outcome)()
        figures = tracking_summary(worst, error)
        if outcome != "succeed":
            self.get_logger().warning(f"{TRAJECTORY_ACTION} {outcome}: {message}")
        else:
            self.get_logger().info(f"trajectory done, {figures}")
        return FollowJointTrajectory.Result(
            error_code=code if outcome != "cancel" else 0,
            error_string=f"{message or 'goal reached'}; {figures}",
        )

    # ------------------------------------------------------------------ gripper action
    def _move_gripper(self, goal_handle) -> GripperCommand.Result:
        goal = goal_handle.request.command  # position: the finger opening [m]
        with self._lock:
            try:
                self.world.command_gripper(goal.position, goal.max_effort)
            except ValueError as error:
                self.get_logger().error(f"{GRIPPER_ACTION} rejected: {error}")
                goal_handle.abort()
                state = self.world.gripper_state()
                return GripperCommand.Result(position=state.opening, effort=abs(state.force))
            start = self.world.time
            limit = start + self.world.gripper_stroke / self.world.config.gripper.speed + 1.0
        slow_since = None
        while True:
            time.sleep(0.005)
            with self._lock:
                if goal_handle.is_cancel_requested:
                    state = self.world.gripper_state()
                    self.world.command_gripper(state.opening, state.force_limit)
                    goal_handle.canceled()
                    return gripper_result(state, reached=False, stalled=False)
                now, state = self.world.time, self.world.gripper_state()
            reached = abs(state.opening - goal.position) < 1e-3
            slow = abs(state.opening_rate) < GRIPPER_STALL_SPEED and now - start > 0.05
            slow_since = (slow_since or now) if slow else None
            stalled = (
                not reached
                and slow_since is not None
                and now - slow_since > GRIPPER_STALL_TIME
                and abs(state.force) >= 0.99 * state.force_limit
            )
            goal_handle.publish_feedback(gripper_feedback(state, reached, stalled))
            if reached or stalled or now > limit:
                goal_handle.succeed()
                self.get_logger().info(
                    f"gripper at {state.opening * 1e3:.1f} mm, force {abs(state.force):.1f} N"
                    + (" (stalled on an object)" if stalled else "")
                )
                return gripper_result(state, reached, stalled)


# ---------------------------------------------------------------------- conversions
def _check_no_multi_dof(names) -> None:
    if names:
        raise TrajectoryError(
            INVALID_JOINTS,
            f"multi_dof_trajectory names {list(names)}; the arm has single-axis joints only",
        )


def _all_have(points, field_name: str) -> bool:
    return bool(points) and all(len(getattr(p, field_name)) > 0 for p in points)


def tolerances(entries, names: list[str], default: float) -> np.ndarray:
    """Per-joint position tolerance from JointTolerance entries (0: default, < 0: none)."""
    values = np.full(len(names), default)
    for entry in entries:
        if entry.name in names and entry.position != 0.0:
            values[names.index(entry.name)] = entry.position
    return values


def twist_message(velocity: np.ndarray) -> Twist:
    twist = Twist()
    twist.angular.x, twist.angular.y, twist.angular.z = (float(v) for v in velocity[:3])
    twist.linear.x, twist.linear.y, twist.linear.z = (float(v) for v in velocity[3:])
    return twist


def tf_message(now: float, frames: list[FrameTransform]) -> TFMessage:
    stamp = time_message(now)
    return TFMessage(
        transforms=[
            TransformStamped(
                header=Header(stamp=stamp, frame_id=frame.parent),
                child_frame_id=frame.child,
                transform=transform_message(frame.X_PC),
            )
            for frame in frames
        ]
    )


def transform_message(pose: RigidTransform) -> Transform:
    """With Drake's quaternion: scipy's conversion cost ~20x more per frame (bench_tf)."""
    x, y, z = pose.translation()
    q = pose.rotation().ToQuaternion()
    return Transform(
        translation=Vector3(x=x, y=y, z=z), rotation=Quaternion(x=q.x(), y=q.y(), z=q.z(), w=q.w())
    )


def camera_info(frame: CameraFrame, header: Header) -> CameraInfo:
    height, width = frame.depth.shape
    intrinsics = frame.K
    return CameraInfo(
        header=header,
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=[0.0] * 5,
        k=intrinsics.ravel().tolist(),
        r=np.eye(3).ravel().tolist(),
        p=np.hstack([intrinsics, np.zeros((3, 1))]).ravel().tolist(),
    )


def tracking_summary(worst: float, error: np.ndarray | None) -> str:
    summary = f"largest tracking error {worst:.2e} rad"
    if error is None:
        return summary
    return summary + f", when it ended {float(np.abs(error).max()):.2e} rad"


def feedback_message(names, now, desired_state, state) -> FollowJointTrajectory.Feedback:
    desired, velocity, acceleration = desired_state
    feedback = FollowJointTrajectory.Feedback()
    feedback.header.stamp = time_message(now)
    feedback.joint_names = names
    feedback.desired = JointTrajectoryPoint(
        positions=desired.tolist(),
        velocities=velocity.tolist(),
        accelerations=acceleration.tolist(),
    )
    feedback.actual = JointTrajectoryPoint(
        positions=state.position[:7].tolist(), velocities=state.velocity[:7].tolist()
    )
    feedback.error = JointTrajectoryPoint(
        positions=(state.position[:7] - desired).tolist(),
        velocities=(state.velocity[:7] - velocity).tolist(),
    )
    return feedback


def gripper_result(state, reached: bool, stalled: bool) -> GripperCommand.Result:
    return GripperCommand.Result(
        position=state.opening, effort=abs(state.force), stalled=stalled, reached_goal=reached
    )


def gripper_feedback(state, reached: bool, stalled: bool) -> GripperCommand.Feedback:
    return GripperCommand.Feedback(
        position=state.opening, effort=abs(state.force), stalled=stalled, reached_goal=reached
    )


def spin_forever(executor: MultiThreadedExecutor, node: Node) -> None:
    """Spin until shutdown; a callback that raises is logged and the node keeps serving."""
    while rclpy.ok():
        try:
            executor.spin()
        except (KeyboardInterrupt, ExternalShutdownException):
            return
        except Exception as error:  # one bad callback must not stop the node
            node.get_logger().error(f"callback failed: {error!r}; still serving")


def main(args: list[str] | None = None) -> int:
    tune_allocator()
    rclpy.init(args=args)
    try:
        node = SimNode()
    except ValueError as error:
        print(f"sim_node: bad parameters: {error}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    executor = MultiThreadedExecutor(num_threads=4)
    executor.add_node(node)
    spinner = threading.Thread(target=spin_forever, args=(executor, node), daemon=True)
    spinner.start()
    stop = threading.Event()
    try:
        with stop_quietly_on_shutdown():
            node.run(stop)
    finally:
        stop.set()
        executor.shutdown(timeout_sec=2.0)
        spinner.join(timeout=2.0)
        node.save_meshcat_recording()
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())

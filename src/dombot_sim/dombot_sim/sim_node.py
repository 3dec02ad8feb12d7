"""sim_node: the simulated DOM-BOT cell exposed over ROS 2 as a real cell would be.

Publishes ``/clock``, ``/joint_states``, per camera colour, depth and camera_info (a
camera is rendered only while one of its topics has a subscriber, as a lazy camera
driver would), and ``/sim/domino_ground_truth`` (evaluation only); serves the arm and
gripper actions at ros2_control's names (``control_msgs`` FollowJointTrajectory at
``TRAJECTORY_ACTION``, GripperCommand at ``GRIPPER_ACTION``, its position the finger
opening) and ``/sim/reset``. The simulation runs in the main thread, paced to ``real_time_factor``;
ROS callbacks run on a multi-threaded executor and reach the world under one lock.
After each trajectory and gripper goal it logs the dominoes that moved ``log_moved_mm``
or more meanwhile (the truth, for whoever reads the log; nothing else sees it).

Frames, as robot_state_publisher and a calibrated camera mount would give them: ``/tf``
(arm and gripper links at ``tf_rate``, the dominoes at ``domino_tf_rate``),
``/tf_static`` (arm base, table, fixed links, the cameras' optical frames) and
``/robot_description``, both transient local.
"""

from __future__ import annotations

import os
import queue
import sys
import threading
import time
from collections.abc import Callable, Iterator, MutableMapping
from contextlib import contextmanager
from pathlib import Path
from typing import TypeVar

import rclpy
from ament_index_python.packages import get_package_share_directory
from control_msgs.action import FollowJointTrajectory, GripperCommand
from rcl_interfaces.msg import SetParametersResult
from rclpy.action import ActionServer, CancelResponse, GoalResponse
from rclpy.callback_groups import ReentrantCallbackGroup
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.qos import DurabilityPolicy, QoSProfile
from rosgraph_msgs.msg import Clock
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import Header, String
from tf2_msgs.msg import TFMessage

from dombot_adapters.node_shutdown import (
    BackgroundSpinner,
    DrainingExecutor,
    stop_quietly_on_shutdown,
)
from dombot_adapters.parameters import DataclassParameters
from dombot_adapters.pose_messages import pose_message, seconds_of, time_message
from dombot_description.allocator import release_memory, set_mmap_threshold, tune_allocator
from dombot_description.robot_description import robot_urdf
from dombot_msgs.msg import DominoState, DominoStateArray
from dombot_msgs.srv import ResetSim
from dombot_sim.cameras import CameraFrame, cameras_due
from dombot_sim.frames import FrameTransform, camera_transforms
from dombot_sim.goal_monitor import (
    GripperMonitor,
    Outcome,
    TrajectoryMonitor,
    tracking_summary,
)
from dombot_sim.motion_watch import describe_motion, take_snapshot
from dombot_sim.pacing import Pacer
from dombot_sim.sim_messages import (
    all_have,
    camera_info,
    check_no_multi_dof,
    feedback_message,
    goal_tolerances,
    gripper_feedback,
    gripper_result,
    tf_message,
    twist_message,
)
from dombot_sim.sim_parameters import MAX_DOMINOES, SimParameters
from dombot_sim.sleeping import SleepSettings
from dombot_sim.trajectory import TrajectoryError, build_trajectory
from dombot_sim.world import CellWorld, WorldConfig

T = TypeVar("T")
# ros2_control's names: joint_trajectory_controller "arm_controller", gripper action
# controller "gripper_controller".
TRAJECTORY_ACTION = "/arm_controller/follow_joint_trajectory"
GRIPPER_ACTION = "/gripper_controller/gripper_cmd"
FEEDBACK_PERIOD = 0.1  # s wall between action feedback messages
# s a finished goal (and so its request) is kept for its result: rclpy's default, 900 s,
# kept every 100,000-point goal of a fuzz run alive, 1.3 GB after 1,000 goals
RESULT_TIMEOUT = 60.0
BIG_GOAL_POINTS = 1000  # a refused goal this long leaves freed pages worth handing back
RESULT_CODES = {
    Outcome.SUCCEEDED: FollowJointTrajectory.Result.SUCCESSFUL,
    Outcome.PATH_TOLERANCE_VIOLATED: FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED,
    Outcome.GOAL_TOLERANCE_VIOLATED: FollowJointTrajectory.Result.GOAL_TOLERANCE_VIOLATED,
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
# Images and camera_info: RELIABLE keep-last 5 (sensor data's depth). A reliable writer
# serves reliable readers and best-effort ones (perception's `image_reliability`
# best_effort, as for a best-effort camera driver; its default is reliable); a best-effort
# writer would serve only best-effort readers. docs/ARCHITECTURE.md, "Quality of service".
CAMERA_QOS = QoSProfile(depth=5)
TF_QOS = QoSProfile(depth=100)  # tf2_ros TransformBroadcaster
# tf2_ros StaticTransformBroadcaster and robot_state_publisher's /robot_description: the
# last message, kept for subscribers that come later
LATCHED_QOS = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
DDS_PROFILES = "FASTRTPS_DEFAULT_PROFILES_FILE"  # Fast DDS 2's XML profiles file
DDS_PROFILE_FILE = "fastdds_sim_node.xml"  # in the package's share/config


class SimStoppedError(RuntimeError):
    """The simulation loop has ended: a request waiting for it is never served."""


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


class SimNode(Node):
    def __init__(self) -> None:
        super().__init__("sim_node")
        self.parameters = DataclassParameters(self, SimParameters)
        self.settings = self.parameters.read()  # raises ValueError: bad parameters
        self._lock = WorldLock()
        self._loop_tasks: queue.Queue[Callable[[], None]] = queue.Queue()
        self._generation = 0  # bumped by reset and by new trajectory goals (preemption)
        self._resets = 0
        # set when the simulation loop has ended for good: the world no longer moves, so
        # callbacks waiting for it return (the executor drains them before the node goes)
        self.stopped = threading.Event()
        config = WorldConfig(
            scenario_path=self.settings.scenario or None,
            time_step=self.settings.time_step,
            contact_approximation=self.settings.contact_approximation,
            cameras=self.settings.cameras,
            meshcat=self.settings.meshcat,
            domino_capacity=self.settings.domino_count,
            skip_still=self.settings.skip_still,
            sleep=SleepSettings(enabled=self.settings.sleeping),
        )
        self.world = CellWorld(config)
        self.world.trouble_listener = self.get_logger().warning
        if self.world.meshcat_url():
            self.get_logger().info(f"Meshcat: {self.world.meshcat_url()}")
            if self.settings.meshcat_recording_path:
                self.world.start_meshcat_recording()
        self._make_interfaces()
        self._publish_description()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self._reset(self.settings.domino_count, self.settings.seed)

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        fixed = [p.name for p in parameters if p.name in RESTART_PARAMETERS]
        if fixed:
            return SetParametersResult(
                successful=False, reason=f"{', '.join(fixed)} can only be set at start-up"
            )
        try:
            self.settings = self.parameters.read(parameters)
        except (ValueError, TypeError) as error:
            self.get_logger().error(f"rejected parameters: {error}")
            return SetParametersResult(successful=False, reason=str(error))
        return SetParametersResult(successful=True)

    def save_meshcat_recording(self) -> None:
        """Write Meshcat's recording to ``meshcat_recording_path`` (if asked for)."""
        path = self.settings.meshcat_recording_path
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
        self._next_frame = dict.fromkeys(self.world.camera_names, 0.0)  # s simulated
        self._audience: dict[str, tuple[int, ...]] = {}  # subscribers per camera topic
        self.frames_rendered = dict.fromkeys(self.world.camera_names, 0)
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
        """Advance the world tick by tick, publish, and keep pace with the real-time factor
        (``pacing``: at 0, the ticks in which the cell was still at real time) until
        ``stop`` or shutdown; ``stopped`` is set once it ends, however it ends."""
        try:
            self._run(stop)
        finally:
            self.stopped.set()

    def _run(self, stop: threading.Event) -> None:
        next_truth = next_tf = next_domino_tf = 0.0
        pacer = Pacer(self.settings.real_time_factor)
        while not stop.is_set() and rclpy.ok():
            rates = self.settings
            pacer.factor = rates.real_time_factor
            with self._lock.loop_turn():
                while not self._loop_tasks.empty():
                    self._loop_tasks.get()()
                self.world.skip_still = rates.skip_still
                skipped = self.world.skipped_time
                self.world.advance(1.0 / rates.joint_state_rate)
                now, still = self.world.time, self.world.skipped_time > skipped
                self._publish_state(now)
                if rates.camera_rate > 0.0:
                    self._render_watched(now, 1.0 / rates.camera_rate)
                if rates.ground_truth_rate > 0.0 and now >= next_truth:
                    self._publish_truth(now)
                    next_truth = now + 1.0 / rates.ground_truth_rate
                if rates.tf_rate > 0.0 and now >= next_tf:
                    self._publish_tf(now, self.world.link_frames())
                    next_tf = now + 1.0 / rates.tf_rate
                if rates.domino_tf_rate > 0.0 and now >= next_domino_tf:
                    self._publish_tf(now, self.world.domino_frames())
                    next_domino_tf = now + 1.0 / rates.domino_tf_rate
            delay = pacer.delay(now, time.monotonic(), still)
            if delay > 0.0:
                time.sleep(delay)

    # ------------------------------------------------------------------ publishing
    def _render_watched(self, now: float, period: float) -> None:
        """Render and publish the cameras someone subscribes to (a frame nobody takes
        costs ~25 ms of rendering and ~2 MB of copies): a camera someone starts watching,
        or one of whose topics gains a subscriber, gets a frame at this tick, then one a
        ``period`` (``cameras_due``)."""
        audience = {
            name: tuple(publisher.get_subscription_count() for publisher in publishers)
            for name, publishers in self._camera_pubs.items()
        }
        due = cameras_due(now, self._next_frame, audience, self._audience)
        self._audience = audience
        if not due:
            return
        frames = self.world.render(due, labels=False)
        for name in due:
            self._next_frame[name] = now + period
            self.frames_rendered[name] += 1
        self._publish_cameras(frames)

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
        except SimStoppedError as error:  # the node is going: no log line, rosout may be gone
            response.success, response.message = False, str(error)
            return response
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
        while not done.wait(0.1):
            if self.stopped.is_set() and not done.is_set():
                raise SimStoppedError("sim_node is stopping: the request was not served")
        if "error" in outcome:
            raise outcome["error"]
        return outcome["value"]

    def _reset(self, count: int, seed: int):
        self.get_logger().info(f"pouring {count} dominoes (seed {seed}) ...")
        with self._lock:
            self._generation += 1
            self._resets += 1
            set_mmap_threshold(self.world.step_block_size)  # for the pour
            report = self.world.reset(count, seed)
            set_mmap_threshold(self.world.step_block_size)  # a bigger pile rebuilt the plant
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
        threshold = self.settings.log_moved_mm * 1e-3
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
        refusal = None
        with self._lock:
            try:
                check_no_multi_dof(goal.multi_dof_trajectory.joint_names)
                spline = build_trajectory(
                    goal.trajectory.joint_names,
                    [seconds_of(p.time_from_start) for p in points],
                    [list(p.positions) for p in points],
                    [list(p.velocities) for p in points]
                    if all_have(points, "velocities")
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
                refusal = FollowJointTrajectory.Result(
                    error_code=error.code, error_string=str(error)
                )
            else:
                self._generation += 1  # preempts the running goal
                generation = self._generation
                end = self.world.follow_trajectory(spline)
        if refusal is not None:  # outside the except block: its traceback held the lists
            if len(points) > BIG_GOAL_POINTS:
                del points  # the last reference to hundreds of thousands of point objects
                release_memory()
            return refusal
        names = list(self.world.arm_joint_names)
        monitor = TrajectoryMonitor(names, end, goal_tolerances(goal, names))
        self.get_logger().info(
            f"executing a {spline.end_time():.2f} s trajectory ({len(points)} points)"
        )
        last_feedback = 0.0
        while True:
            time.sleep(0.005)
            with self._lock:
                if self.stopped.is_set():
                    self._abort_stopped(goal_handle)
                    return FollowJointTrajectory.Result(error_string="sim_node stopped")
                if generation != self._generation:
                    return self._finish(
                        goal_handle, "abort", monitor, None, "preempted by a newer goal or a reset"
                    )
                if goal_handle.is_cancel_requested:
                    self.world.hold_arm()
                    return self._finish(goal_handle, "cancel", monitor, None, "canceled")
                now = self.world.time
                desired, velocity, acceleration = self.world.desired_arm_state()
                state = self.world.joint_state()
            verdict = monitor.check(now, state.position[:7], desired)
            if verdict.outcome is Outcome.PATH_TOLERANCE_VIOLATED:
                with self._lock:
                    self.world.hold_arm()
            if verdict.outcome is not Outcome.RUNNING:
                return self._finish(
                    goal_handle,
                    "succeed" if verdict.outcome is Outcome.SUCCEEDED else "abort",
                    monitor,
                    verdict.error,
                    verdict.message,
                    RESULT_CODES[verdict.outcome],
                )
            if time.monotonic() - last_feedback > FEEDBACK_PERIOD:
                last_feedback = time.monotonic()
                goal_handle.publish_feedback(
                    feedback_message(names, now, (desired, velocity, acceleration), state)
                )

    @staticmethod
    def _abort_stopped(goal_handle) -> None:
        """End a goal the stopped loop would never finish. No log line, and the abort's
        status message may fail: Ctrl-C may have shut the context down."""
        with stop_quietly_on_shutdown():
            goal_handle.abort()

    def _finish(self, goal_handle, outcome, monitor, error, message, code=0):
        """End the goal; ``error_string`` carries the tracking figures the control_msgs
        result has no fields for (largest error along the way, worst joint at the end)."""
        getattr(goal_handle, outcome)()
        figures = tracking_summary(monitor.worst, error)
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
            monitor = GripperMonitor(goal.position, self.world.time, self.world.gripper_stroke_time)
        while True:
            time.sleep(0.005)
            with self._lock:
                if self.stopped.is_set():
                    self._abort_stopped(goal_handle)
                    return gripper_result(self.world.gripper_state(), reached=False, stalled=False)
                if goal_handle.is_cancel_requested:
                    state = self.world.gripper_state()
                    self.world.command_gripper(state.opening, state.force_limit)
                    goal_handle.canceled()
                    return gripper_result(state, reached=False, stalled=False)
                now, state = self.world.time, self.world.gripper_state()
            verdict = monitor.check(
                now, state.opening, state.opening_rate, state.force, state.force_limit
            )
            reached, stalled = verdict.reached, verdict.stalled
            goal_handle.publish_feedback(gripper_feedback(state, reached, stalled))
            if verdict.done:
                goal_handle.succeed()
                self.get_logger().info(
                    f"gripper at {state.opening * 1e3:.1f} mm, force {abs(state.force):.1f} N"
                    + (" (stalled on an object)" if stalled else "")
                )
                return gripper_result(state, reached, stalled)


def use_dds_profile(environ: MutableMapping[str, str] = os.environ) -> None:
    """Have Fast DDS read sim_node's writer settings (DDS_PROFILE_FILE: a heartbeat every
    0.1 s) unless the user chose a profiles file: a reliable writer repairs a frame its
    reader missed only at its next heartbeat, by default 3 s on, and in-hand checks
    waited up to 2.5 s for a frame so (docs/SIM.md, "Camera frames on time")."""
    share = Path(get_package_share_directory("dombot_sim"))
    environ.setdefault(DDS_PROFILES, str(share / "config" / DDS_PROFILE_FILE))


def main(args: list[str] | None = None) -> int:
    tune_allocator()
    use_dds_profile()  # before the DDS participant is made
    rclpy.init(args=args)
    try:
        node = SimNode()
    except ValueError as error:
        print(f"sim_node: bad parameters: {error}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    executor = DrainingExecutor(num_threads=4)
    executor.add_node(node)
    spinner = BackgroundSpinner(executor, node)
    stop = threading.Event()
    try:
        with stop_quietly_on_shutdown():
            node.run(stop)
    finally:
        stop.set()
        frames = ", ".join(f"{name} {count}" for name, count in node.frames_rendered.items())
        # the loop has ended (node.stopped): the callbacks still at work see it and return;
        # the node is destroyed only once they have (rclpy issue 893, node_shutdown)
        spinner.stop()
        node.save_meshcat_recording()
        # a logger of its own, not the node's (nor its child, which rclpy registers with
        # rosout): Ctrl-C may have shut the context down, and rosout would refuse the line
        logger = rclpy.logging.get_logger(f"{node.get_name()}.shutdown")
        logger.info(f"camera frames rendered: {frames or 'none (no cameras)'}")
        logger.info(
            f"simulated {node.world.time:.1f} s, of which the cell was still (no physics "
            f"steps) {node.world.skipped_time:.1f} s"
        )
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())

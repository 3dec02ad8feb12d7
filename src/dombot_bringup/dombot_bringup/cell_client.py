"""The bring-up's ROS side: the task core's ``Cell`` over the nodes' services and actions.

One node spins on a background executor; each method sends a request and waits for
its answer with a timeout, so the task loop reads like the procedure it is. Messages
become the plain types of ``task.cell`` once, at the door (``cell_messages``); the
services and actions it asks are named in ``cell_endpoints``.
"""

from __future__ import annotations

import threading
import time
from collections import defaultdict
from collections.abc import Callable, Iterator, Mapping, Sequence
from contextlib import contextmanager
from typing import Any

import numpy as np
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import GripperCommand as GripperGoal
from control_msgs.msg import JointTolerance
from geometry_msgs.msg import Point, Vector3
from rclpy.action import ActionClient
from rclpy.event_handler import SubscriptionEventCallbacks
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import Image, JointState

from dombot_adapters.node_shutdown import BackgroundSpinner
from dombot_adapters.pose_messages import (
    pose_matrix,
    pose_message,
    seconds_of,
    time_message,
)
from dombot_bringup.cell_endpoints import (
    ACTIVITIES,
    DETECT_SERVICE,
    DETECT_TIMEOUT,
    GRIPPER_ACTION,
    RESTART_TIMEOUT,
    SERVERS,
    SERVICES,
    TRAJECTORY_ACTION,
    SerialActionClient,
)
from dombot_bringup.cell_messages import (
    detections_of,
    geometry_pose,
    plan_of,
    pose_or_none,
    trajectory_message,
)
from dombot_bringup.qos import matching_qos
from dombot_bringup.task.cell import (
    CellError,
    Detections,
    Later,
    Meanwhile,
    Motion,
    PlacementCheck,
    PlaceRequest,
    Plan,
    Pose,
    Seen,
    StrikeRequest,
    Trajectory,
)
from dombot_msgs.msg import DominoStateArray
from dombot_msgs.srv import CheckPlacement, DetectDominoes, PlanPlace, PlanStrike, ResetSim

_RESTARTED = object()  # a call's server was started again before it answered


class CellClient:
    """The ``Cell`` of sim, perception and planner nodes; ``close()`` when done.

    ``watchdog`` is called while waiting for any answer; the bring-up passes its process
    group's check, so a node that dies mid-call is reported at once, by name, or
    started again. ``restarts`` says how often each node was started again: a request
    whose server was restarted while it waited is sent again to the new one.
    """

    def __init__(
        self,
        name: str = "bringup",
        watchdog: Callable[[], None] = lambda: None,
        restarts: Callable[[], Mapping[str, int]] = dict,
    ) -> None:
        self.node = Node(name, parameter_overrides=[Parameter("use_sim_time", value=False)])
        self._watchdog = watchdog
        self._restarts = restarts
        # per service: its server's restart count and request readers when last sent to
        self._sent_to: dict[str, tuple[int, frozenset[bytes]]] = {}
        self._clients = {n: self.node.create_client(t, n) for n, t in SERVICES.items()}
        self._trajectory = SerialActionClient(self.node, FollowJointTrajectory, TRAJECTORY_ACTION)
        self._gripper = SerialActionClient(self.node, GripperCommand, GRIPPER_ACTION)
        self._lock = threading.Lock()
        self._joint_state: JointState | None = None
        self._truth: DominoStateArray | None = None
        self._images: dict[str, Image | None] = {}  # latest frame of a picture asked for
        self._sim_time = 0.0
        self._received = 0  # joint states so far
        # simulated seconds that passed while waiting for each kind of answer (ACTIVITIES)
        self.simulated_by_activity: dict[str, float] = defaultdict(float)
        self.node.create_subscription(JointState, "/joint_states", self._on_joint_state, 10)
        self.node.create_subscription(
            DominoStateArray, "/sim/domino_ground_truth", self._on_truth, 2
        )
        executor = MultiThreadedExecutor(num_threads=2)
        executor.add_node(self.node)
        self._spinner = BackgroundSpinner(executor, self.node)

    def close(self) -> None:
        self._spinner.stop()  # before the node goes (node_shutdown.BackgroundSpinner)
        self.node.destroy_node()

    # ------------------------------------------------------------------ topics
    def _on_joint_state(self, message: JointState) -> None:
        with self._lock:
            self._joint_state = message
            self._received += 1
            self._sim_time = message.header.stamp.sec + message.header.stamp.nanosec * 1e-9

    def _on_truth(self, message: DominoStateArray) -> None:
        with self._lock:
            self._truth = message

    def _on_image(self, topic: str, message: Image) -> None:
        with self._lock:
            self._images[topic] = message

    def picture(self, camera: str, not_before: float, timeout: float = 30.0) -> np.ndarray:
        """An RGB frame (height x width x 3) of ``camera`` stamped at or after ``not_before``
        [s simulated]. Subscribed for this frame only (the bring-up wants a few pictures,
        not a stream: sim_node renders a camera only while someone subscribes), with the
        QoS the camera offers: in a run at load 17-20 a best-effort reader of sim_node's
        reliable camera got no frame for 30 s after the strike."""
        topic = f"/{camera}/color/image_raw"
        publishers = self._wait(
            lambda: self.node.get_publishers_info_by_topic(topic) or None, timeout, topic
        )
        with self._lock:
            self._images[topic] = None
        subscription = self.node.create_subscription(
            Image,
            topic,
            lambda m: self._on_image(topic, m),
            matching_qos(publishers, 2),
            # no QoS event handler: destroyed below while the executor may be building
            # its wait set, which rclpy does not guard for event handlers (InvalidHandle)
            event_callbacks=SubscriptionEventCallbacks(use_default_callbacks=False),
        )

        def fresh() -> Image | None:
            with self._lock:
                image = self._images[topic]
            if image is None or seconds_of(image.header.stamp) < not_before:
                return None
            return image

        try:
            image = self._wait(fresh, timeout, topic)
        finally:
            self.node.destroy_subscription(subscription)
        if image.encoding != "rgb8":
            raise CellError(f"{topic} sends {image.encoding}, not rgb8")
        rows = np.frombuffer(bytes(image.data), np.uint8).reshape(image.height, image.step)
        return rows[:, : 3 * image.width].reshape(image.height, image.width, 3)

    def joints(self) -> tuple[list[str], list[float]]:
        """The latest /joint_states (arm and fingers)."""
        with self._lock:
            state = self._joint_state or JointState()
        return list(state.name), list(state.position)

    @property
    def sim_time(self) -> float:
        """Simulated seconds, from the latest joint state."""
        with self._lock:
            return self._sim_time

    @property
    def time_spent(self) -> dict[str, float]:
        return self.simulated_by_activity

    def truth(self, newer_than: float = -1.0, timeout: float = 10.0) -> list[tuple[str, Pose]]:
        """The simulator's ground truth (for the report only), stamped after ``newer_than``."""

        def fresh() -> DominoStateArray | None:
            with self._lock:
                truth = self._truth
            if truth is None:
                return None
            stamp = truth.header.stamp.sec + truth.header.stamp.nanosec * 1e-9
            return truth if stamp > newer_than else None

        truth = self._wait(fresh, timeout, "/sim/domino_ground_truth")
        return [(domino.name, pose_matrix(domino.pose)) for domino in truth.dominoes]

    def wait_for_sim_time(self, seconds: float, timeout: float = 120.0) -> None:
        """Block until simulated time has advanced by ``seconds`` from now.

        "Now" is the first joint state received after the call: the latest one may be
        older than the last answer (a reset blocks the simulator's publishing).
        """
        received = self._received
        with self._spending("simulated time"):
            self._wait(lambda: self._received > received or None, timeout, "/joint_states")
            target = self.sim_time + seconds
            self._wait(lambda: self.sim_time >= target or None, timeout, "simulated time")

    def ready(self, names: Sequence[str]) -> bool:
        """Are these services (and both actions) available? Once they are, each one's
        request readers are remembered as its server's (``_await_server``): a server
        killed and counted restarted before this client's first request to it left
        readers that looked like a server, and the request sent to them was lost (the
        restart test's bring-up waited an hour for the planner's answer)."""
        if not (
            all(self._clients[n].service_is_ready() for n in names)
            and self._trajectory.server_is_ready()
            and self._gripper.server_is_ready()
            and self._joint_state is not None
        ):
            return False
        for name in names:
            served = (self._server_restarts(name), self._request_readers(name))
            self._sent_to.setdefault(name, served)
        return True

    # ------------------------------------------------------------------ services
    def call(self, name: str, request, timeout: float):
        """``request``'s answer; sent again (up to the restarts allowed) when its server
        was restarted before it answered: every server here answers from the request and
        the scene as it is now, so nothing else needs restoring."""
        return self.call_later(name, request, timeout)()

    def _server_restarts(self, name: str) -> int:
        return self._restarts().get(SERVERS[name], 0)

    def _await_server(self, name: str, timeout: float) -> None:
        """Wait until ``name`` is served, after a restart by the new server.

        A killed server's endpoints stay in the DDS graph until its lease runs out, and a
        request sent to them alone is lost: after a restart, wait for a request reader
        that was not there when this client last sent (and give the restarted node time
        to come back: the planner builds its plants first).
        """
        client = self._clients[name]
        generation = self._server_restarts(name)
        last_generation, last_readers = self._sent_to.get(name, (generation, frozenset()))
        old = last_readers if last_generation != generation else frozenset()
        self._wait(
            lambda: (client.service_is_ready() and bool(self._request_readers(name) - old)) or None,
            RESTART_TIMEOUT if old else min(timeout, 10.0),
            f"{name} (not available)",
        )
        self._sent_to[name] = (generation, self._request_readers(name))

    def _request_readers(self, name: str) -> frozenset[bytes]:
        """The DDS readers of ``name``'s requests (one per server process)."""
        readers = self.node.get_subscriptions_info_by_topic(f"rq{name}Request", no_mangle=True)
        return frozenset(bytes(reader.endpoint_gid) for reader in readers)

    def reset(self, pile: int, seed: int) -> str:
        request = ResetSim.Request(domino_count=pile, seed=seed)
        return self.call("/sim/reset", request, 600.0).message

    def detect(self, not_before: float = 0.0) -> Detections:
        """Perception's detections in frames stamped at or after ``not_before`` [s]."""
        request = DetectDominoes.Request(not_before=time_message(not_before))
        return detections_of(self.call(DETECT_SERVICE, request, DETECT_TIMEOUT))

    def detect_later(self, not_before: float) -> Later[Detections]:
        """``detect(not_before)`` sent now; calling the answer waits for it (only that wait
        counts as perception's time), or asks again when perception was restarted
        meanwhile."""
        request = DetectDominoes.Request(not_before=time_message(not_before))
        answer = self.call_later(DETECT_SERVICE, request, DETECT_TIMEOUT)
        return Later(lambda: detections_of(answer()), answer.answered)

    def call_later(self, name: str, request, timeout: float) -> Later[Any]:
        """``request`` sent to ``name`` now; calling the answer waits for it (only that
        wait counts as the service's activity), or sends it again, waiting, when the
        server was restarted meanwhile (not answered yet then)."""
        self._await_server(name, timeout)
        started = self._server_restarts(name)
        future = self._clients[name].call_async(request)

        def answer_or_restart():
            if future.done():
                return future.result()
            return _RESTARTED if self._server_restarts(name) != started else None

        def answer():
            with self._spending(name):
                response = self._wait(answer_or_restart, timeout, name)
            return self.call(name, request, timeout) if response is _RESTARTED else response

        return Later(answer, future.done)

    def check_placement(
        self, expected: Sequence[Pose], in_hand: bool = False, not_before: float = 0.0
    ) -> PlacementCheck:
        request = CheckPlacement.Request(
            expected=[pose_message(pose) for pose in expected],
            in_hand=in_hand,
            not_before=time_message(not_before),
        )
        answer = self.call("/perception/check_placement", request, 30.0)
        return PlacementCheck(
            answer.success,
            answer.message,
            tuple(Seen(s) for s in answer.status),
            tuple(pose_matrix(p) for p in answer.measured),
            tuple(answer.position_error),
            tuple(answer.tilt),
        )

    def plan_place(self, request: PlaceRequest) -> Plan:
        return self.plan_place_later(request)()

    def plan_place_later(self, request: PlaceRequest) -> Later[Plan]:
        start = {} if request.start is None else request.start
        message = PlanPlace.Request(
            start_state=JointState(name=list(start), position=[*start.values()]),
            domino_pose=pose_message(request.domino),
            grasp_pose=geometry_pose(request.grasp),
            grasp_width=0.0,
            place_pose=pose_message(request.place),
            standing_dominoes=[pose_message(p) for p in request.standing],
            pile_dominoes=[pose_message(p) for p in request.pile],
            pile_points=[Point(x=x, y=y, z=z) for x, y, z in request.pile_points.tolist()],
            pads_into_pile=request.pads_into_pile,
            time_budget=request.time_budget,
            holding=request.holding,
        )
        answer = self.call_later("/plan_place", message, request.time_budget + 30.0)

        def plan() -> Plan:
            response = answer()
            return plan_of(response, pose_or_none(response.held_above_place))

        return Later(plan, answer.answered)

    def plan_strike(self, request: StrikeRequest) -> Plan:
        sweep = np.zeros(2) if request.sweep is None else request.sweep
        message = PlanStrike.Request(
            domino_pose=pose_message(request.domino),
            standing_dominoes=[pose_message(p) for p in request.standing],
            sweep_direction=Vector3(x=float(sweep[0]), y=float(sweep[1]), z=0.0),
            push_distance=request.push_distance,
            time_budget=request.time_budget,
        )
        return plan_of(self.call("/plan_strike", message, request.time_budget + 30.0), None)

    # ------------------------------------------------------------------ actions
    def execute(
        self,
        trajectory: Trajectory,
        goal_tolerance: float = 0.0,
        path_tolerance: float = 0.0,
        *,
        meanwhile: Meanwhile | None = None,
    ) -> Motion:
        """Run ``trajectory``; each joint must end within ``goal_tolerance`` rad of its last
        point (0: the controller's default) within a second, and stay within
        ``path_tolerance`` of it on the way (0: not checked). The wall-clock timeout is
        generous: the simulator may run well below real time. ``meanwhile`` is called
        between polls for the result (``_wait``), on this thread."""
        goal = FollowJointTrajectory.Goal(
            trajectory=trajectory_message(trajectory),
            path_tolerance=[
                JointTolerance(name=name, position=path_tolerance)
                for name in trajectory.joint_names
            ],
            goal_tolerance=[
                JointTolerance(name=name, position=goal_tolerance)
                for name in trajectory.joint_names
            ],
            goal_time_tolerance=Duration(sec=1),
        )
        timeout = trajectory.duration * 60 + 120
        action = self._action_later(self._trajectory, goal, timeout, TRAJECTORY_ACTION, meanwhile)
        result = action()
        return Motion(result.error_code == 0, result.error_string)

    def gripper(
        self,
        position: float,
        max_effort: float,
        timeout: float = 180.0,
        *,
        meanwhile: Meanwhile | None = None,
    ) -> float:
        """Move the fingers to the opening ``position`` [m] (the gap between them);
        ``meanwhile`` as ``execute``'s."""
        return self.gripper_later(position, max_effort, timeout, meanwhile=meanwhile)()

    def gripper_later(
        self,
        position: float,
        max_effort: float,
        timeout: float = 180.0,
        *,
        meanwhile: Meanwhile | None = None,
    ) -> Later[float]:
        """``gripper(position, max_effort)`` sent now; taking the answer waits for it,
        calling ``meanwhile`` (as ``execute``'s)."""
        command = GripperGoal(position=float(position), max_effort=float(max_effort))
        goal = GripperCommand.Goal(command=command)
        result = self._action_later(self._gripper, goal, timeout, GRIPPER_ACTION, meanwhile)
        return Later(lambda: result().position, result.answered)

    def _action_later(
        self,
        client: ActionClient,
        goal,
        timeout: float,
        name: str,
        meanwhile: Meanwhile | None = None,
    ) -> Later[Any]:
        """``goal`` sent now; taking the answer waits for its acceptance and result (only
        that wait counts as ``name``'s activity: the arm may move meanwhile), calling
        ``meanwhile`` between polls."""
        if not client.wait_for_server(timeout_sec=10.0):
            raise CellError(f"{name} is not available")
        sent = client.send_goal_async(goal)

        def result():
            with self._spending(name):
                handle = self._wait(
                    lambda: sent.result() if sent.done() else None, 10.0, name, meanwhile
                )
                if not handle.accepted:
                    raise CellError(f"{name} refused the goal")
                answer = handle.get_result_async()
                done = self._wait(
                    lambda: answer.result() if answer.done() else None, timeout, name, meanwhile
                )
                return done.result

        return Later(result, sent.done)

    @contextmanager
    def _spending(self, name: str) -> Iterator[None]:
        """Count the simulated time that passes inside as ``name``'s activity."""
        start = self.sim_time
        try:
            yield
        finally:
            self.simulated_by_activity[ACTIVITIES[name]] += self.sim_time - start

    def _wait(self, poll, timeout: float, what: str, meanwhile: Meanwhile | None = None):
        """``poll()``'s first value but None, polled every 10 ms; ``meanwhile`` is called
        between polls (on this thread: the caller's, not the spinner's)."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline:
            value = poll()
            if value is not None:
                return value
            self._watchdog()
            if meanwhile is not None:
                meanwhile()
            time.sleep(0.01)
        raise CellError(f"no answer from {what} within {timeout:.0f} s")

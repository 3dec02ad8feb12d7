"""planner_node: serves /plan_place (dombot_msgs/srv/PlanPlace) and /plan_strike
(dombot_msgs/srv/PlanStrike).

A thin ROS adapter over ``planner`` and ``strike``: parameters are PlannerSettings' fields
(validated; a rejected update keeps the old values), /joint_states gives the start state
when a request has none (the latest once it shows the arm at rest, waited for up to
``start_rest_wait``), requests are checked and converted before they wait for the planner, and
every failure is answered with an error code and a message and logged with its stage and
the time spent. Both services run in a reentrant callback group on a
multi-threaded executor, so bad requests are answered at once while another request is
being planned (the two planners share shadow plants and plan one request at a time); a
request that cannot start planning within its time budget gets TIMEOUT, and so does one
arriving while MAX_WAITING others wait (the executor keeps threads free for bad requests).
"""

from __future__ import annotations

import dataclasses
import threading
import time
import traceback
from collections.abc import Callable

import numpy as np
import rclpy
from geometry_msgs.msg import Pose, Vector3
from rcl_interfaces.msg import ParameterDescriptor, SetParametersResult
from rclpy.callback_groups import MutuallyExclusiveCallbackGroup, ReentrantCallbackGroup
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from dombot_adapters.node_shutdown import (
    DrainingExecutor,
    spin_until_shutdown,
    stop_quietly_on_shutdown,
)
from dombot_adapters.parameters import DataclassParameters
from dombot_adapters.pose_messages import duration_message, pose_message
from dombot_description.allocator import release_memory, tune_allocator
from dombot_description.scenario import ScenarioError, load_scenario
from dombot_msgs.msg import TrajectorySegment
from dombot_msgs.srv import PlanPlace, PlanStrike
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.pick_place_plan import PickPlacePlan
from dombot_planner.plan_segments import GRIPPER_CLOSE, GRIPPER_OPEN, Plan
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import (
    MAX_PILE_DOMINOES,
    MAX_PILE_POINTS,
    MAX_STANDING,
    PickPlaceRequest,
    StrikeRequest,
    arm_positions,
    at_rest,
    check_sizes,
    finger_opening,
    pose_from,
)
from dombot_planner.settings import PlannerSettings
from dombot_planner.strike import StrikePlan, StrikePlanner

MAX_WAITING = 8  # requests that may wait for the planner at once (docs/PLANNER.md)
# executor threads: the waiting requests, the one being planned, /joint_states and one
# more, so a bad request never waits for a thread
EXECUTOR_THREADS = MAX_WAITING + 3

GRIPPER_EVENTS = {
    GRIPPER_OPEN: TrajectorySegment.GRIPPER_OPEN,
    GRIPPER_CLOSE: TrajectorySegment.GRIPPER_CLOSE,
}


def pose_of(message: Pose, what: str):
    p, o = message.position, message.orientation
    return pose_from([p.x, p.y, p.z], [o.w, o.x, o.y, o.z], what)


def is_unset(message: Pose) -> bool:
    """A grasp_pose left at the origin (inside the arm base): the planner chooses."""
    p = message.position
    return p.x == 0.0 and p.y == 0.0 and p.z == 0.0


def sweep_of(message: Vector3) -> np.ndarray | None:
    """A sweep direction, or None for a strike (the zero vector)."""
    direction = np.array([message.x, message.y, message.z])
    return None if not np.any(direction) else direction


def poses_of(poses: list[Pose], field: str) -> tuple:
    return tuple(pose_of(p, f"{field}[{i}]") for i, p in enumerate(poses))


class PlannerNode(Node):
    def __init__(self) -> None:
        super().__init__("planner_node")
        self.declare_parameter(
            "scenario", "", ParameterDescriptor(description="scenario YAML; empty: the default")
        )
        self.parameters = DataclassParameters(
            self, PlannerSettings, description="see docs/PLANNER.md"
        )
        try:
            self.scenario = load_scenario(self.get_parameter("scenario").value or None)
            settings = self.parameters.read()
        except (ScenarioError, ValueError, TypeError) as error:
            self.get_logger().fatal(f"cannot start: {error}")
            raise
        self._make_planners(settings)
        self.lock = threading.Lock()
        self.waiting = threading.BoundedSemaphore(MAX_WAITING)
        self.joint_state: JointState | None = None
        self.joint_state_changed = threading.Condition()
        self.add_on_set_parameters_callback(self._on_set_parameters)
        self.create_subscription(
            JointState,
            "joint_states",
            self._on_joint_state,
            10,
            callback_group=MutuallyExclusiveCallbackGroup(),
        )
        services = ReentrantCallbackGroup()
        self.create_service(PlanPlace, "plan_place", self._on_plan_place, callback_group=services)
        self.create_service(
            PlanStrike, "plan_strike", self._on_plan_strike, callback_group=services
        )
        self.get_logger().info(
            f"ready: /plan_place, /plan_strike on scenario {self.scenario.path.name}, "
            f"default time budget {settings.default_time_budget} s"
        )

    # ------------------------------------------------------------------ parameters
    def _make_planners(self, settings: PlannerSettings) -> None:
        self.planner = PickPlacePlanner(self.scenario, settings)
        self.striker = StrikePlanner(self.scenario, settings, plants=self.planner.plants)

    def _on_set_parameters(self, parameters) -> SetParametersResult:
        if any(p.name == "scenario" for p in parameters):
            return SetParametersResult(successful=False, reason="scenario is read at start only")
        try:
            settings = self.parameters.read(parameters)
        except (ValueError, TypeError) as error:
            self.get_logger().error(f"rejected parameter update: {error}")
            return SetParametersResult(successful=False, reason=str(error))
        with self.lock:
            self._make_planners(settings)
        self.get_logger().info(f"settings updated: {sorted(p.name for p in parameters)}")
        return SetParametersResult(successful=True)

    def _on_joint_state(self, message: JointState) -> None:
        with self.joint_state_changed:
            self.joint_state = message
            self.joint_state_changed.notify_all()

    # ------------------------------------------------------------------ services
    def _on_plan_place(self, request: PlanPlace.Request, response: PlanPlace.Response):
        def note(plan: PickPlacePlan) -> str:
            notes = {
                "domino turned in place first": plan.regrasped,
                "the pads nudge the pile": plan.nudged,
            }
            return "; ".join(words for words, applies in notes.items() if applies)

        return self._serve(
            "plan_place", response, lambda: (self.planner, self._place_request(request)), note
        )

    def _on_plan_strike(self, request: PlanStrike.Request, response: PlanStrike.Response):
        def note(plan: StrikePlan) -> str:
            return "gripper closed first" if plan.closes_gripper else ""

        return self._serve(
            "plan_strike", response, lambda: (self.striker, self._strike_request(request)), note
        )

    def _serve(self, service: str, response, convert: Callable, note: Callable[[Plan], str]):
        """Check and convert a request (answered at once), then plan it under the lock.

        ``convert()`` gives the planner and the request; ``note(plan)`` a remark or "".
        """
        began = time.monotonic()
        try:
            planner, plan_request = convert()
            planner.check(plan_request)  # answered before queueing
            budget = plan_request.time_budget or planner.settings.default_time_budget
            self._queue(budget)
            try:
                if planner.settings.budget_clock == "wall":  # the queue's wait counts
                    budget = max(budget - (time.monotonic() - began), 1e-3)
                plan = planner.plan(dataclasses.replace(plan_request, time_budget=budget))
            finally:
                self.lock.release()
            remark = note(plan)
            self._fill(response, plan, planner.settings.sample_period, remark)
            self.get_logger().info(
                f"{service}: planned in {time.monotonic() - began:.2f} s "
                f"({len(response.segments)} segments, "
                f"{sum(s.duration for s in plan.segments):.2f} s of motion"
                f"{', ' + remark if remark else ''})"
            )
        except PlanningError as error:
            self._fail(service, response, error, began)
        except Exception as error:  # the node must keep serving
            self.get_logger().error(traceback.format_exc())
            internal = PlanningError(ErrorCode.PLANNING_FAILED, "internal", repr(error))
            self._fail(service, response, internal, began)
        response.planning_time = time.monotonic() - began
        release_memory()
        return response

    def _queue(self, budget: float) -> None:
        """Wait for the planner (self.lock, held on return) among at most MAX_WAITING."""
        if not self.waiting.acquire(blocking=False):
            raise PlanningError(
                ErrorCode.TIMEOUT, "queue", f"{MAX_WAITING} requests already wait for the planner"
            )
        try:
            if not self.lock.acquire(timeout=budget):
                raise PlanningError(
                    ErrorCode.TIMEOUT, "queue", f"still busy with another request after {budget} s"
                )
        finally:
            self.waiting.release()

    def _fail(self, service: str, response, error: PlanningError, began: float) -> None:
        response.success = False
        response.error_code = int(error.code)
        response.message = f"{error.code.name} at {error.stage}: {error.message}"
        self.get_logger().warning(
            f"{service}: {response.message} (after {time.monotonic() - began:.2f} s)"
        )

    def _start_state(self, state: JointState) -> JointState:
        """The request's start state, or the latest /joint_states when it is empty (once
        it shows the arm at rest, waiting up to ``start_rest_wait``)."""
        if state.name or state.position:
            return state
        arm = self.scenario.arm_joints

        def settled() -> bool:
            latest = self.joint_state
            return latest is None or at_rest(list(latest.name), list(latest.velocity), arm)

        wait = self.planner.settings.start_rest_wait
        with self.joint_state_changed:
            if not self.joint_state_changed.wait_for(settled, timeout=wait):
                self.get_logger().warning(
                    f"the arm did not come to rest within {wait} s: planning from the "
                    "latest /joint_states"
                )
            latest = self.joint_state
        if latest is None:
            raise PlanningError(
                ErrorCode.NO_START_STATE,
                "start",
                "start_state is empty and no /joint_states has been received",
            )
        return latest

    def _arm(self, state: JointState):
        return arm_positions(
            list(state.name),
            list(state.position),
            self.scenario.arm_joints,
            self.planner.lower,
            self.planner.upper,
            velocities=list(state.velocity),
            velocity_limits=self.planner.velocity_limits,
        )

    def _place_request(self, request: PlanPlace.Request) -> PickPlaceRequest:
        check_sizes(  # before converting thousands of poses
            standing_dominoes=(len(request.standing_dominoes), MAX_STANDING),
            pile_dominoes=(len(request.pile_dominoes), MAX_PILE_DOMINOES),
            pile_points=(len(request.pile_points), MAX_PILE_POINTS),
        )
        return PickPlaceRequest(
            domino_pose=pose_of(request.domino_pose, "domino_pose"),
            place_pose=pose_of(request.place_pose, "place_pose"),
            start=self._arm(self._start_state(request.start_state)),
            grasp_pose=(
                None if is_unset(request.grasp_pose) else pose_of(request.grasp_pose, "grasp_pose")
            ),
            grasp_width=request.grasp_width,
            standing=poses_of(request.standing_dominoes, "standing_dominoes"),
            pile=poses_of(request.pile_dominoes, "pile_dominoes"),
            pile_points=np.array([(p.x, p.y, p.z) for p in request.pile_points]).reshape(-1, 3),
            pads_into_pile=request.pads_into_pile,
            time_budget=request.time_budget,
            holding=request.holding,
        )

    def _strike_request(self, request: PlanStrike.Request) -> StrikeRequest:
        check_sizes(standing_dominoes=(len(request.standing_dominoes), MAX_STANDING))
        state = self._start_state(request.start_state)
        return StrikeRequest(
            domino_pose=pose_of(request.domino_pose, "domino_pose"),
            start=self._arm(state),
            finger_opening=finger_opening(
                list(state.name), list(state.position), self.scenario.gripper_joints
            ),
            standing=poses_of(request.standing_dominoes, "standing_dominoes"),
            push_distance=request.push_distance,
            push_speed=request.push_speed,
            time_budget=request.time_budget,
            sweep=sweep_of(request.sweep_direction),
        )

    def _fill(self, response, plan: Plan, period: float, remark: str) -> None:
        for segment, sampled in zip(plan.segments, plan.sampled(period), strict=True):
            trajectory = JointTrajectory(joint_names=list(self.scenario.arm_joints))
            for t, q, qd, qdd in zip(
                sampled.times,
                sampled.positions,
                sampled.velocities,
                sampled.accelerations,
                strict=True,
            ):
                trajectory.points.append(
                    JointTrajectoryPoint(
                        positions=q.tolist(),
                        velocities=qd.tolist(),
                        accelerations=qdd.tolist(),
                        time_from_start=duration_message(float(t)),
                    )
                )
            response.segments.append(
                TrajectorySegment(
                    label=segment.label,
                    trajectory=trajectory,
                    gripper_after=GRIPPER_EVENTS.get(
                        segment.gripper_after, TrajectorySegment.GRIPPER_NONE
                    ),
                    gripper_position=float(segment.gripper_position),
                    gripper_max_effort=float(segment.gripper_effort),
                )
            )
        if isinstance(plan, PickPlacePlan):
            response.held_above_place = pose_message(plan.held_above_place.GetAsMatrix4())
        response.success = True
        response.error_code = int(ErrorCode.SUCCESS)
        response.message = "planned" + (f" ({remark})" if remark else "")


def main(args: list[str] | None = None) -> None:
    tune_allocator()
    rclpy.init(args=args)
    node = None
    with stop_quietly_on_shutdown():  # Ctrl-C while the planner is being built
        node = PlannerNode()
    if node is None:
        rclpy.try_shutdown()
        return
    spin_until_shutdown(node, DrainingExecutor(num_threads=EXECUTOR_THREADS))


if __name__ == "__main__":
    main()

"""planner_node over real DDS: good and bad /plan_place and /plan_strike requests, the
start state given or from /joint_states, bad requests answered while others are being planned,
parameters validated. The node plans with a budget no search uses up (``UNHURRIED``): an
unreachable domino is proven so by its search, not cut short by a loaded machine."""

from __future__ import annotations

import math
import time
from collections.abc import Callable

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.node import Node
from sensor_msgs.msg import JointState

from dombot_description.grasp import flat_pose, upright_pose
from dombot_description.scenario import load_scenario
from dombot_msgs.msg import TrajectorySegment
from dombot_msgs.srv import PlanPlace, PlanStrike
from dombot_planner.errors import ErrorCode
from dombot_planner.foreseen_refusal import PADS_IN_PILE
from support.planning_clock import UNHURRIED
from support.ros_processes import installed_node, spin_until

pytestmark = pytest.mark.slow  # a planner_node process

SCENARIO = load_scenario()


def pose_message(transform) -> Pose:
    x, y, z = transform.translation()
    q = transform.rotation().ToQuaternion()
    return Pose(
        position=Point(x=x, y=y, z=z), orientation=Quaternion(w=q.w(), x=q.x(), y=q.y(), z=q.z())
    )


def plan_request(**changes) -> PlanPlace.Request:
    request = PlanPlace.Request()
    request.start_state = JointState(
        name=list(SCENARIO.arm_joints), position=SCENARIO.home_position.tolist()
    )
    request.domino_pose = pose_message(flat_pose(0.60, -0.28, 0.4))
    request.place_pose = pose_message(upright_pose(0.55, 0.15, 0.3))
    for name, value in changes.items():
        setattr(request, name, value)
    return request


def strike_request(**changes) -> PlanStrike.Request:
    """The first domino of a run of three at 60 % spacing; the fingers open at the start."""
    request = PlanStrike.Request()
    request.start_state = JointState(
        name=[*SCENARIO.arm_joints, *SCENARIO.gripper_joints],
        position=[*SCENARIO.home_position.tolist(), 0.017, 0.017],
    )
    run = [
        upright_pose(0.55 + i * 0.0288 * math.cos(0.3), 0.15 + i * 0.0288 * math.sin(0.3), 0.3)
        for i in range(3)
    ]
    request.domino_pose = pose_message(run[0])
    request.standing_dominoes = [pose_message(p) for p in run[1:]]
    for name, value in changes.items():
        setattr(request, name, value)
    return request


class Client:
    def __init__(self) -> None:
        self.node = Node("plan_place_probe")
        self.plan = self.node.create_client(PlanPlace, "/plan_place")
        self.strike = self.node.create_client(PlanStrike, "/plan_strike")
        self.joints = self.node.create_publisher(JointState, "/joint_states", 10)

    def call_async(self, request):
        service = self.strike if isinstance(request, PlanStrike.Request) else self.plan
        return service.call_async(request)

    def call(self, request, timeout: float = 300.0):
        future = self.call_async(request)
        assert spin_until(self.node, future.done, timeout=timeout), "no answer"
        return future.result()


@pytest.fixture(scope="module")
def client():
    rclpy.init()
    budget = f"default_time_budget:={UNHURRIED}"
    with installed_node("dombot_planner", "planner_node", "--ros-args", "-p", budget) as process:
        client = Client()
        for service in (client.plan, client.strike):
            assert spin_until(client.node, service.service_is_ready, timeout=180), process.poll()
        yield client
        client.node.destroy_node()
        assert process.poll() is None, "planner_node died during the tests"
    rclpy.shutdown()


def test_good_request_gets_a_trajectory_with_gripper_events(client: Client) -> None:
    response = client.call(plan_request())
    assert response.success, response.message
    assert response.error_code == PlanPlace.Response.SUCCESS
    assert [s.label for s in response.segments] == [
        "open_gripper",
        "approach_grasp",
        "lift",
        "transfer",
        "place",
        "retreat",
    ]
    assert [s.gripper_after for s in response.segments] == [
        TrajectorySegment.GRIPPER_OPEN,
        TrajectorySegment.GRIPPER_CLOSE,
        TrajectorySegment.GRIPPER_NONE,
        TrajectorySegment.GRIPPER_NONE,
        TrajectorySegment.GRIPPER_OPEN,
        TrajectorySegment.GRIPPER_NONE,
    ]
    # the held domino above its place, upright, where the bring-up looks at the hold
    above, place = response.held_above_place, plan_request().place_pose
    assert (above.position.x, above.position.y) == pytest.approx(
        (place.position.x, place.position.y), abs=1e-3
    )
    assert above.position.z == pytest.approx(place.position.z + 0.07, abs=1e-3)
    approach = response.segments[1].trajectory
    assert list(approach.joint_names) == list(SCENARIO.arm_joints)
    first = approach.points[0]
    assert first.positions == pytest.approx(SCENARIO.home_position.tolist(), abs=1e-9)
    times = [p.time_from_start.sec + 1e-9 * p.time_from_start.nanosec for p in approach.points]
    assert np.all(np.diff(times) > 0)
    assert approach.points[-1].velocities == pytest.approx([0.0] * 7, abs=1e-6)
    assert response.planning_time > 0.0


@pytest.mark.parametrize(
    ("changes", "code"),
    [
        (
            {"domino_pose": Pose(position=Point(x=math.nan, y=-0.3, z=0.004))},
            PlanPlace.Response.INVALID_REQUEST,
        ),
        (
            {
                "place_pose": Pose(
                    position=Point(x=0.5, y=0.1, z=0.024),
                    orientation=Quaternion(w=0.9, x=0.0, y=0.0, z=0.0),
                )
            },
            PlanPlace.Response.INVALID_REQUEST,
        ),
        ({"time_budget": -2.0}, PlanPlace.Response.INVALID_REQUEST),
        (
            {"pile_points": [Point(x=0.6, y=-0.28, z=0.01), Point(x=math.inf)]},
            PlanPlace.Response.INVALID_REQUEST,
        ),
        (
            {"place_pose": pose_message(upright_pose(1.5, 0.0, 0.0))},
            PlanPlace.Response.OUTSIDE_WORKSPACE,
        ),
        (
            {"standing_dominoes": [pose_message(upright_pose(0.55, 0.15, 0.3))]},
            PlanPlace.Response.PLACE_IN_COLLISION,
        ),
        (
            {"start_state": JointState(name=["iiwa_joint_1"], position=[0.0])},
            PlanPlace.Response.INVALID_REQUEST,
        ),
        (
            {"place_pose": pose_message(upright_pose(0.33, 0.0, math.pi / 2))},
            PlanPlace.Response.PLACE_UNREACHABLE,
        ),
    ],
    ids=[
        "nan",
        "non_unit_quaternion",
        "negative_budget",
        "infinite_pile_point",
        "outside_workspace",
        "place_on_a_standing_domino",
        "start_state_lacks_joints",
        "unreachable_place",
    ],
)
def test_bad_requests_get_an_error_code_and_a_message(client: Client, changes, code) -> None:
    response = client.call(plan_request(**changes))
    assert not response.success
    assert response.error_code == code, response.message
    assert ErrorCode(code).name in response.message
    assert not response.segments


def test_pile_dominoes_reach_the_planner_and_are_checked(client: Client) -> None:
    """A pile domino all along the side that the reachable grasps' pads would go down."""
    side = 0.0245 * np.array([math.sin(0.4), -math.cos(0.4)])  # the picked one's −y side
    beside = pose_message(flat_pose(0.60 + side[0], -0.28 + side[1], 0.4))
    response = client.call(plan_request(pile_dominoes=[beside]))
    assert response.error_code == PlanPlace.Response.GRASP_UNREACHABLE, response.message
    assert PADS_IN_PILE in response.message  # told before any IK, from the pile's boxes
    nowhere = Pose(position=Point(x=0.6, y=math.inf, z=0.004))
    response = client.call(plan_request(pile_dominoes=[beside, nowhere]))
    assert response.error_code == PlanPlace.Response.INVALID_REQUEST
    assert "pile_dominoes[1]" in response.message


def test_good_strike_request_closes_the_gripper_then_pushes(client: Client) -> None:
    response = client.call(strike_request())
    assert response.success, response.message
    assert [(s.label, s.gripper_after) for s in response.segments] == [
        ("close_gripper", TrajectorySegment.GRIPPER_CLOSE),
        ("approach", TrajectorySegment.GRIPPER_NONE),
        ("push", TrajectorySegment.GRIPPER_NONE),
        ("retreat", TrajectorySegment.GRIPPER_NONE),
    ]
    first = response.segments[1].trajectory.points[0].positions
    assert first == pytest.approx(SCENARIO.home_position.tolist(), abs=1e-9)
    assert response.planning_time > 0.0


def test_a_sweep_pushes_a_fallen_domino_along_the_direction_given(client: Client) -> None:
    response = client.call(
        strike_request(
            domino_pose=pose_message(flat_pose(0.55, -0.05, 0.0)),
            sweep_direction=Vector3(x=1.0),
            push_distance=0.03,
        )
    )
    assert response.success, response.message
    assert [s.label for s in response.segments] == ["close_gripper", "approach", "push", "retreat"]


@pytest.mark.parametrize(
    ("changes", "code"),
    [
        (
            {"domino_pose": Pose(position=Point(x=0.55, y=math.inf, z=0.024))},
            PlanStrike.Response.INVALID_REQUEST,
        ),
        (
            {
                "domino_pose": Pose(
                    position=Point(x=0.55, y=0.15, z=0.024),
                    orientation=Quaternion(w=1.0, x=0.1, y=0.0, z=0.0),
                )
            },
            PlanStrike.Response.INVALID_REQUEST,
        ),
        (
            {"domino_pose": pose_message(flat_pose(0.55, 0.15, 0.3))},
            PlanStrike.Response.INVALID_REQUEST,
        ),
        ({"push_distance": -0.01}, PlanStrike.Response.INVALID_REQUEST),
        (
            {"domino_pose": pose_message(upright_pose(0.1, 0.0, 0.0))},
            PlanStrike.Response.OUTSIDE_WORKSPACE,
        ),
        ({"push_distance": 0.03}, PlanStrike.Response.PLACE_IN_COLLISION),
        ({"sweep_direction": Vector3(x=math.nan)}, PlanStrike.Response.INVALID_REQUEST),
        ({"sweep_direction": Vector3(z=1.0)}, PlanStrike.Response.INVALID_REQUEST),
    ],
    ids=[
        "inf",
        "non_unit_quaternion",
        "not_upright",
        "negative_push",
        "outside_workspace",
        "push_reaches_next",
        "nan_sweep",
        "vertical_sweep",
    ],
)
def test_bad_strike_requests_get_an_error_code_and_a_message(client: Client, changes, code) -> None:
    response = client.call(strike_request(**changes))
    assert not response.success
    assert response.error_code == code, response.message
    assert ErrorCode(code).name in response.message
    assert not response.segments


def test_empty_start_state_uses_joint_states(client: Client) -> None:
    empty = plan_request(start_state=JointState())
    response = client.call(empty)
    assert response.error_code == PlanPlace.Response.NO_START_STATE, response.message
    state = JointState(name=list(SCENARIO.arm_joints), position=SCENARIO.home_position.tolist())

    def received() -> bool:
        client.joints.publish(state)
        answer = client.call(empty)
        return answer.error_code != PlanPlace.Response.NO_START_STATE

    assert spin_until(client.node, received, timeout=120)
    response = client.call(empty)
    assert response.success, response.message
    start = response.segments[1].trajectory.points[0].positions
    assert start == pytest.approx(SCENARIO.home_position.tolist(), abs=1e-9)


def arm_state(offset: float, speed: float) -> JointState:
    """Home with joint 2 ``offset`` rad off it, moving at ``speed`` rad/s."""
    position, velocity = SCENARIO.home_position.copy(), np.zeros(7)
    position[1], velocity[1] = position[1] + offset, speed
    return JointState(
        name=list(SCENARIO.arm_joints), position=position.tolist(), velocity=velocity.tolist()
    )


# joint 2 decelerating at 8.5 rad/s², 25 mrad before it stops: as the latest /joint_states
# was when a strike's plan started that far off where the arm stopped (the sim refused it)
STOPPING = arm_state(0.025, 0.65)


def strike_start(client: Client, publish: JointState) -> list[float]:
    """Where a strike with an empty start state starts: STOPPING is the latest joint state
    when it is asked for, ``publish`` after that until it is answered."""

    def published_for(seconds: float) -> Callable[[], bool]:
        until = time.monotonic() + seconds
        return lambda: client.joints.publish(STOPPING) or time.monotonic() > until

    spin_until(client.node, published_for(1.0), timeout=30)
    future = client.call_async(strike_request(start_state=JointState()))
    assert spin_until(
        client.node, lambda: client.joints.publish(publish) or future.done(), timeout=300
    )
    response = future.result()
    assert response.success, response.message
    return list(response.segments[0].trajectory.points[0].positions)


def test_an_empty_start_state_is_the_arm_at_rest(client: Client) -> None:
    """Right after a motion the latest /joint_states may be from before the arm stopped."""
    start = strike_start(client, publish=arm_state(0.0, 0.0))
    assert start == pytest.approx(SCENARIO.home_position.tolist(), abs=1e-9)


def test_an_arm_that_does_not_come_to_rest_is_planned_from_where_it_is(client: Client) -> None:
    """Waited for start_rest_wait, then planned from the latest joint state."""
    start = strike_start(client, publish=STOPPING)
    assert start == pytest.approx(STOPPING.position.tolist(), abs=1e-9)
    client.joints.publish(arm_state(0.0, 0.0))  # at rest again for the tests after


def test_a_given_start_state_is_where_the_plan_starts(client: Client) -> None:
    """The bring-up asks for a pick from where the retreat under way will end: the plan
    starts at start_state, not where /joint_states shows the arm."""
    elsewhere = arm_state(0.2, 0.0)
    until = time.monotonic() + 1.0  # the node has it before the request comes
    spin_until(
        client.node, lambda: client.joints.publish(elsewhere) or time.monotonic() > until, 30
    )
    future = client.call_async(plan_request())  # start_state: home
    assert spin_until(
        client.node, lambda: client.joints.publish(elsewhere) or future.done(), timeout=300
    )
    response = future.result()
    assert response.success, response.message
    start = list(response.segments[1].trajectory.points[0].positions)
    assert start == pytest.approx(SCENARIO.home_position.tolist(), abs=1e-9)
    client.joints.publish(arm_state(0.0, 0.0))  # at home again for the tests after


def test_bad_requests_are_answered_while_others_are_planned(client: Client) -> None:
    """Two unreachable places (each searched to the end) sent first: one is planned, the
    other waits for the planner; bad requests sent after them are checked before they
    would wait, so they are answered while at least one of the two is still unanswered
    (it needs the other's whole search and its own)."""
    unreachable = plan_request(place_pose=pose_message(upright_pose(0.33, 0.0, 1.57)))
    slow = [client.call_async(unreachable) for _ in range(2)]
    bad = client.call_async(plan_request(time_budget=-1.0))
    bad_strike = client.call_async(strike_request(push_speed=-1.0))
    assert spin_until(client.node, lambda: bad.done() and bad_strike.done(), timeout=300)
    assert bad.result().error_code == PlanPlace.Response.INVALID_REQUEST
    assert bad_strike.result().error_code == PlanStrike.Response.INVALID_REQUEST
    assert not all(s.done() for s in slow), "the bad requests waited for the planner"
    assert spin_until(client.node, lambda: all(s.done() for s in slow), timeout=600)
    for answer in slow:
        assert answer.result().error_code == PlanPlace.Response.PLACE_UNREACHABLE


def test_wrong_parameter_value_is_refused(client: Client) -> None:
    service = client.node.create_client(SetParameters, "/planner_node/set_parameters")
    assert spin_until(client.node, service.service_is_ready, timeout=120)
    value = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=-1.0)
    request = SetParameters.Request(parameters=[Parameter(name="acceleration_limit", value=value)])
    future = service.call_async(request)
    assert spin_until(client.node, future.done, timeout=120)
    result = future.result().results[0]
    assert not result.successful and "acceleration_limit" in result.reason
    assert client.call(plan_request()).success  # still serving with the old settings


def test_error_codes_are_the_service_constants() -> None:
    for code in ErrorCode:
        assert getattr(PlanPlace.Response, code.name) == code.value
        if hasattr(PlanStrike.Response, code.name):
            assert getattr(PlanStrike.Response, code.name) == code.value

"""sim_node over real DDS: images with the right encodings and intrinsics, the arm and
gripper driven as a ros2_control client would (control_msgs actions at the controllers'
names), resets that change the pile, and clear errors for bad goals, requests and
parameters while the node keeps running."""

from __future__ import annotations

import numpy as np
import pytest
import rclpy
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import GripperCommand as GripperGoal
from control_msgs.msg import JointTolerance
from rcl_interfaces.srv import SetParameters
from rclpy.action import ActionClient, get_action_names_and_types
from rclpy.node import Node
from rclpy.parameter import Parameter
from sensor_msgs.msg import CameraInfo, Image, JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from dombot_description.scenario import load_scenario
from dombot_msgs.msg import DominoStateArray
from dombot_msgs.srv import ResetSim
from support.ros_processes import installed_node, spin_until

pytestmark = pytest.mark.slow  # a sim_node process

SCENARIO = load_scenario()
ARM = list(SCENARIO.arm_joints)
FINGERS = ["wsg_left_finger_joint", "wsg_right_finger_joint"]
TRAJECTORY_ACTION = "/arm_controller/follow_joint_trajectory"
GRIPPER_ACTION = "/gripper_controller/gripper_cmd"
STATE_TOPICS = {"/joint_states": JointState, "/sim/domino_ground_truth": DominoStateArray}
CAMERA_TOPICS = {
    "/camera_0/color/image_raw": Image,
    "/camera_0/depth/image_raw": Image,
    "/camera_0/color/camera_info": CameraInfo,
    "/camera_1/depth/image_raw": Image,
}


class Probe:
    def __init__(self) -> None:
        self.node = Node("sim_probe")
        self.latest: dict[str, object] = {}
        for topic, kind in STATE_TOPICS.items():
            self._subscribe(topic, kind)
        self.trajectory = ActionClient(self.node, FollowJointTrajectory, TRAJECTORY_ACTION)
        self.gripper = ActionClient(self.node, GripperCommand, GRIPPER_ACTION)
        self.reset = self.node.create_client(ResetSim, "/sim/reset")

    def _subscribe(self, topic: str, kind: type):
        return self.node.create_subscription(
            kind, topic, lambda msg: self.latest.__setitem__(topic, msg), 5
        )

    def fresh(self, topic: str, timeout: float = 120.0):
        """The next message on ``topic``; a camera topic is subscribed only meanwhile (sim_node
        renders the cameras someone watches: watched all along, they cost the node a
        render a period through every test)."""
        self.latest.pop(topic, None)
        camera = self._subscribe(topic, CAMERA_TOPICS[topic]) if topic in CAMERA_TOPICS else None
        try:
            got = spin_until(self.node, lambda: topic in self.latest, timeout)
            assert got, f"nothing on {topic}"
        finally:
            if camera is not None:
                self.node.destroy_subscription(camera)
        return self.latest[topic]

    def positions(self, names: list[str]) -> np.ndarray:
        state = self.fresh("/joint_states")
        return np.array([state.position[state.name.index(n)] for n in names])

    def positions_at_rest(self, names: list[str], speed: float = 1e-3) -> np.ndarray:
        """The joints' positions in the first /joint_states that shows them still (every
        one slower than ``speed``): under load a state published before an action's
        result can still be waiting in the subscription's queue after it (the fingers
        read 32.05 mm, still closing, after a 30 mm goal was reached)."""
        for _ in range(1000):
            state = self.fresh("/joint_states")
            index = [state.name.index(n) for n in names]
            if np.all(np.abs(np.asarray(state.velocity)[index]) < speed):
                return np.asarray(state.position)[index]
        raise AssertionError(f"{names} never at rest in 1000 joint states")

    def arm_position(self) -> np.ndarray:
        return self.positions(ARM)

    def send(self, client: ActionClient, goal, feedback=None):
        """The accepted goal's handle."""
        assert client.wait_for_server(timeout_sec=120)
        sent = client.send_goal_async(goal, feedback_callback=feedback)
        assert spin_until(self.node, sent.done, 120)
        handle = sent.result()
        assert handle.accepted
        return handle

    def outcome(self, handle, timeout: float = 300.0):
        """(status, result) of an accepted goal."""
        result = handle.get_result_async()
        assert spin_until(self.node, result.done, timeout)
        return result.result().status, result.result().result

    def run_action(self, client: ActionClient, goal, timeout: float = 300.0):
        return self.outcome(self.send(client, goal), timeout)[1]

    def call_reset(self, count: int, seed: int) -> ResetSim.Response:
        assert self.reset.wait_for_service(timeout_sec=120)
        future = self.reset.call_async(ResetSim.Request(domino_count=count, seed=seed))
        assert spin_until(self.node, future.done, 120)
        return future.result()


@pytest.fixture(scope="module")
def probe():
    rclpy.init()
    arguments = [
        "--ros-args",
        "-p",
        "domino_count:=6",
        "-p",
        "real_time_factor:=0.0",
        "-p",
        "camera_rate:=5.0",
        "-p",
        "ground_truth_rate:=5.0",
    ]
    with installed_node("dombot_sim", "sim_node", *arguments) as process:
        probe = Probe()
        assert spin_until(probe.node, lambda: "/joint_states" in probe.latest, 300), process.poll()
        yield probe
        probe.node.destroy_node()
        assert process.poll() is None, "sim_node died during the tests"
    rclpy.shutdown()


def trajectory_goal(names, points) -> FollowJointTrajectory.Goal:
    goal = FollowJointTrajectory.Goal()
    goal.trajectory = JointTrajectory(joint_names=names)
    for seconds, positions in points:
        goal.trajectory.points.append(
            JointTrajectoryPoint(
                positions=list(positions),
                time_from_start=Duration(sec=int(seconds), nanosec=int(seconds % 1 * 1e9)),
            )
        )
    return goal


def test_cameras_publish_rgb8_and_32fc1_with_the_scenario_intrinsics(probe: Probe) -> None:
    color = probe.fresh("/camera_0/color/image_raw")
    depth = probe.fresh("/camera_0/depth/image_raw")
    info = probe.fresh("/camera_0/color/camera_info")
    spec = SCENARIO.cameras[0]
    assert (color.encoding, color.width, color.height, color.step) == ("rgb8", 640, 480, 1920)
    assert (depth.encoding, depth.step) == ("32FC1", 2560)
    assert color.header.frame_id == "camera_0_optical"
    assert np.array(info.k).reshape(3, 3) == pytest.approx(spec.intrinsics)
    metres = np.frombuffer(bytes(depth.data), dtype="<f4").reshape(480, 640)
    centre = metres[240, 320]  # the pile centre is in the middle of the image
    distance = np.linalg.norm(spec.position - np.array([*SCENARIO.pile_center, 0.0]))
    assert 0.8 * distance < centre < 1.02 * distance
    pixels = np.frombuffer(bytes(color.data), dtype=np.uint8).reshape(480, 640, 3)
    assert pixels.std() > 5.0  # an actual picture, not a blank frame
    assert probe.fresh("/camera_1/depth/image_raw").encoding == "32FC1"


def gripper_goal(position: float, max_effort: float = 0.0) -> GripperCommand.Goal:
    return GripperCommand.Goal(command=GripperGoal(position=position, max_effort=max_effort))


def test_the_actions_are_served_at_ros2_control_names_with_control_msgs_types(
    probe: Probe,
) -> None:
    expected = {
        TRAJECTORY_ACTION: ["control_msgs/action/FollowJointTrajectory"],
        GRIPPER_ACTION: ["control_msgs/action/GripperCommand"],
    }

    def served() -> dict[str, list[str]]:
        return {n: t for n, t in get_action_names_and_types(probe.node) if n in expected}

    assert spin_until(probe.node, lambda: served() == expected, 30), served()


def test_a_trajectory_moves_the_arm_to_its_goal_with_feedback(probe: Probe) -> None:
    start = probe.arm_position()
    goal = start + np.array([0.3, -0.1, 0.0, 0.2, 0.0, -0.2, 0.4])
    feedback: list[FollowJointTrajectory.Feedback] = []
    handle = probe.send(
        probe.trajectory,
        trajectory_goal(ARM, [(1.5, goal)]),
        feedback=lambda message: feedback.append(message.feedback),
    )
    status, result = probe.outcome(handle)
    assert status == GoalStatus.STATUS_SUCCEEDED
    assert result.error_code == FollowJointTrajectory.Result.SUCCESSFUL, result.error_string
    assert "goal reached; largest tracking error" in result.error_string
    # within the default goal tolerance, 0.01 rad, read from /joint_states
    assert probe.arm_position() == pytest.approx(goal, abs=0.01)
    assert feedback, "no feedback during the goal"
    for message in feedback:
        assert list(message.joint_names) == ARM
        actual, desired = np.array(message.actual.positions), np.array(message.desired.positions)
        assert np.array(message.error.positions) == pytest.approx(actual - desired, abs=1e-12)
        assert np.abs(actual - desired).max() < 0.05  # it tracks the trajectory on the way
    # Back again, with the joints in another order.
    order = ARM[::-1]
    back = [start[ARM.index(name)] for name in order]
    result = probe.run_action(probe.trajectory, trajectory_goal(order, [(1.5, back)]))
    assert result.error_code == FollowJointTrajectory.Result.SUCCESSFUL, result.error_string
    assert probe.arm_position() == pytest.approx(start, abs=0.01)


@pytest.mark.parametrize(
    ("names", "points", "code", "words"),
    [
        ([*ARM[:6], "elbow"], [(1.0, [0.0] * 7)], -2, "unknown joints ['elbow']"),
        (ARM[:6], [(1.0, [0.0] * 6)], -2, "joints ['iiwa_joint_7'] are missing"),
        ([*ARM[:6], ARM[0]], [(1.0, [0.0] * 7)], -2, "named twice"),
        (ARM, [(1.0, [0.0] * 7), (0.5, [0.1] * 7)], -1, "strictly increase"),
        (ARM, [(1.0, [3.0] + [0.0] * 6)], -1, "iiwa_joint_1 = 3.0000 rad is outside its limits"),
        (ARM, [(0.05, [1.0, 0.35, 0.0, -1.75, 0.0, 1.05, 0.0])], -1, "over its limit"),
        (ARM, [(1.0, [float("nan")] * 7)], -1, "finite"),
        (ARM, [], -1, "no points"),
        (ARM, [(0.5 + 0.01 * i, [0.0] * 7) for i in range(10_001)], -1, "at most 10000"),
    ],
    ids=[
        "unknown-joint",
        "missing-joint",
        "twice",
        "time-goes-back",
        "beyond-limit",
        "too-fast",
        "nan",
        "empty",
        "too-many-points",
    ],
)
def test_bad_trajectories_are_refused_with_a_code_and_a_reason(
    probe: Probe, names, points, code, words
) -> None:
    before = probe.arm_position()
    status, result = probe.outcome(probe.send(probe.trajectory, trajectory_goal(names, points)))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == code
    assert words in result.error_string
    assert probe.arm_position() == pytest.approx(before, abs=1e-3)


def test_a_multi_dof_trajectory_is_refused_as_invalid_joints(probe: Probe) -> None:
    goal = trajectory_goal(ARM, [(1.0, probe.arm_position())])
    goal.multi_dof_trajectory.joint_names = ["base"]
    result = probe.run_action(probe.trajectory, goal)
    assert result.error_code == FollowJointTrajectory.Result.INVALID_JOINTS
    assert "multi_dof_trajectory names ['base']" in result.error_string


def test_a_path_tolerance_tighter_than_the_tracking_aborts_the_goal(probe: Probe) -> None:
    start = probe.arm_position()
    goal = trajectory_goal(ARM, [(1.0, start + np.array([0.4, 0, 0, 0, 0, 0, 0]))])
    goal.path_tolerance = [JointTolerance(name="iiwa_joint_1", position=1e-7)]
    status, result = probe.outcome(probe.send(probe.trajectory, goal))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == FollowJointTrajectory.Result.PATH_TOLERANCE_VIOLATED
    assert "path tolerance violated on iiwa_joint_1" in result.error_string
    assert probe.run_action(probe.trajectory, trajectory_goal(ARM, [(1.0, start)])).error_code == 0


def test_a_newer_goal_preempts_the_running_one(probe: Probe) -> None:
    start = probe.arm_position()
    slow = trajectory_goal(ARM, [(600.0, start + 0.3)])  # far longer than the test
    feedback: list[FollowJointTrajectory.Feedback] = []
    first = probe.send(probe.trajectory, slow, feedback=feedback.append)
    assert spin_until(probe.node, lambda: bool(feedback), 30), "the first goal never ran"
    second = probe.send(probe.trajectory, trajectory_goal(ARM, [(1.0, start)]))
    status, result = probe.outcome(first)
    assert status == GoalStatus.STATUS_ABORTED
    assert "preempted by a newer goal" in result.error_string
    status, result = probe.outcome(second)
    assert status == GoalStatus.STATUS_SUCCEEDED, result.error_string
    assert probe.arm_position() == pytest.approx(start, abs=0.01)


def test_a_refused_goal_leaves_the_running_one_going(probe: Probe) -> None:
    start = probe.arm_position()
    feedback: list[FollowJointTrajectory.Feedback] = []
    running = probe.send(
        probe.trajectory, trajectory_goal(ARM, [(600.0, start + 0.3)]), feedback=feedback.append
    )
    assert spin_until(probe.node, lambda: bool(feedback), 30), "the first goal never ran"
    goal = trajectory_goal(ARM, [(1.0, start)])
    goal.trajectory.points[0].effort = [-1.0, -2.0]  # one per joint or none
    status, result = probe.outcome(probe.send(probe.trajectory, goal))
    assert status == GoalStatus.STATUS_ABORTED
    assert result.error_code == FollowJointTrajectory.Result.INVALID_GOAL
    assert "effort must be empty or 7 finite numbers" in result.error_string
    feedback.clear()
    assert spin_until(probe.node, lambda: len(feedback) >= 3, 30), "the running goal stopped"
    back = probe.send(probe.trajectory, trajectory_goal(ARM, [(1.0, start)]))
    assert "preempted by a newer goal" in probe.outcome(running)[1].error_string
    assert probe.outcome(back)[0] == GoalStatus.STATUS_SUCCEEDED


def test_the_gripper_reaches_the_commanded_opening(probe: Probe) -> None:
    result = probe.run_action(probe.gripper, gripper_goal(0.03, max_effort=10.0))
    assert result.reached_goal and result.position == pytest.approx(0.03, abs=1e-3)
    # the opening is the gap between the fingers: the sum of their joint positions
    assert probe.positions_at_rest(FINGERS).sum() == pytest.approx(0.03, abs=1e-3)
    status, result = probe.outcome(probe.send(probe.gripper, gripper_goal(0.5)))
    assert status == GoalStatus.STATUS_ABORTED  # beyond the 0.11 m stroke: refused
    assert not result.reached_goal
    assert result.position == pytest.approx(0.03, abs=1e-3)  # the fingers stayed
    result = probe.run_action(probe.gripper, gripper_goal(0.1))
    assert result.reached_goal
    assert probe.positions_at_rest(FINGERS).sum() == pytest.approx(0.1, abs=1e-3)


def test_reset_pours_the_pile_the_seed_asks_for(probe: Probe) -> None:
    def pile() -> np.ndarray:
        truth = probe.fresh("/sim/domino_ground_truth")
        return np.array(
            [[d.pose.position.x, d.pose.position.y, d.pose.position.z] for d in truth.dominoes]
        )

    response = probe.call_reset(5, seed=3)
    assert response.success and response.settle_time > 0.0, response.message
    first = pile()
    assert first.shape == (5, 3)
    assert probe.call_reset(5, seed=4).success
    assert np.abs(pile() - first).max() > 0.01
    assert probe.call_reset(5, seed=3).success
    assert pile() == pytest.approx(first, abs=1e-6)
    refused = probe.call_reset(100000, seed=1)
    assert not refused.success and "domino_count" in refused.message
    assert probe.fresh("/joint_states")  # still serving


def test_bad_parameters_are_refused_with_a_reason_and_good_ones_taken(probe: Probe) -> None:
    client = probe.node.create_client(SetParameters, "/sim_node/set_parameters")
    assert client.wait_for_service(timeout_sec=120)

    def set_log_moved(value: float):
        parameter = Parameter("log_moved_mm", Parameter.Type.DOUBLE, value).to_parameter_msg()
        future = client.call_async(SetParameters.Request(parameters=[parameter]))
        assert spin_until(probe.node, future.done, 120)
        return future.result().results[0]

    for bad in (-1.0, float("nan"), float("inf")):
        result = set_log_moved(bad)
        assert not result.successful and "log_moved_mm must be" in result.reason
    assert set_log_moved(2.0).successful
    assert probe.arm_position().shape == (7,)  # still serving

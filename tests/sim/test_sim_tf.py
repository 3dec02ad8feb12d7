"""sim_node's frames over real DDS: /tf and /tf_static compose to Drake's forward
kinematics of the published joint state, /robot_description reaches a late subscriber
and names the joints /joint_states carries, and images reach best-effort readers."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree

import numpy as np
import pytest
import rclpy
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy, qos_profile_sensor_data
from sensor_msgs.msg import Image, JointState
from std_msgs.msg import String
from tf2_msgs.msg import TFMessage

from dombot_adapters.pose_messages import pose_matrix
from dombot_description.cell import add_cell
from dombot_description.scenario import load_scenario
from dombot_msgs.msg import DominoStateArray
from support.camera_messages import transform_matrix
from support.ros_processes import installed_node, spin_until

pytestmark = pytest.mark.slow  # a sim_node process

SCENARIO = load_scenario()
DOMINOES = 3
LATCHED = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)


def nanoseconds(stamp) -> int:
    return stamp.sec * 1_000_000_000 + stamp.nanosec


class Listener:
    """Keeps joint states, /tf and ground truth by stamp; the latched topics as they come."""

    def __init__(self) -> None:
        self.node = Node("tf_listener")
        self.joint_states: dict[int, JointState] = {}
        self.links: dict[int, TFMessage] = {}
        self.dominoes: dict[int, TFMessage] = {}
        self.truth: dict[int, DominoStateArray] = {}
        self.latched: dict[str, object] = {}
        self.images: dict[str, Image] = {}
        self.node.create_subscription(JointState, "/joint_states", self._on_joint_state, 50)
        self.node.create_subscription(TFMessage, "/tf", self._on_tf, 100)
        self.node.create_subscription(
            DominoStateArray, "/sim/domino_ground_truth", self._on_truth, 10
        )

    def _on_joint_state(self, message: JointState) -> None:
        self.joint_states[nanoseconds(message.header.stamp)] = message

    def _on_tf(self, message: TFMessage) -> None:
        first = message.transforms[0]
        kind = self.dominoes if first.child_frame_id.startswith("domino_") else self.links
        kind[nanoseconds(first.header.stamp)] = message

    def _on_truth(self, message: DominoStateArray) -> None:
        self.truth[nanoseconds(message.header.stamp)] = message

    def subscribe_latched(self) -> None:
        for topic, kind in (("/tf_static", TFMessage), ("/robot_description", String)):
            self.node.create_subscription(
                kind, topic, lambda m, topic=topic: self.latched.__setitem__(topic, m), LATCHED
            )

    def subscribe_images(self) -> None:
        for topic, qos in (
            ("/camera_0/color/image_raw", qos_profile_sensor_data),  # best effort
            ("/camera_0/depth/image_raw", QoSProfile(depth=2)),  # reliable
        ):
            self.node.create_subscription(
                Image, topic, lambda m, topic=topic: self.images.__setitem__(topic, m), qos
            )

    def spin_for(self, done, timeout: float = 120.0) -> None:
        assert spin_until(self.node, done, timeout)


@pytest.fixture(scope="module")
def listener():
    rclpy.init()
    arguments = [
        "--ros-args",
        *("-p", f"domino_count:={DOMINOES}"),
        *("-p", "camera_rate:=1.0"),
        *("-p", "ground_truth_rate:=5.0"),
        *("-p", "domino_tf_rate:=5.0"),
    ]
    with installed_node("dombot_sim", "sim_node", *arguments) as process:
        listener = Listener()
        assert spin_until(listener.node, lambda: listener.joint_states, 120), process.poll()
        listener.subscribe_latched()  # after the node published them: transient local
        listener.subscribe_images()
        yield listener
        listener.node.destroy_node()
        assert process.poll() is None, "sim_node died during the tests"
    rclpy.shutdown()


@pytest.fixture(scope="module")
def cell():
    plant = MultibodyPlant(time_step=0.0)
    add_cell(plant, SCENARIO)
    plant.Finalize()
    return plant


def by_child(messages: list[TFMessage]) -> dict[str, tuple[str, np.ndarray]]:
    frames = {}
    for message in messages:
        for t in message.transforms:
            assert t.child_frame_id not in frames, f"{t.child_frame_id} has two parents"
            frames[t.child_frame_id] = (t.header.frame_id, transform_matrix(t.transform))
    return frames


def chain(frames: dict[str, tuple[str, np.ndarray]], parent: str, child: str) -> np.ndarray:
    x = np.eye(4)
    while child != parent:
        child, x_pc = frames[child]
        x = x_pc @ x
    return x


def test_world_to_tcp_over_tf_is_drakes_forward_kinematics(listener: Listener, cell) -> None:
    listener.spin_for(lambda: "/tf_static" in listener.latched)
    listener.spin_for(lambda: len(listener.links.keys() & listener.joint_states.keys()) >= 3)
    context = cell.CreateDefaultContext()
    for stamp in sorted(listener.links.keys() & listener.joint_states.keys())[-3:]:
        state = listener.joint_states[stamp]
        q = cell.GetPositions(context)
        for name, value in zip(state.name, state.position, strict=True):
            q[cell.GetJointByName(name).position_start()] = value
        cell.SetPositions(context, q)
        frames = by_child([listener.latched["/tf_static"], listener.links[stamp]])
        x_wt = RigidTransform(chain(frames, "world", SCENARIO.tcp_frame))
        expected = cell.GetFrameByName(SCENARIO.tcp_frame).CalcPoseInWorld(context)
        assert np.linalg.norm(x_wt.translation() - expected.translation()) < 1e-6
        rotation = x_wt.rotation().InvertAndCompose(expected.rotation())
        assert rotation.ToAngleAxis().angle() < 1e-6


def test_robot_description_reaches_a_late_subscriber_and_names_the_joints(
    listener: Listener,
) -> None:
    listener.spin_for(lambda: {"/tf_static", "/robot_description"} <= listener.latched.keys())
    urdf = listener.latched["/robot_description"].data
    robot = MultibodyPlant(time_step=0.0)
    Parser(robot).AddModelsFromString(urdf, "urdf")  # a URDF parser accepts it
    robot.WeldFrames(robot.world_frame(), robot.GetFrameByName("iiwa_link_0"))
    robot.Finalize()
    movable = {
        robot.get_joint(index).name()
        for index in robot.GetJointIndices()
        if robot.get_joint(index).num_positions() > 0
    }
    state = listener.joint_states[max(listener.joint_states)]
    assert movable == set(state.name)
    # every link of the document is in the tf tree, so RViz can place each one
    listener.spin_for(lambda: listener.links)
    frames = by_child([listener.latched["/tf_static"], next(iter(listener.links.values()))])
    links = {link.get("name") for link in ElementTree.fromstring(urdf).findall("link")}
    assert links <= frames.keys()
    assert frames["iiwa_link_0"][0] == "world"


def test_tf_static_holds_the_camera_optical_frames_and_the_table(listener: Listener) -> None:
    listener.spin_for(lambda: "/tf_static" in listener.latched)
    frames = by_child([listener.latched["/tf_static"]])
    for spec in SCENARIO.cameras:
        parent, x = frames[f"{spec.name}_optical"]
        assert parent == "world"
        assert np.allclose(x, spec.pose(), atol=1e-9)
    assert frames["table_top"][0] == "world"


def test_domino_frames_are_the_ground_truth_poses(listener: Listener) -> None:
    listener.spin_for(lambda: listener.dominoes.keys() & listener.truth.keys())
    stamp = max(listener.dominoes.keys() & listener.truth.keys())
    frames = by_child([listener.dominoes[stamp]])
    truth = listener.truth[stamp].dominoes
    names = [f"domino_{i}" for i in range(DOMINOES)]
    assert sorted(frames) == sorted(d.name for d in truth) == names
    for domino in truth:
        parent, x = frames[domino.name]
        assert parent == "world"
        assert np.allclose(x, pose_matrix(domino.pose), atol=1e-9)


def test_images_reach_best_effort_and_reliable_readers(listener: Listener) -> None:
    listener.spin_for(lambda: len(listener.images) == 2, timeout=120)
    assert listener.images["/camera_0/color/image_raw"].encoding == "rgb8"
    assert listener.images["/camera_0/depth/image_raw"].encoding == "32FC1"
    [offered] = listener.node.get_publishers_info_by_topic("/camera_0/color/image_raw")
    assert offered.qos_profile.reliability == ReliabilityPolicy.RELIABLE

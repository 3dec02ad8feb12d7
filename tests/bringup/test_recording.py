"""Recording to MCAP and replaying it: the message definitions decode what rclpy
serializes, images are thinned, and a recording of a live sim_node (plus a transient
local topic published before the recorder started) reads back with the live graph's
types and plays back to a subscriber, message for message."""

from __future__ import annotations

import signal
from collections.abc import Iterator
from pathlib import Path
from subprocess import PIPE

import numpy as np
import pytest
import rclpy
from ament_index_python.packages import get_package_share_directory
from mcap.records import Schema
from mcap_ros2.decoder import DecoderFactory
from mcap_ros2.reader import read_ros2_messages
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy
from rclpy.serialization import serialize_message
from sensor_msgs.msg import CameraInfo, Image, JointState
from std_msgs.msg import String

from dombot_bringup.record_node import is_hidden
from dombot_bringup.recording import (
    SEPARATOR,
    DefinitionNotFoundError,
    McapSink,
    Throttle,
    header_stamp,
    message_definition,
    recorded_channels,
    recorded_messages,
)
from dombot_msgs.msg import DominoState, DominoStateArray
from support.ros_processes import installed_node, spin_until

LATCHED = QoSProfile(
    depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL, reliability=ReliabilityPolicy.RELIABLE
)


def decode(type_name: str, data: bytes):
    """``data`` decoded as Foxglove does: from the recorded definition alone."""
    definition = message_definition(type_name, get_package_share_directory)
    schema = Schema(id=1, name=type_name, encoding="ros2msg", data=definition.encode())
    return DecoderFactory().decoder_for("cdr", schema)(data)


def test_definitions_decode_what_rclpy_serializes() -> None:
    info = CameraInfo(width=640, height=480, distortion_model="plumb_bob", d=[0.1, 0.0])
    info.k[0], info.header.frame_id, info.roi.do_rectify = 615.0, "camera_2_optical", True
    decoded = decode("sensor_msgs/msg/CameraInfo", serialize_message(info))
    assert (decoded.width, decoded.height, decoded.distortion_model) == (640, 480, "plumb_bob")
    assert decoded.k[0] == 615.0 and list(decoded.d) == [0.1, 0.0]
    assert decoded.header.frame_id == "camera_2_optical" and decoded.roi.do_rectify

    truth = DominoStateArray(dominoes=[DominoState(name="domino_3", upright=True)])
    truth.dominoes[0].pose.position.x = 0.55
    decoded = decode("dombot_msgs/msg/DominoStateArray", serialize_message(truth))
    assert decoded.dominoes[0].name == "domino_3" and decoded.dominoes[0].upright
    assert decoded.dominoes[0].pose.position.x == 0.55


def test_definition_lists_each_used_type_once_after_the_root() -> None:
    text = message_definition("sensor_msgs/msg/Image", get_package_share_directory)
    headers = [line for line in text.splitlines() if line.startswith("MSG: ")]
    assert headers == ["MSG: std_msgs/msg/Header", "MSG: builtin_interfaces/msg/Time"]
    assert text.count(SEPARATOR) == 2 and not text.startswith("MSG")
    with pytest.raises(DefinitionNotFoundError):
        message_definition("no_such_msgs/msg/Thing", get_package_share_directory)


def test_throttle_keeps_one_message_per_period_per_topic() -> None:
    throttle = Throttle(1.0)
    times = [int(t * 1e8) for t in range(35)]  # 10 Hz for 3.5 s
    kept = [t for t in times if throttle.keep("/a", t)]
    assert kept == [0, 10**9, 2 * 10**9, 3 * 10**9]
    assert throttle.keep("/b", 5 * 10**8)  # topics are thinned separately
    assert not any(Throttle(0.0).keep("/a", t) for t in times)
    with pytest.raises(ValueError):
        Throttle(-1.0)


def test_header_stamp_is_read_from_the_raw_message() -> None:
    image = Image(height=1, width=1, encoding="rgb8", step=3, data=b"abc")
    image.header.stamp.sec, image.header.stamp.nanosec = 12, 500_000_000
    assert header_stamp(serialize_message(image)) == 12_500_000_000
    assert header_stamp(b"\x00\x01") is None


def test_mcap_sink_round_trip(tmp_path: Path) -> None:
    path = tmp_path / "x.mcap"
    sink = McapSink(path)
    definition = message_definition("std_msgs/msg/String", get_package_share_directory)
    sink.add_channel("/words", "std_msgs/msg/String", definition, {"durability": "volatile"})
    for i, word in enumerate(["one", "two"]):
        sink.write("/words", serialize_message(String(data=word)), 10 + i, 10 + i)
    sink.close()
    assert recorded_channels(path) == {
        "/words": ("std_msgs/msg/String", {"durability": "volatile"})
    }
    messages = list(recorded_messages(path))
    assert [m.log_time for m in messages] == [10, 11]
    assert [decode(m.type_name, m.data).data for m in messages] == ["one", "two"]


# ---------------------------------------------------------------- with real processes
class Listener:
    def __init__(self, node: Node) -> None:
        self.received: dict[str, list] = {"/joint_states": [], "/latched": []}
        node.create_subscription(
            JointState, "/joint_states", self.received["/joint_states"].append, 100
        )
        node.create_subscription(String, "/latched", self.received["/latched"].append, LATCHED)


RECORDED_TOPICS = ("/camera_2/depth/image_raw", "/joint_states", "/clock", "/latched")


@pytest.fixture(scope="module")
def recording(tmp_path_factory) -> Iterator[tuple[Path, dict[str, str], Node, Path]]:
    """A live sim_node (cameras at 2 Hz, images kept at 1 Hz) and a transient local topic
    published once before the recorder started, recorded until camera_2 sent 4 frames
    after both recorders subscribed; the live graph's types; and the file of a second
    recorder (every image). Both are stopped by SIGINT, as the bring-up stops them: how
    much a fixed wall-clock span holds depends on the machine's load."""
    folder = tmp_path_factory.mktemp("record")
    path, interrupted = folder / "run.mcap", folder / "interrupted.mcap"
    rclpy.init()
    probe = Node("record_probe")
    latch = Node("latch")
    latch.create_publisher(String, "/latched", LATCHED).publish(String(data="published once"))
    sim_arguments = ["--ros-args", "-p", "domino_count:=2", "-p", "camera_rate:=2.0"]
    with installed_node("dombot_sim", "sim_node", *sim_arguments) as sim:
        images = []
        probe.create_subscription(Image, "/camera_2/color/image_raw", images.append, 2)
        assert spin_until(probe, lambda: bool(images), 120), sim.poll()
        record = ("dombot_bringup", "record", "-o")
        with (
            installed_node(
                *record, str(interrupted), "--image-rate", "100", output=PIPE
            ) as stopped,
            installed_node(*record, str(path), "--image-rate", "1", output=PIPE) as recorder,
        ):

            def subscribed() -> bool:
                return all(probe.count_subscribers(t) >= 2 for t in RECORDED_TOPICS)

            assert spin_until(probe, subscribed, 120), "the recorders never subscribed"
            images.clear()
            assert spin_until(probe, lambda: len(images) >= 4, 120), "camera_2 stopped"
            for process in (recorder, stopped):
                process.send_signal(signal.SIGINT)
            assert recorder.wait(timeout=120) == 0, recorder.stdout.read()
            assert stopped.wait(timeout=120) == 0, stopped.stdout.read()
        live = {
            topic: types[0]
            for topic, types in probe.get_topic_names_and_types()
            if not is_hidden(topic)
        }
        assert sim.poll() is None, "sim_node died"
    latch.destroy_node()
    yield path, live, probe, interrupted
    probe.destroy_node()
    rclpy.shutdown()


@pytest.mark.slow
def test_recording_has_every_topic_with_the_live_types(recording) -> None:
    path, live, _, _ = recording
    channels = {topic: kind for topic, (kind, _) in recorded_channels(path).items()}
    for topic in ("/clock", "/joint_states", "/camera_0/color/image_raw", "/latched"):
        assert topic in channels, f"{topic} not recorded: {sorted(channels)}"
    assert {t: live[t] for t in channels} == channels  # every channel with its live type
    counts: dict[str, int] = {}
    image_stamps: dict[str, list[int]] = {}
    for message in recorded_messages(path):
        counts[message.topic] = counts.get(message.topic, 0) + 1
        if message.type_name == "sensor_msgs/msg/Image":
            image_stamps.setdefault(message.topic, []).append(header_stamp(message.data))
    assert counts["/joint_states"] >= 2 and counts["/clock"] >= 2
    assert counts["/latched"] == 1  # published before the recorder started: transient local
    for topic, stamps in image_stamps.items():  # 2 Hz frames thinned to 1 Hz of their stamps
        assert np.all(np.diff(stamps) > 0.999e9), (topic, stamps)  # (stamps rounded to ns)
    assert "/camera_2/depth/image_raw" in image_stamps


@pytest.mark.slow
def test_every_message_decodes_from_its_recorded_schema(recording) -> None:
    path, _, _, _ = recording
    seen = {}
    for message in read_ros2_messages(str(path)):
        seen[message.channel.topic] = message.ros_msg
    assert seen["/latched"].data == "published once"
    assert len(seen["/joint_states"].name) == len(seen["/joint_states"].position) >= 9
    image = seen["/camera_0/depth/image_raw"]
    assert image.encoding == "32FC1" and len(image.data) == image.height * image.step


@pytest.mark.slow
def test_replay_publishes_the_recorded_messages(recording) -> None:
    path, _, probe, _ = recording
    recorded = {
        m.header.stamp.sec * 10**9 + m.header.stamp.nanosec
        for m in (msg.ros_msg for msg in read_ros2_messages(str(path), topics=["/joint_states"]))
    }
    listener = Listener(probe)
    with installed_node("dombot_bringup", "replay", str(path), output=PIPE) as replay:
        assert spin_until(probe, lambda: replay.poll() is not None, 120)
        assert replay.returncode == 0, replay.stdout.read()
    spin_until(probe, lambda: False, 0.5)  # the last messages' way
    received = listener.received["/joint_states"]
    assert received, "no /joint_states from the replay"
    stamps = {m.header.stamp.sec * 10**9 + m.header.stamp.nanosec for m in received}
    assert stamps <= recorded  # the recorded messages, nothing else
    assert [m.data for m in listener.received["/latched"]] == ["published once"]


@pytest.mark.slow
def test_a_recorder_stopped_by_sigint_leaves_a_readable_file(recording) -> None:
    _, _, _, interrupted = recording
    topics = {m.topic for m in recorded_messages(interrupted)}  # reads every chunk
    assert {"/joint_states", "/camera_2/color/image_raw"} <= topics


@pytest.mark.slow
def test_a_recorder_with_a_duration_stops_by_itself(tmp_path: Path) -> None:
    path = tmp_path / "short.mcap"
    with installed_node(
        "dombot_bringup", "record", "-o", str(path), "--duration", "1", output=PIPE
    ) as recorder:
        assert recorder.wait(timeout=120) == 0, recorder.stdout.read()
    assert isinstance(recorded_channels(path), dict)  # a complete, readable file


@pytest.mark.slow
def test_replay_refuses_what_is_not_a_recording(tmp_path: Path) -> None:
    bogus = tmp_path / "not.mcap"
    bogus.write_text("hello")
    with installed_node("dombot_bringup", "replay", str(bogus), output=PIPE) as replay:
        assert replay.wait(timeout=120) == 2
        assert "cannot read" in replay.stdout.read()

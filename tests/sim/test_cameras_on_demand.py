"""sim_node renders a camera only while someone subscribes to one of its topics: frames
counted in a real SimNode (Drake's VTK cameras, real DDS), its loop unpaced in a thread."""

from __future__ import annotations

import threading
import time

import pytest
import rclpy
from rclpy.executors import MultiThreadedExecutor
from rclpy.node import Node
from sensor_msgs.msg import Image

from dombot_adapters.node_shutdown import BackgroundSpinner
from dombot_sim.sim_node import SimNode
from support.ros_processes import spin_until

RATE = 5.0  # Hz simulated: a second unwatched would have rendered 5 frames a camera


@pytest.fixture(scope="module")
def sim():
    rclpy.init(
        args=[
            "--ros-args",
            *("-p", "domino_count:=0", "-p", "real_time_factor:=0.0"),
            *("-p", f"camera_rate:={RATE}", "-p", "ground_truth_rate:=0.0"),
        ]
    )
    node = SimNode()
    executor = MultiThreadedExecutor(num_threads=2)
    executor.add_node(node)
    spinner = BackgroundSpinner(executor, node)
    stop = threading.Event()
    loop = threading.Thread(target=node.run, args=(stop,), daemon=True)
    loop.start()
    viewer = Node("camera_viewer")
    yield node, viewer
    stop.set()
    loop.join(timeout=10)
    spinner.stop()
    viewer.destroy_node()
    node.destroy_node()
    rclpy.shutdown()


def advance(node: SimNode, viewer: Node, seconds: float) -> None:
    """Let ``seconds`` of simulated time pass (spinning the viewer meanwhile)."""
    target = node.world.time + seconds
    assert spin_until(viewer, lambda: node.world.time >= target, timeout=300)


def test_nothing_is_rendered_while_nobody_subscribes(sim) -> None:
    node, viewer = sim
    advance(node, viewer, 2.0)
    assert node.frames_rendered == dict.fromkeys(node.world.camera_names, 0)


def test_a_subscriber_gets_frames_of_its_camera_only_and_only_while_it_listens(sim) -> None:
    node, viewer = sim
    frames: list[Image] = []
    subscription = viewer.create_subscription(Image, "/camera_2/color/image_raw", frames.append, 5)
    assert spin_until(viewer, lambda: len(frames) >= 3, timeout=120), node.frames_rendered
    assert node.frames_rendered["camera_2"] >= 3
    assert node.frames_rendered["camera_0"] == node.frames_rendered["camera_1"] == 0
    assert frames[-1].header.frame_id == "camera_2_optical"

    viewer.destroy_subscription(subscription)
    publisher = node._camera_pubs["camera_2"][0]
    deadline = time.monotonic() + 60
    while publisher.get_subscription_count() and time.monotonic() < deadline:
        time.sleep(0.05)
    advance(node, viewer, 1.0 / RATE)  # a frame may have been on its way
    rendered = dict(node.frames_rendered)
    advance(node, viewer, 2.0)
    assert node.frames_rendered == rendered

"""Messages and services cross process boundaries over real Fast DDS."""

from __future__ import annotations

import pytest
import rclpy
from rclpy.node import Node

from dombot_msgs.msg import DominoDetectionArray
from dombot_msgs.srv import ResetSim
from support.ros_processes import call_service, python_process, spin_until

pytestmark = pytest.mark.slow  # node processes over DDS

TALKER = """
import rclpy
from dombot_msgs.msg import DominoDetection, DominoDetectionArray
rclpy.init()
node = rclpy.create_node("foundation_talker")
pub = node.create_publisher(DominoDetectionArray, "/foundation/detections", 10)
count = 0
def publish():
    global count
    count += 1
    msg = DominoDetectionArray(detections=[DominoDetection(id=count, score=0.5)])
    msg.header.frame_id = "world"
    pub.publish(msg)
node.create_timer(0.05, publish)
rclpy.spin(node)
"""

RESET_SERVER = """
import rclpy
from dombot_msgs.srv import ResetSim
rclpy.init()
node = rclpy.create_node("foundation_reset_server")
def reset(request, response):
    response.success = request.domino_count > 0
    response.message = f"pile of {request.domino_count} from seed {request.seed}"
    response.settle_time = 0.01 * request.domino_count
    return response
node.create_service(ResetSim, "/foundation/reset", reset)
rclpy.spin(node)
"""


@pytest.fixture
def node():
    rclpy.init()
    test_node = Node("foundation_test")
    yield test_node
    test_node.destroy_node()
    rclpy.shutdown()


def test_custom_message_published_in_one_process_arrives_in_another(node: Node) -> None:
    received: list[DominoDetectionArray] = []
    node.create_subscription(DominoDetectionArray, "/foundation/detections", received.append, 10)
    with python_process(TALKER) as talker:
        assert spin_until(node, lambda: len(received) >= 3, timeout=30), talker.poll()
    ids = [msg.detections[0].id for msg in received]
    assert ids == sorted(ids) and ids[0] >= 1
    assert received[0].header.frame_id == "world"


def test_service_call_crosses_processes(node: Node) -> None:
    client = node.create_client(ResetSim, "/foundation/reset")
    with python_process(RESET_SERVER):
        response = call_service(node, client, ResetSim.Request(domino_count=12, seed=4), 10)
    assert response is not None and response.success
    assert response.message == "pile of 12 from seed 4"
    assert response.settle_time == pytest.approx(0.12)

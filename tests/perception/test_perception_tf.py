"""perception_node with extrinsics_from_tf over real DDS: a best-effort camera (as
realsense-ros publishes, sensor-data QoS) in frames named by its driver, placed in world
by /tf_static through a calibration chain; the detections follow the transforms."""

from __future__ import annotations

import time
from collections.abc import Callable

import numpy as np
import pytest
import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, qos_profile_sensor_data
from sensor_msgs.msg import CameraInfo, Image
from tf2_msgs.msg import TFMessage

from dombot_msgs.srv import DetectDominoes
from support.camera_messages import image_messages, transform_stamped
from support.perception_scenes import PILE_CENTRE, flat
from support.ros_processes import call_service, installed_node, spin_until

TRUTH = flat(*PILE_CENTRE, yaw=-0.3)
pytestmark = pytest.mark.slow  # a perception_node process

RIG = np.eye(4)  # the cameras' mount in world, as a calibration would publish it
RIG[:3, 3] = [0.5, -0.5, 0.4]


def driver_frame(camera: str) -> str:
    return f"{camera}_color_optical_frame"  # realsense-ros's name, not sim_node's


class Camera:
    """Plays rendered frames best effort and publishes world → rig → optical frames."""

    def __init__(self, views) -> None:
        self.node = Node("realsense_like")
        self.views = views
        self.publishers = {
            view.name: [
                self.node.create_publisher(kind, f"/{view.name}/{topic}", qos_profile_sensor_data)
                for kind, topic in (
                    (Image, "color/image_raw"),
                    (Image, "depth/image_raw"),
                    (CameraInfo, "color/camera_info"),
                )
            ]
            for view in views
        }
        latched = QoSProfile(depth=1, durability=DurabilityPolicy.TRANSIENT_LOCAL)
        self.static = self.node.create_publisher(TFMessage, "/tf_static", latched)
        self.detect = self.node.create_client(DetectDominoes, "/perception/detect")
        self.node.create_timer(0.2, self.play)

    def play(self) -> None:
        stamp = self.node.get_clock().now().to_msg()
        for view in self.views:
            messages = image_messages(view, stamp, frame_id=driver_frame(view.name))
            for publisher, message in zip(self.publishers[view.name], messages, strict=True):
                publisher.publish(message)

    def calibrate(self, x_wr: np.ndarray) -> None:
        """/tf_static: world → rig at x_wr; rig → each optical frame where the scenario's
        camera is when the rig is at RIG (one message: depth 1 keeps only the last)."""
        transforms = [("world", "camera_rig", x_wr)] + [
            ("camera_rig", driver_frame(view.name), np.linalg.inv(RIG) @ view.X_WC)
            for view in self.views
        ]
        self.static.publish(TFMessage(transforms=[transform_stamped(*t) for t in transforms]))

    def detect_until(
        self, done: Callable[[np.ndarray | None, str], bool], timeout: float = 120.0
    ) -> tuple[np.ndarray | None, str]:
        """The first answer ``done`` accepts, or the last after ``timeout``: best effort,
        a detect may find a camera's colour or depth image dropped, so one answer is not
        the camera's last word."""
        deadline = time.monotonic() + timeout
        answer = self.detected_position()
        while not done(*answer) and time.monotonic() < deadline:
            rclpy.spin_once(self.node, timeout_sec=0.05)
            answer = self.detected_position()
        return answer

    def detected_position(self) -> tuple[np.ndarray | None, str]:
        response = call_service(self.node, self.detect, DetectDominoes.Request(), timeout=60)
        assert response is not None, "no answer from /perception/detect"
        if not response.success or len(response.detections.detections) != 1:
            return None, response.message
        p = response.detections.detections[0].pose.position
        return np.array([p.x, p.y, p.z]), response.message


@pytest.fixture(scope="module")
def camera(render_scene):
    views = render_scene({0: TRUTH})
    rclpy.init()
    arguments = [
        "--ros-args",
        *("-p", "extrinsics_from_tf:=true"),
        *("-p", "image_reliability:=best_effort"),  # as a realsense-ros user sets it
        *("-p", "cameras:=[camera_0, camera_1]"),
        *("-p", "continuous:=false"),
    ]
    with installed_node("dombot_perception", "perception_node", *arguments) as process:
        camera = Camera(views)
        assert spin_until(camera.node, camera.detect.service_is_ready, 120), process.poll()
        yield camera
        camera.node.destroy_node()
        assert process.poll() is None, "perception_node died during the tests"
    rclpy.shutdown()


def test_no_camera_pose_without_transforms_then_the_calibrated_pose(camera: Camera) -> None:
    """Before /tf_static says where the cameras are, no view is usable and the answer
    names the missing frame; with it, the domino is where it lies."""
    frame = driver_frame("camera_0")
    position, message = camera.detect_until(lambda position, message: frame in message)
    assert position is None and frame in message, message
    camera.calibrate(RIG)
    position, message = camera.detect_until(lambda position, message: position is not None)
    assert position is not None and np.linalg.norm(position - TRUTH[:3, 3]) < 0.003, message


def test_a_moved_rig_moves_the_detection_with_it(camera: Camera) -> None:
    shift = np.array([0.0, 0.015, 0.0])
    moved = RIG.copy()
    moved[:3, 3] += shift
    camera.calibrate(moved)

    def shifted(position: np.ndarray | None, message: str) -> bool:
        return position is not None and np.linalg.norm(position - TRUTH[:3, 3]) > 0.0075

    position, message = camera.detect_until(shifted)
    assert shifted(position, message), message
    assert np.linalg.norm(position - (TRUTH[:3, 3] + shift)) < 0.003, message


def test_a_reliable_reader_of_a_best_effort_camera_is_told_so(camera: Camera) -> None:
    """Left at its default (reliable), perception gets nothing from a best-effort camera;
    the answer says so and what to set, instead of only "nothing received"."""
    arguments = [
        "--ros-args",
        *("-r", "__node:=perception_reliable"),
        *("-r", "perception/detect:=reliable/detect"),
        *("-r", "perception/check_placement:=reliable/check_placement"),
        *("-p", "cameras:=[camera_0, camera_1]"),
        *("-p", "continuous:=false"),
    ]
    with installed_node("dombot_perception", "perception_node", *arguments) as process:
        detect = camera.node.create_client(DetectDominoes, "/reliable/detect")
        assert spin_until(camera.node, detect.service_is_ready, 120), process.poll()
        response = call_service(camera.node, detect, DetectDominoes.Request(), timeout=60)
        camera.node.destroy_client(detect)
        assert response is not None and not response.success
        assert "best effort" in response.message, response.message
        assert "image_reliability" in response.message, response.message
        assert process.poll() is None

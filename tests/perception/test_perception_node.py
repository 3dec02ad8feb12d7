"""perception_node over real DDS: camera topics in, poses and detections out, bad input
answered with a message while the node keeps serving."""

from __future__ import annotations

import time

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Time
from geometry_msgs.msg import PoseArray
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.duration import Duration
from rclpy.node import Node
from sensor_msgs.msg import CameraInfo, Image
from std_msgs.msg import Header

from dombot_adapters.pose_messages import pose_message
from dombot_description.grasp import upright_pose
from dombot_msgs.msg import DominoDetection, DominoDetectionArray
from dombot_msgs.srv import CheckPlacement, DetectDominoes
from dombot_perception.domino_model import orientation_error
from dombot_perception.perception_messages import CameraInput
from dombot_perception.perception_parameters import PerceptionParameters
from support.camera_messages import image_messages
from support.perception_scenes import PILE_CENTRE, flat
from support.ros_processes import call_service, installed_node, spin_until

pytestmark = pytest.mark.slow  # a perception_node process

TRUTH = flat(*PILE_CENTRE, yaw=0.4)
STANDING_IN_RUN = upright_pose(0.52, 0.15, 0.4).GetAsMatrix4()  # seen by camera_2


class Cameras:
    """Test-side node: plays rendered frames on the camera topics, calls the node."""

    def __init__(self, views) -> None:
        self.node = Node("camera_player")
        self.views = views
        self.depth_encoding = "32FC1"
        self.playing = {view.name for view in views}
        self.held_stamps: dict[str, Time] = {}  # cameras whose frames keep this stamp
        self.publishers = {
            view.name: (
                self.node.create_publisher(Image, f"/{view.name}/color/image_raw", 2),
                self.node.create_publisher(Image, f"/{view.name}/depth/image_raw", 2),
                self.node.create_publisher(CameraInfo, f"/{view.name}/color/camera_info", 2),
            )
            for view in views
        }
        self.poses: list[PoseArray] = []
        self.detections: list[DominoDetectionArray] = []
        self.debug: list[Image] = []
        self.node.create_subscription(PoseArray, "/domino_poses", self.poses.append, 10)
        self.node.create_subscription(
            DominoDetectionArray, "/domino_detections", self.detections.append, 10
        )
        self.node.create_subscription(Image, "/perception/debug_image", self.debug.append, 2)
        self.node.create_timer(0.2, self.play)

    def play(self) -> None:
        stamp = self.node.get_clock().now().to_msg()
        for view in self.views:
            if view.name in self.playing:
                held = self.held_stamps.get(view.name, stamp)
                messages = image_messages(view, held, self.depth_encoding)
                for publisher, message in zip(self.publishers[view.name], messages, strict=True):
                    publisher.publish(message)

    def call(self, service_type, name: str, request, timeout: float = 60.0):
        client = self.node.create_client(service_type, name)
        response = call_service(self.node, client, request, timeout)
        assert response is not None, f"no response from {name}"
        return response

    def detect(self, cameras: list[str] | None = None) -> DetectDominoes.Response:
        return self.call(
            DetectDominoes, "/perception/detect", DetectDominoes.Request(cameras=cameras or [])
        )

    def check_placement(self, expected: list[np.ndarray]) -> CheckPlacement.Response:
        """The node's answer once it has camera_2's frames: the fixture waits for the pile
        cameras only, and on a loaded CPU camera_2's first frames came later (the check
        answered "no colour, depth and camera_info received yet")."""
        request = CheckPlacement.Request(expected=[pose_message(pose) for pose in expected])
        deadline = time.monotonic() + 120.0
        while True:
            response = self.call(CheckPlacement, "/perception/check_placement", request)
            if "received yet" not in response.message or time.monotonic() > deadline:
                return response
            self.settle(0.5)

    def set_parameter(self, name: str, value: ParameterValue):
        request = SetParameters.Request(parameters=[Parameter(name=name, value=value)])
        return self.call(SetParameters, "/perception_node/set_parameters", request).results[0]

    def settle(self, seconds: float) -> None:
        deadline = time.monotonic() + seconds
        spin_until(self.node, lambda: time.monotonic() > deadline, timeout=seconds + 1)


@pytest.fixture(scope="module")
def cameras(world):
    world.set_domino_poses({0: TRUTH, 1: STANDING_IN_RUN})
    from dombot_perception.frames import CameraView

    views = [CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC) for f in world.render().values()]
    rclpy.init()
    with installed_node(
        "dombot_perception", "perception_node", "--ros-args", "-p", "rate:=2.0"
    ) as process:
        player = Cameras(views)

        def both_cameras_seen() -> bool:
            return any(d.num_cameras == 2 for array in player.detections for d in array.detections)

        assert spin_until(player.node, both_cameras_seen, timeout=180), process.poll()
        yield player
        player.node.destroy_node()
        assert process.poll() is None, "perception_node died during the tests"
    rclpy.shutdown()


def test_detect_service_finds_the_domino_and_topics_carry_it(cameras: Cameras) -> None:
    response = cameras.detect()
    assert response.success, response.message
    assert response.detections.header.frame_id == "world"
    [detection] = response.detections.detections
    position = detection.pose.position
    assert np.linalg.norm([position.x, position.y, position.z] - TRUTH[:3, 3]) < 0.003
    quaternion = detection.pose.orientation
    from scipy.spatial.transform import Rotation

    rotation = Rotation.from_quat([quaternion.x, quaternion.y, quaternion.z, quaternion.w])
    assert orientation_error(rotation.as_matrix(), TRUTH[:3, :3]) < np.radians(3)
    assert detection.posture == DominoDetection.POSTURE_FLAT
    assert detection.num_cameras == 2, response.message
    assert detection.score > 0.5
    assert detection.grasp_width > 0.024
    assert spin_until(cameras.node, lambda: bool(cameras.debug), timeout=120)
    assert cameras.debug[-1].width == 2 * 640 and cameras.debug[-1].encoding == "rgb8"
    latest = cameras.poses[-1]
    assert latest.header.frame_id == "world" and len(latest.poses) == 1
    assert len(cameras.detections[-1].detections) == 1


def test_only_frames_stamped_from_not_before_on_are_paired() -> None:
    """A request's not_before (the arm stopped then) rules out a frame from before, however
    recently it arrived: on a loaded CPU images come after the joint states."""
    camera = CameraInput()
    for seconds in (4.0, 5.0):
        stamp = Time(sec=int(seconds))
        camera.colors.append(Image(header=Header(stamp=stamp)))
        camera.depths.append(Image(header=Header(stamp=stamp)))
    assert camera.latest_pair(0.01)[0].header.stamp.sec == 5
    assert camera.latest_pair(0.01, not_before=5.0)[0].header.stamp.sec == 5
    assert camera.latest_pair(0.01, not_before=5.5) is None


def test_placement_check_over_dds(cameras: Cameras) -> None:
    empty_place = STANDING_IN_RUN.copy()
    empty_place[:2, 3] += [0.06, 0.03]
    response = cameras.check_placement([STANDING_IN_RUN, empty_place])
    assert response.success, response.message
    assert list(response.status) == [
        CheckPlacement.Response.STANDING,
        CheckPlacement.Response.MISSING,
    ]
    assert response.position_error[0] < 0.003 and response.tilt[0] < np.radians(2)
    assert "1 standing" in response.message


def test_placement_check_in_hand_over_dds(cameras: Cameras) -> None:
    """The in_hand field reaches the check: a standing domino (no gripper in this scene) is
    measured from its lower part; a place that is not upright cannot be held there."""
    request = CheckPlacement.Request(expected=[pose_message(STANDING_IN_RUN)], in_hand=True)
    response = cameras.call(CheckPlacement, "/perception/check_placement", request)
    assert response.success, response.message
    assert list(response.status) == [CheckPlacement.Response.STANDING]
    assert response.position_error[0] < 0.003 and response.tilt[0] < np.radians(2)
    request.expected = [pose_message(TRUTH)]  # lying flat
    response = cameras.call(CheckPlacement, "/perception/check_placement", request)
    assert not response.success and "in_hand" in response.message


def test_placement_check_rejects_a_non_unit_quaternion(cameras: Cameras) -> None:
    request = CheckPlacement.Request(expected=[pose_message(STANDING_IN_RUN)])
    request.expected[0].orientation.w *= 2.0
    response = cameras.call(CheckPlacement, "/perception/check_placement", request)
    assert not response.success and "quaternion" in response.message


def test_one_camera_on_request(cameras: Cameras) -> None:
    response = cameras.detect(["camera_1"])
    assert response.success, response.message
    assert [d.num_cameras for d in response.detections.detections] == [1]


def watched(cameras: Cameras) -> list[str]:
    """The cameras whose colour topic perception subscribes to now."""
    return [
        name for name, (color, *_) in cameras.publishers.items() if color.get_subscription_count()
    ]


def test_on_demand_it_listens_only_while_a_request_waits_and_still_detects(
    cameras: Cameras,
) -> None:
    """With continuous off (the bring-up's setting) perception subscribes to a camera only
    while a request waits for its frames, so a simulator that renders only what someone
    watches renders nothing in between; a streaming camera (this player, a realsense)
    serves it just the same."""
    continuous = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=False)
    assert cameras.set_parameter("continuous", continuous).successful
    try:
        assert spin_until(cameras.node, lambda: not watched(cameras), timeout=30), watched(cameras)
        response = cameras.detect()
        assert response.success, response.message
        assert [d.num_cameras for d in response.detections.detections] == [2], response.message
        assert spin_until(cameras.node, lambda: not watched(cameras), timeout=30), watched(cameras)
    finally:
        continuous.bool_value = True
        cameras.set_parameter("continuous", continuous)
    # continuous again: every camera of its ``cameras`` (each one the scenario has)
    assert spin_until(cameras.node, lambda: len(watched(cameras)) == len(cameras.views), 30)


def test_a_placement_check_is_answered_while_a_detect_waits(cameras: Cameras) -> None:
    """The bring-up asks for the in-hand check while the look at the pile for the next
    pick runs: perception answers the check beside the detect, not after it. The pile
    cameras' frames keep an old stamp, so a detect for frames from later waits as long as
    they do; the check, on camera_2 from now on (subscribed for it: its frames come in on
    a thread of their own), answers meanwhile; then the pile's stamps move on and the
    detect answers too. The detect waits for them as long as it takes here, however loaded
    the machine (``fresh_frame_timeout``, 10 s by default)."""
    continuous = ParameterValue(type=ParameterType.PARAMETER_BOOL, bool_value=False)
    assert cameras.set_parameter("continuous", continuous).successful
    patient = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=600.0)
    assert cameras.set_parameter("fresh_frame_timeout", patient).successful
    old = cameras.node.get_clock().now()
    cameras.held_stamps = dict.fromkeys(("camera_0", "camera_1"), old.to_msg())
    try:
        assert spin_until(cameras.node, lambda: not watched(cameras), timeout=30), watched(cameras)
        later = (old + Duration(seconds=0.05)).to_msg()
        detect_client = cameras.node.create_client(DetectDominoes, "/perception/detect")
        detecting = detect_client.call_async(DetectDominoes.Request(not_before=later))
        # the detect waits for the pile cameras' frames: it holds them
        assert spin_until(cameras.node, lambda: "camera_0" in watched(cameras), timeout=60)
        request = CheckPlacement.Request(
            expected=[pose_message(STANDING_IN_RUN)],
            not_before=cameras.node.get_clock().now().to_msg(),
        )
        check = cameras.call(CheckPlacement, "/perception/check_placement", request)
        assert check.success, check.message
        assert list(check.status) == [CheckPlacement.Response.STANDING]
        assert not detecting.done(), detecting.result()  # still waiting for a new pile frame
        cameras.held_stamps = {}
        assert spin_until(cameras.node, detecting.done, timeout=60)
        response = detecting.result()
        assert response.success, response.message
        assert [d.num_cameras for d in response.detections.detections] == [2], response.message
    finally:
        cameras.held_stamps = {}
        continuous.bool_value = True
        cameras.set_parameter("continuous", continuous)
        patient.double_value = PerceptionParameters().fresh_frame_timeout
        cameras.set_parameter("fresh_frame_timeout", patient)
    assert spin_until(cameras.node, lambda: len(watched(cameras)) == len(cameras.views), 30)


def test_unknown_camera_is_an_error_not_a_crash(cameras: Cameras) -> None:
    response = cameras.detect(["camera_9"])
    assert not response.success
    assert "camera_9" in response.message


def test_wrong_depth_encoding_gives_an_empty_result_and_a_warning(cameras: Cameras) -> None:
    cameras.depth_encoding = "mono8"
    try:
        cameras.settle(1.5)  # every buffered depth image is now mono8
        response = cameras.detect()
        assert not response.success
        assert "encoding" in response.message
        assert response.detections.detections == []
    finally:
        cameras.depth_encoding = "32FC1"
        cameras.settle(1.5)
    assert cameras.detect().success


def only_camera_0_left_out(response: DetectDominoes.Response) -> bool:
    words = response.message
    return response.success and "camera_0" in words and "camera_1" not in words


def test_a_camera_that_stops_publishing_is_left_out_with_a_warning(cameras: Cameras) -> None:
    double = ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=1.0)
    assert cameras.set_parameter("max_frame_age", double).successful
    cameras.playing.discard("camera_0")
    try:
        # Past max_frame_age for camera_0; under load the node may take camera_1's frames
        # late too (seen 1.5 s old), so it is asked until only camera_0 is left out.
        cameras.settle(2.0)
        response = cameras.detect()
        deadline = time.monotonic() + 120.0
        while not only_camera_0_left_out(response) and time.monotonic() < deadline:
            cameras.settle(0.5)
            response = cameras.detect()
        assert response.success, response.message
        assert "camera_0" in response.message and "stopped" in response.message
        assert [d.num_cameras for d in response.detections.detections] == [1]
    finally:
        cameras.playing.add("camera_0")
        double.double_value = 5.0
        cameras.set_parameter("max_frame_age", double)


@pytest.mark.parametrize(
    ("name", "value"),
    [
        ("backend", ParameterValue(type=ParameterType.PARAMETER_STRING, string_value="magic")),
        ("backend", ParameterValue(type=ParameterType.PARAMETER_STRING, string_value="sam")),
        ("min_coverage", ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=2.0)),
        ("rate", ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=-1.0)),
        (
            "fresh_frame_timeout",
            ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=0.0),
        ),
    ],
)
def test_bad_parameters_are_rejected_and_the_node_keeps_serving(
    cameras: Cameras, name: str, value: ParameterValue
) -> None:
    result = cameras.set_parameter(name, value)
    assert not result.successful and result.reason
    assert cameras.detect().success

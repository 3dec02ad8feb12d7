"""layer_node over real DDS: radius in, wheel commands out; bad input stops the wheels."""

from __future__ import annotations

import math
import time

import numpy as np
import pytest
import rclpy
from geometry_msgs.msg import PoseStamped
from nav_msgs.msg import Odometry, Path
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, SetParameters
from rclpy.node import Node
from std_msgs.msg import Float64, Float64MultiArray

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import LayerKinematics, wheel_speed_ratio
from dombot_layer.paths import MAX_PATH_BYTES, MAX_POLYLINE_POINTS, rig_length
from dombot_msgs.msg import WheelVelocities
from support.ros_processes import installed_node, spin_until

pytestmark = pytest.mark.slow  # a layer_node process

KINEMATICS = LayerKinematics(VehicleGeometry())


class Probe:
    """Test-side node: publishes targets, records what layer_node sends back."""

    def __init__(self) -> None:
        self.node = Node("layer_probe")
        self.status: list[WheelVelocities] = []
        self.commands: list[Float64MultiArray] = []
        self.node.create_subscription(
            WheelVelocities, "/layer/wheel_velocities", self.status.append, 50
        )
        self.node.create_subscription(
            Float64MultiArray, "/wheel_velocity_controller/commands", self.commands.append, 50
        )
        self.radius_pub = self.node.create_publisher(Float64, "/layer/target_radius", 10)
        self.path_pub = self.node.create_publisher(Path, "/layer/path", 10)

    def send_radius(self, radius: float, expect) -> WheelVelocities:
        """Publish until a status satisfying ``expect`` arrives (the subscriber may join late)."""
        self.status.clear()

        def arrived() -> bool:
            if not any(expect(s) for s in self.status):
                self.radius_pub.publish(Float64(data=radius))
                return False
            return True

        assert spin_until(self.node, arrived, timeout=30), self.status[-1:] or "no status"
        return next(s for s in self.status if expect(s))

    def call(self, service_type, name: str, request):
        client = self.node.create_client(service_type, name)
        assert spin_until(self.node, client.service_is_ready, timeout=30)
        future = client.call_async(request)
        assert spin_until(self.node, future.done, timeout=10)
        return future.result()


@pytest.fixture(scope="module")
def probe():
    rclpy.init()
    with installed_node("dombot_layer", "layer_node") as process:
        probe = Probe()
        assert spin_until(probe.node, lambda: bool(probe.status), timeout=30), process.poll()
        yield probe
        probe.node.destroy_node()
        assert process.poll() is None, "layer_node died during the tests"
    rclpy.shutdown()


def test_radius_gives_wheel_commands_with_the_right_ratio(probe: Probe) -> None:
    status = probe.send_radius(0.5, lambda s: s.deposit_radius == 0.5)
    r_m = KINEMATICS.midpoint_radius(0.5)
    assert status.status == WheelVelocities.STATUS_OK
    assert status.midpoint_radius == pytest.approx(r_m, abs=1e-12)
    assert status.wheel_speed_ratio == pytest.approx(wheel_speed_ratio(KINEMATICS.geometry, r_m))
    assert status.left / status.right == pytest.approx(status.wheel_speed_ratio)
    assert spin_until(
        probe.node,
        lambda: any(
            list(c.data) == pytest.approx([status.left, status.right]) for c in probe.commands
        ),
        timeout=10,
    )


def test_right_turn_swaps_the_inner_wheel(probe: Probe) -> None:
    status = probe.send_radius(-0.5, lambda s: s.deposit_radius == -0.5)
    assert status.status == WheelVelocities.STATUS_OK
    assert status.right < status.left
    assert status.right / status.left == pytest.approx(status.wheel_speed_ratio)


@pytest.mark.parametrize(
    ("radius", "code", "text"),
    [
        (0.01, WheelVelocities.STATUS_UNREACHABLE, "minimum laying radius"),
        (math.nan, WheelVelocities.STATUS_INVALID, "NaN"),
        (0.0, WheelVelocities.STATUS_UNREACHABLE, "zero radius"),
    ],
)
def test_bad_radius_stops_the_wheels_with_a_reason(
    probe: Probe, radius: float, code: int, text: str
) -> None:
    status = probe.send_radius(radius, lambda s: s.status == code and text in s.message)
    assert (status.left, status.right) == (0.0, 0.0)
    # ...and the node still serves good requests afterwards.
    assert (
        probe.send_radius(2.0, lambda s: s.deposit_radius == 2.0).status
        == WheelVelocities.STATUS_OK
    )


def set_parameter(probe: Probe, name: str, value: float):
    parameter = Parameter(
        name=name, value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=value)
    )
    return probe.call(
        SetParameters, "/layer_node/set_parameters", SetParameters.Request(parameters=[parameter])
    )


def get_parameter(probe: Probe, name: str) -> float:
    result = probe.call(
        GetParameters, "/layer_node/get_parameters", GetParameters.Request(names=[name])
    )
    return result.values[0].double_value


def test_invalid_parameter_update_is_rejected_and_keeps_the_old_value(probe: Probe) -> None:
    result = set_parameter(probe, "geometry.d_tw", -0.2)
    assert not result.results[0].successful
    assert "d_tw must be positive" in result.results[0].reason
    assert get_parameter(probe, "geometry.d_tw") == VehicleGeometry().d_tw
    result = set_parameter(probe, "forward_speed", 0.0)
    assert not result.results[0].successful
    result = set_parameter(probe, "command_rate", 1e-63)  # a timer period beyond int64 ns
    assert not result.results[0].successful
    assert "command_rate must be a number in [0.01, 1000.0]" in result.results[0].reason
    assert probe.send_radius(0.5, lambda s: s.deposit_radius == 0.5).status == (
        WheelVelocities.STATUS_OK
    )


def test_valid_parameter_update_changes_the_commands(probe: Probe) -> None:
    assert set_parameter(probe, "forward_speed", 0.2).results[0].successful
    try:
        status = probe.send_radius(
            math.inf, lambda s: s.deposit_radius == math.inf and s.forward_speed == 0.2
        )
        assert status.left == pytest.approx(0.2 / VehicleGeometry().wheel_radius)
        assert status.wheel_speed_ratio == 1.0
    finally:
        set_parameter(probe, "forward_speed", 0.1)


def straight_path(length: float) -> Path:
    path = Path()
    path.header.frame_id = "layer_start"
    for x in (0.0, length / 2, length):
        pose = PoseStamped()
        pose.pose.position.x = x
        path.poses.append(pose)
    return path


def test_path_plays_a_schedule_then_stops(probe: Probe) -> None:
    """No odometry: the schedule runs on the clock."""
    probe.status.clear()
    probe.path_pub.publish(straight_path(0.2))
    assert spin_until(
        probe.node, lambda: any("path piece" in s.message for s in probe.status), timeout=15
    )
    # 0.2 m at 0.1 m/s: the schedule ends after ~2 s with a stop.
    assert spin_until(
        probe.node, lambda: any(s.message == "path finished" for s in probe.status), timeout=15
    )
    assert probe.status[-1].left == 0.0


@pytest.mark.parametrize(
    ("poses", "text"),
    [
        (MAX_POLYLINE_POINTS + 1, "at most 10000 points"),  # checked on the points
        (MAX_PATH_BYTES // 64, "a path message is at most"),  # checked before deserialising
    ],
)
def test_too_large_a_path_stops_the_wheels_with_a_reason(
    probe: Probe, poses: int, text: str
) -> None:
    path = Path()
    path.header.frame_id = "layer_start"
    path.poses = [PoseStamped() for _ in range(poses)]
    for i, pose in enumerate(path.poses):
        pose.pose.position.x = 0.001 * i
    probe.status.clear()
    probe.path_pub.publish(path)
    assert spin_until(
        probe.node, lambda: any(text in s.message for s in probe.status), timeout=30
    ), [s.message for s in probe.status[-3:]]
    rejected = next(s for s in probe.status if text in s.message)
    assert rejected.status == WheelVelocities.STATUS_UNREACHABLE
    assert (rejected.left, rejected.right) == (0.0, 0.0)


def test_with_odometry_the_schedule_follows_the_distance_travelled(probe: Probe) -> None:
    odometry_pub = probe.node.create_publisher(Odometry, "/layer/odom", 10)

    def report(x: float) -> None:
        message = Odometry()
        message.pose.pose.position.x = x
        odometry_pub.publish(message)

    # The node must hear the vehicle before the path, as in the bring-up.
    assert spin_until(probe.node, lambda: odometry_pub.get_subscription_count() > 0, timeout=15)
    report(0.0)
    probe.status.clear()
    probe.path_pub.publish(straight_path(0.2))
    assert spin_until(
        probe.node, lambda: any("path piece" in s.message for s in probe.status), timeout=15
    )
    # A stalled vehicle: 3 s is longer than the 2 s schedule, but nothing has moved.
    deadline = time.monotonic() + 3.0
    spin_until(probe.node, lambda: time.monotonic() > deadline, timeout=4)
    assert not any(s.message == "path finished" for s in probe.status)
    assert probe.status[-1].left > 0.0
    # The path plus the rig-length lead-out the deposit point needs to finish it.
    for x in np.linspace(0.05, 0.2 + rig_length(VehicleGeometry()) + 0.05, 8):
        report(float(x))
    assert spin_until(
        probe.node, lambda: any(s.message == "path finished" for s in probe.status), timeout=15
    )
    probe.node.destroy_publisher(odometry_pub)

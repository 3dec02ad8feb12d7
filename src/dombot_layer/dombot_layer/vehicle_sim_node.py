"""vehicle_sim_node: the domino-laying vehicle simulated from wheel commands.

Subscribes to the ros2_control wheel commands layer_node publishes, integrates the
tractor–trolley model (``vehicle_sim``), and publishes odometry and the dominoes
laid so far, so the whole laying loop runs over ROS with no hardware. Frames:
``layer_start`` is where the vehicle started (M at the origin, heading +x);
``layer_base`` is the drive-axle midpoint M.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from geometry_msgs.msg import Pose, PoseArray
from nav_msgs.msg import Odometry
from rclpy.node import Node
from std_msgs.msg import Float64MultiArray

from dombot_adapters.parameters import DataclassParameters, described
from dombot_layer.geometry import VehicleGeometry
from dombot_layer.layer_node import GEOMETRY_PREFIX, spin
from dombot_layer.vehicle_sim import VehicleSimulator

START_FRAME = "layer_start"
BASE_FRAME = "layer_base"


@dataclass(frozen=True)
class VehicleSimSettings:
    """vehicle_sim_node's own parameters (read at start-up)."""

    deposit_spacing: float = described(0.03, "domino spacing [m]")
    rate: float = described(50.0, "integration/publish rate [Hz]")


class VehicleSimNode(Node):
    def __init__(self) -> None:
        super().__init__("vehicle_sim_node")
        geometry = DataclassParameters(
            self, VehicleGeometry, GEOMETRY_PREFIX, "vehicle dimension [m], see docs/LAYER.md"
        )
        settings = DataclassParameters(self, VehicleSimSettings).read()
        spacing = settings.deposit_spacing
        self.simulator = VehicleSimulator(geometry.read(), spacing)
        self.command = (0.0, 0.0)
        self.deposits: list[np.ndarray] = []
        self.period = 1.0 / settings.rate
        self.odom_pub = self.create_publisher(Odometry, "layer/odom", 10)
        self.deposit_pub = self.create_publisher(PoseArray, "layer/deposits", 10)
        self.create_subscription(
            Float64MultiArray, "wheel_velocity_controller/commands", self._on_command, 10
        )
        self.last_step = self._now()
        self.create_timer(self.period, self._step)
        self.get_logger().info(f"simulating {self.simulator.geometry}, spacing {spacing} m")

    def _on_command(self, message: Float64MultiArray) -> None:
        values = list(message.data)
        if len(values) != 2 or not all(math.isfinite(v) for v in values):
            self.get_logger().error(
                f"ignoring wheel command {values}: need two finite [left, right] rad/s"
            )
            return
        self.command = (values[0], values[1])

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9

    def _step(self) -> None:
        """Integrate over the time that really passed, not the nominal period: a late
        timer on a loaded CPU must not slow the vehicle down against the layer's schedule."""
        now = self._now()
        elapsed, self.last_step = now - self.last_step, now
        if elapsed > 5 * self.period:
            self.get_logger().warning(
                f"integration tick {elapsed * 1e3:.0f} ms late (period {self.period * 1e3:.0f} ms)"
            )
        laid = self.simulator.step(*self.command, elapsed)
        if laid.size:
            self.deposits.extend(laid)
            self.get_logger().info(
                f"laid domino {len(self.deposits)} at ({laid[-1][0]:.3f}, {laid[-1][1]:.3f}) m"
            )
        stamp = self.get_clock().now().to_msg()
        self.odom_pub.publish(self._odometry(stamp))
        deposits = PoseArray()
        deposits.header.stamp = stamp
        deposits.header.frame_id = START_FRAME
        deposits.poses = [self._pose(x, y) for x, y in self.deposits]
        self.deposit_pub.publish(deposits)

    def _odometry(self, stamp) -> Odometry:
        x, y, heading = self.simulator.pose()
        odometry = Odometry()
        odometry.header.stamp = stamp
        odometry.header.frame_id = START_FRAME
        odometry.child_frame_id = BASE_FRAME
        odometry.pose.pose = self._pose(x, y, heading)
        g = self.simulator.geometry
        left, right = self.command
        odometry.twist.twist.linear.x = g.wheel_radius * (left + right) / 2.0
        odometry.twist.twist.angular.z = g.wheel_radius * (right - left) / g.d_w
        return odometry

    @staticmethod
    def _pose(x: float, y: float, heading: float = 0.0) -> Pose:
        pose = Pose()
        pose.position.x, pose.position.y = float(x), float(y)
        pose.orientation.z, pose.orientation.w = math.sin(heading / 2), math.cos(heading / 2)
        return pose


def main(args: list[str] | None = None) -> None:
    spin(VehicleSimNode, args)


if __name__ == "__main__":
    main()

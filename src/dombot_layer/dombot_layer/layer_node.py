"""layer_node: deposit radius or path in, left/right wheel velocity commands out.

A thin ROS adapter over ``kinematics`` and ``paths``: parameters hold the vehicle
geometry and speed (validated; a rejected update keeps the old values), a target
radius sets a steady command, a path plays a time-stamped schedule. Commands are
streamed at ``command_rate`` on the ros2_control forward-command topic and as the
richer ``dombot_msgs/WheelVelocities``. While ``layer/odom`` arrives, a path's
schedule advances with the distance the drive axle really travelled (wheel
odometry), so a vehicle that starts late or lags still steers each piece where
it belongs and lays the whole path; without odometry it advances with the clock.
Anything unreachable or malformed stops the wheels and says why; the node keeps
serving.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
import rclpy
from nav_msgs.msg import Odometry, Path
from rcl_interfaces.msg import SetParametersResult
from rclpy.executors import SingleThreadedExecutor
from rclpy.node import Node
from rclpy.parameter import Parameter
from rclpy.serialization import deserialize_message
from std_msgs.msg import Float64, Float64MultiArray

from dombot_adapters.node_shutdown import spin_until_shutdown
from dombot_adapters.parameters import DataclassParameters, described
from dombot_description.allocator import release_memory, tune_allocator
from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import (
    LayerKinematics,
    UnreachableRadiusError,
    wheel_angular_velocities,
    wheel_speed_ratio,
)
from dombot_layer.paths import (
    MAX_PATH_BYTES,
    PathError,
    WheelSchedule,
    path_segments,
    schedule_segments,
)
from dombot_msgs.msg import WheelVelocities

GEOMETRY_PREFIX = "geometry."
# largest accepted value of each setting: 1000 Hz (faster floods the topics), 10 m/s, 1 m
MAX_SETTING = {"command_rate": 1000.0, "forward_speed": 10.0, "deposit_spacing": 1.0}
# Hz: slower is no stream, and a rate of 1e-63 made a timer period beyond int64 ns that
# killed the node (a TypeError in the parameter callback)
MIN_SETTING = {"command_rate": 0.01}
BIG_MESSAGE_BYTES = 1 << 20  # a path this large leaves freed pages worth handing back


@dataclass(frozen=True)
class Driving:
    """How the vehicle is driven; each a number in (0, MAX_SETTING], at least MIN_SETTING."""

    forward_speed: float = described(0.1, "front-axle midpoint speed [m/s]")
    deposit_spacing: float = described(0.03, "domino spacing on paths [m]")
    command_rate: float = described(20.0, "command publish rate [Hz]")

    def __post_init__(self) -> None:
        for name, most in MAX_SETTING.items():
            value, least = getattr(self, name), MIN_SETTING.get(name)
            if (
                isinstance(value, bool)
                or not isinstance(value, int | float)
                or not (math.isfinite(value) and 0 < value <= most)
                or (least is not None and value < least)
            ):
                bounds = f"[{least}, {most}]" if least is not None else f"(0, {most}]"
                raise ValueError(f"{name} must be a number in {bounds}, got {value!r}")


class LayerNode(Node):
    def __init__(self) -> None:
        super().__init__("layer_node")
        self.geometry_parameters = DataclassParameters(
            self, VehicleGeometry, GEOMETRY_PREFIX, "vehicle dimension [m], see docs/LAYER.md"
        )
        self.driving_parameters = DataclassParameters(self, Driving)
        self.driving = self.driving_parameters.read()
        self.kinematics = LayerKinematics(self.geometry_parameters.read())
        self.add_on_set_parameters_callback(self._on_set_parameters)

        self.command_pub = self.create_publisher(
            Float64MultiArray, "wheel_velocity_controller/commands", 10
        )
        self.status_pub = self.create_publisher(WheelVelocities, "layer/wheel_velocities", 10)
        self.create_subscription(Float64, "layer/target_radius", self._on_target_radius, 10)
        # raw: a path's size is checked before rclpy turns each pose into Python objects
        self.create_subscription(Path, "layer/path", self._on_path, 10, raw=True)
        self.create_subscription(Odometry, "layer/odom", self._on_odometry, 10)
        self.command = self._stop_command(
            WheelVelocities.STATUS_STOPPED, "waiting for a target radius or path"
        )
        self.schedule: WheelSchedule | None = None
        self.schedule_start = 0.0
        self.last_position: np.ndarray | None = None
        self.travelled = 0.0  # m by the drive axle since the path started (odometry)
        self.timer = self.create_timer(1.0 / self.driving.command_rate, self._publish)
        minimum = self.kinematics.minimum_laying_radius
        self.get_logger().info(
            f"ready: minimum laying radius {minimum('left'):.4f} m (left), "
            f"{minimum('right'):.4f} m (right)"
        )

    # ------------------------------------------------------------------ parameters
    def _on_set_parameters(self, parameters: list[Parameter]) -> SetParametersResult:
        try:
            geometry = self.geometry_parameters.read(parameters)
            driving = self.driving_parameters.read(parameters)
        except ValueError as error:
            self.get_logger().error(f"rejected parameter update: {error}")
            return SetParametersResult(successful=False, reason=str(error))
        if geometry != self.kinematics.geometry:
            self.kinematics = LayerKinematics(geometry)
            self.get_logger().info(f"geometry updated: {geometry}")
        if driving.command_rate != self.driving.command_rate:
            self.timer.cancel()
            self.timer = self.create_timer(1.0 / driving.command_rate, self._publish)
        self.driving = driving
        return SetParametersResult(successful=True)

    # ------------------------------------------------------------------ inputs
    def _on_target_radius(self, message: Float64) -> None:
        self.schedule = None
        self.command = self._radius_command(message.data)

    def _radius_command(self, radius: float) -> WheelVelocities:
        speed = self.driving.forward_speed
        try:
            midpoint = self.kinematics.midpoint_radius(radius)
        except UnreachableRadiusError as error:
            status = (
                WheelVelocities.STATUS_INVALID
                if math.isnan(radius)
                else WheelVelocities.STATUS_UNREACHABLE
            )
            self.get_logger().error(f"{error}; stopping the wheels")
            return self._stop_command(status, str(error), radius)
        left, right = wheel_angular_velocities(self.kinematics.geometry, midpoint, speed)
        ratio = wheel_speed_ratio(self.kinematics.geometry, midpoint)
        self.get_logger().info(
            f"target r_d = {radius:.4f} m → r_m = {midpoint:.4f} m, wheel speed ratio {ratio:.4f}, "
            f"left {left:.3f} rad/s, right {right:.3f} rad/s"
        )
        return WheelVelocities(
            left=left,
            right=right,
            forward_speed=speed,
            deposit_radius=radius,
            midpoint_radius=midpoint,
            wheel_speed_ratio=ratio,
            status=WheelVelocities.STATUS_OK,
            message="laying",
        )

    def _on_path(self, serialized: bytes) -> None:
        try:
            self._start_path(serialized)
        except PathError as error:
            self.schedule = None
            self.get_logger().error(f"path rejected: {error}; stopping the wheels")
            self.command = self._stop_command(
                WheelVelocities.STATUS_UNREACHABLE, f"path rejected: {error}"
            )
        finally:
            if len(serialized) > BIG_MESSAGE_BYTES:
                release_memory()

    def _start_path(self, serialized: bytes) -> None:
        """Check the path's size, then its points, and play its schedule."""
        if len(serialized) > MAX_PATH_BYTES:  # 100,000 poses: 7 MB, 1.4 million objects
            raise PathError(
                f"a path message is at most {MAX_PATH_BYTES} bytes, got {len(serialized)}"
            )
        message = deserialize_message(serialized, Path)
        points = np.array(
            [[p.pose.position.x, p.pose.position.y] for p in message.poses], dtype=float
        ).reshape(-1, 2)
        del message  # thousands of pose objects: not kept while the schedule is built
        segments = path_segments(points)
        self.schedule = schedule_segments(
            self.kinematics,
            segments,
            self.driving.forward_speed,
            self.driving.deposit_spacing,
            look_ahead=True,
        )
        self.schedule_start = self._now()
        self.travelled = 0.0
        self.get_logger().info(
            f"path accepted: {len(segments)} pieces, {self.schedule.duration:.1f} s, "
            f"{len(self.schedule.deposit_times)} dominoes"
        )
        self._publish()  # the wheels start when the schedule's clock does, not a tick later

    # ------------------------------------------------------------------ output
    def _on_odometry(self, message: Odometry) -> None:
        position = np.array([message.pose.pose.position.x, message.pose.pose.position.y])
        if not np.all(np.isfinite(position)):
            self.get_logger().warning(
                f"ignoring odometry at {position.tolist()}: not finite", throttle_duration_sec=5.0
            )
            return
        if self.last_position is not None:
            self.travelled += float(np.linalg.norm(position - self.last_position))
        self.last_position = position

    def _schedule_time(self) -> float:
        """Where the vehicle is in the schedule: odometry distance over the axle speed."""
        if self.last_position is None:  # no odometry (yet): the clock
            return self._now() - self.schedule_start
        return self.travelled / self.driving.forward_speed

    def _publish(self) -> None:
        if self.schedule is not None:
            self.command = self._schedule_command(self._schedule_time())
        self.command.header.stamp = self.get_clock().now().to_msg()
        self.status_pub.publish(self.command)
        self.command_pub.publish(Float64MultiArray(data=[self.command.left, self.command.right]))

    def _schedule_command(self, elapsed: float) -> WheelVelocities:
        schedule = self.schedule
        if elapsed >= schedule.duration:
            self.schedule = None
            self.get_logger().info("path finished; wheels stopped")
            return self._stop_command(WheelVelocities.STATUS_STOPPED, "path finished")
        k = int(np.searchsorted(schedule.start_time, elapsed, side="right")) - 1
        left, right = schedule.command_at(elapsed)
        midpoint = float(schedule.midpoint_radius[k])
        return WheelVelocities(
            left=left,
            right=right,
            forward_speed=self.driving.forward_speed,
            deposit_radius=float(schedule.deposit_radius[k]),
            midpoint_radius=midpoint,
            wheel_speed_ratio=wheel_speed_ratio(self.kinematics.geometry, midpoint),
            status=WheelVelocities.STATUS_OK,
            message=f"path piece {k + 1}/{len(schedule.left)}",
        )

    @staticmethod
    def _stop_command(status: int, message: str, radius: float = math.nan) -> WheelVelocities:
        return WheelVelocities(
            left=0.0,
            right=0.0,
            forward_speed=0.0,
            deposit_radius=radius,
            midpoint_radius=math.nan,
            wheel_speed_ratio=math.nan,
            status=status,
            message=message,
        )

    def _now(self) -> float:
        return self.get_clock().now().nanoseconds * 1e-9


def spin(node_class: type[Node], args: list[str] | None = None) -> None:
    """Run one node until Ctrl-C or shutdown, then clean up."""
    rclpy.init(args=args)
    # built before the node says it is ready: a Ctrl-C inside an executor's __init__
    # leaves half an executor whose __del__ prints a traceback
    executor = SingleThreadedExecutor()
    spin_until_shutdown(node_class(), executor)


def main(args: list[str] | None = None) -> None:
    tune_allocator()
    spin(LayerNode, args)


if __name__ == "__main__":
    main()

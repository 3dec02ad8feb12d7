"""Conversions between sim_node's world and its ROS messages: tf, camera_info, domino
twists, the trajectory and gripper actions' goals, feedback and results."""

from __future__ import annotations

import numpy as np
from control_msgs.action import FollowJointTrajectory, GripperCommand
from geometry_msgs.msg import Quaternion, Transform, TransformStamped, Twist, Vector3
from pydrake.math import RigidTransform
from sensor_msgs.msg import CameraInfo
from std_msgs.msg import Header
from tf2_msgs.msg import TFMessage
from trajectory_msgs.msg import JointTrajectoryPoint

from dombot_adapters.pose_messages import seconds_of, time_message
from dombot_sim.cameras import CameraFrame
from dombot_sim.frames import FrameTransform
from dombot_sim.goal_monitor import (
    DEFAULT_GOAL_TOLERANCE,
    GOAL_SETTLE_TIME,
    Tolerances,
    joint_tolerances,
)
from dombot_sim.trajectory import INVALID_JOINTS, TrajectoryError


def check_no_multi_dof(names) -> None:
    if names:
        raise TrajectoryError(
            INVALID_JOINTS,
            f"multi_dof_trajectory names {list(names)}; the arm has single-axis joints only",
        )


def all_have(points, field_name: str) -> bool:
    return bool(points) and all(len(getattr(p, field_name)) > 0 for p in points)


def goal_tolerances(goal: FollowJointTrajectory.Goal, names: list[str]) -> Tolerances:
    """The goal's JointTolerance entries and goal_time_tolerance as monitor tolerances."""
    path = [(entry.name, entry.position) for entry in goal.path_tolerance]
    end = [(entry.name, entry.position) for entry in goal.goal_tolerance]
    return Tolerances(
        path=joint_tolerances(path, names, default=-1.0),
        goal=joint_tolerances(end, names, default=DEFAULT_GOAL_TOLERANCE),
        settle=seconds_of(goal.goal_time_tolerance) or GOAL_SETTLE_TIME,
    )


def twist_message(velocity: np.ndarray) -> Twist:
    twist = Twist()
    twist.angular.x, twist.angular.y, twist.angular.z = (float(v) for v in velocity[:3])
    twist.linear.x, twist.linear.y, twist.linear.z = (float(v) for v in velocity[3:])
    return twist


def tf_message(now: float, frames: list[FrameTransform]) -> TFMessage:
    stamp = time_message(now)
    return TFMessage(
        transforms=[
            TransformStamped(
                header=Header(stamp=stamp, frame_id=frame.parent),
                child_frame_id=frame.child,
                transform=transform_message(frame.X_PC),
            )
            for frame in frames
        ]
    )


def transform_message(pose: RigidTransform) -> Transform:
    """With Drake's quaternion: scipy's conversion cost ~20x more per frame (bench_tf)."""
    x, y, z = pose.translation()
    q = pose.rotation().ToQuaternion()
    return Transform(
        translation=Vector3(x=x, y=y, z=z), rotation=Quaternion(x=q.x(), y=q.y(), z=q.z(), w=q.w())
    )


def camera_info(frame: CameraFrame, header: Header) -> CameraInfo:
    height, width = frame.depth.shape
    intrinsics = frame.K
    return CameraInfo(
        header=header,
        height=height,
        width=width,
        distortion_model="plumb_bob",
        d=[0.0] * 5,
        k=intrinsics.ravel().tolist(),
        r=np.eye(3).ravel().tolist(),
        p=np.hstack([intrinsics, np.zeros((3, 1))]).ravel().tolist(),
    )


def feedback_message(names, now, desired_state, state) -> FollowJointTrajectory.Feedback:
    desired, velocity, acceleration = desired_state
    feedback = FollowJointTrajectory.Feedback()
    feedback.header.stamp = time_message(now)
    feedback.joint_names = names
    feedback.desired = JointTrajectoryPoint(
        positions=desired.tolist(),
        velocities=velocity.tolist(),
        accelerations=acceleration.tolist(),
    )
    feedback.actual = JointTrajectoryPoint(
        positions=state.position[:7].tolist(), velocities=state.velocity[:7].tolist()
    )
    feedback.error = JointTrajectoryPoint(
        positions=(state.position[:7] - desired).tolist(),
        velocities=(state.velocity[:7] - velocity).tolist(),
    )
    return feedback


def gripper_result(state, reached: bool, stalled: bool) -> GripperCommand.Result:
    return GripperCommand.Result(
        position=state.opening, effort=abs(state.force), stalled=stalled, reached_goal=reached
    )


def gripper_feedback(state, reached: bool, stalled: bool) -> GripperCommand.Feedback:
    return GripperCommand.Feedback(
        position=state.opening, effort=abs(state.force), stalled=stalled, reached_goal=reached
    )

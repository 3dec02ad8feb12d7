"""The bring-up's door: the nodes' messages as the plain types of ``task.cell``, and back."""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Pose as PoseMessage
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from dombot_adapters.pose_messages import (
    duration_message,
    pose_matrix,
    pose_message,
    seconds_of,
)
from dombot_bringup.task.cell import (
    Detection,
    Detections,
    GripperEvent,
    Plan,
    Pose,
    Posture,
    Segment,
    Trajectory,
)
from dombot_msgs.msg import DominoDetection, TrajectorySegment
from dombot_msgs.srv import DetectDominoes, PlanPlace, PlanStrike
from dombot_planner.errors import ErrorCode


def geometry_pose(pose: Pose | None) -> PoseMessage:
    """``pose`` as a message; None as the default pose at the origin (a request's unset)."""
    return PoseMessage() if pose is None else pose_message(pose)


def pose_or_none(message: PoseMessage) -> Pose | None:
    """The transform of ``message``; None for a field left at the origin (inside the arm
    base: unset, as planner_node reads a grasp_pose)."""
    p = message.position
    return pose_matrix(message) if any((p.x, p.y, p.z)) else None


def detections_of(answer: DetectDominoes.Response) -> Detections:
    return Detections(
        answer.success,
        answer.message,
        tuple(detection_of(d) for d in answer.detections.detections),
        np.array([(p.x, p.y, p.z) for p in answer.unexplained_points]).reshape(-1, 3),
    )


def detection_of(message: DominoDetection) -> Detection:
    return Detection(
        pose_matrix(message.pose),
        Posture(message.posture),
        message.score,
        message.clearance,
        pose_or_none(message.grasp_pose),
    )


def plan_of(answer: PlanPlace.Response | PlanStrike.Response, held: Pose | None) -> Plan:
    return Plan(
        answer.success,
        ErrorCode(answer.error_code),
        answer.message,
        tuple(segment_of(s) for s in answer.segments),
        held,
    )


def segment_of(message: TrajectorySegment) -> Segment:
    return Segment(
        message.label,
        trajectory_of(message.trajectory),
        GripperEvent(message.gripper_after),
        message.gripper_position,
        message.gripper_max_effort,
    )


def trajectory_of(message: JointTrajectory) -> Trajectory:
    points, joints = message.points, len(message.joint_names)
    with_velocities = all(len(p.velocities) == joints for p in points)  # else none given
    return Trajectory(
        tuple(message.joint_names),
        np.array([seconds_of(p.time_from_start) for p in points]),
        np.array([list(p.positions) for p in points]).reshape(len(points), joints),
        np.array([list(p.velocities) for p in points if with_velocities]).reshape(
            len(points) if with_velocities else 0, joints
        ),
    )


def trajectory_message(trajectory: Trajectory) -> JointTrajectory:
    velocities = trajectory.velocities.tolist() or [[]] * len(trajectory.times)
    return JointTrajectory(
        joint_names=list(trajectory.joint_names),
        points=[
            JointTrajectoryPoint(
                positions=positions,
                velocities=speeds,
                time_from_start=duration_message(time),
            )
            for time, positions, speeds in zip(
                trajectory.times.tolist(), trajectory.positions.tolist(), velocities, strict=True
            )
        ],
    )

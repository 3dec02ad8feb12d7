"""CellClient's door: messages become the task core's plain types once, and back."""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Pose

from dombot_adapters.pose_messages import pose_message
from dombot_bringup.cell_client import CellClient
from dombot_bringup.cell_messages import (
    detection_of,
    geometry_pose,
    plan_of,
    pose_or_none,
    trajectory_message,
    trajectory_of,
)
from dombot_bringup.task.cell import GripperEvent, Posture, Trajectory
from dombot_msgs.msg import DominoDetection, TrajectorySegment
from dombot_msgs.srv import PlanPlace
from dombot_planner.errors import ErrorCode
from support.cell_protocol import differences


def test_a_trajectory_goes_to_its_message_and_back_unchanged() -> None:
    trajectory = Trajectory(
        ("iiwa_joint_1", "iiwa_joint_2"),
        np.array([0.0, 0.75, 1.5]),
        np.array([[0.1, 0.2], [0.3, 0.4], [0.5, 0.6]]),
        np.array([[0.0, 0.0], [0.2, -0.1], [0.0, 0.0]]),
    )
    back = trajectory_of(trajectory_message(trajectory))
    assert back.joint_names == trajectory.joint_names
    for field in ("times", "positions", "velocities"):
        assert np.allclose(getattr(back, field), getattr(trajectory, field))
    reversed_back = trajectory.reversed(0.5)
    assert reversed_back.times.tolist() == [0.5, 1.25, 2.0]
    assert reversed_back.velocities[1].tolist() == [-0.2, 0.1]


def test_an_unset_pose_field_is_none_and_none_goes_out_as_unset() -> None:
    assert pose_or_none(Pose()) is None
    assert geometry_pose(None) == Pose()
    pose = np.eye(4)
    pose[:3, 3] = [0.5, -0.3, 0.01]
    assert np.allclose(pose_or_none(pose_message(pose)), pose)


def test_a_detection_and_a_plan_arrive_in_plain_types() -> None:
    detection = detection_of(
        DominoDetection(posture=DominoDetection.POSTURE_TILTED, score=0.5, clearance=0.01)
    )
    assert detection.posture is Posture.TILTED and detection.grasp is None
    answer = PlanPlace.Response(
        success=False,
        error_code=PlanPlace.Response.GRASP_UNREACHABLE,
        message="no grasp",
        segments=[TrajectorySegment(label="place", gripper_after=TrajectorySegment.GRIPPER_OPEN)],
    )
    plan = plan_of(answer, None)
    assert plan.error is ErrorCode.GRASP_UNREACHABLE
    (segment,) = plan.segments
    assert segment.gripper_after is GripperEvent.OPEN and segment.trajectory.duration == 0.0


def test_cell_client_takes_the_cell_protocols_arguments() -> None:
    """As the task core passes them: ``meanwhile`` by keyword (``gripper`` and
    ``gripper_later`` took it before and after their timeout)."""
    assert differences(CellClient) == []

"""The compat interface packages carry control_msgs' and tf2_msgs' Jazzy fields exactly.

A client built against the real packages (MoveIt, rqt, tf2_ros) only talks to DOM-BOT
if names, field names and field types are the same; these tables are the Jazzy ones.
"""

from __future__ import annotations

import pytest
from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import JointComponentTolerance, JointTolerance
from rclpy.serialization import deserialize_message, serialize_message
from tf2_msgs.msg import TFMessage

JAZZY_FIELDS = {
    FollowJointTrajectory.Goal: {
        "trajectory": "trajectory_msgs/JointTrajectory",
        "multi_dof_trajectory": "trajectory_msgs/MultiDOFJointTrajectory",
        "path_tolerance": "sequence<control_msgs/JointTolerance>",
        "component_path_tolerance": "sequence<control_msgs/JointComponentTolerance>",
        "goal_tolerance": "sequence<control_msgs/JointTolerance>",
        "component_goal_tolerance": "sequence<control_msgs/JointComponentTolerance>",
        "goal_time_tolerance": "builtin_interfaces/Duration",
    },
    FollowJointTrajectory.Result: {"error_code": "int32", "error_string": "string"},
    FollowJointTrajectory.Feedback: {
        "header": "std_msgs/Header",
        "joint_names": "sequence<string>",
        "desired": "trajectory_msgs/JointTrajectoryPoint",
        "actual": "trajectory_msgs/JointTrajectoryPoint",
        "error": "trajectory_msgs/JointTrajectoryPoint",
        "multi_dof_joint_names": "sequence<string>",
        "multi_dof_desired": "trajectory_msgs/MultiDOFJointTrajectoryPoint",
        "multi_dof_actual": "trajectory_msgs/MultiDOFJointTrajectoryPoint",
        "multi_dof_error": "trajectory_msgs/MultiDOFJointTrajectoryPoint",
    },
    GripperCommand.Goal: {"command": "control_msgs/GripperCommand"},
    GripperCommand.Result: {
        "position": "double",
        "effort": "double",
        "stalled": "boolean",
        "reached_goal": "boolean",
    },
    GripperCommand.Feedback: {
        "position": "double",
        "effort": "double",
        "stalled": "boolean",
        "reached_goal": "boolean",
    },
    JointTolerance: {
        "name": "string",
        "position": "double",
        "velocity": "double",
        "acceleration": "double",
    },
    JointComponentTolerance: {
        "joint_name": "string",
        "component": "uint16",
        "position": "double",
        "velocity": "double",
        "acceleration": "double",
    },
    TFMessage: {"transforms": "sequence<geometry_msgs/TransformStamped>"},
}


@pytest.mark.parametrize("message_type", list(JAZZY_FIELDS), ids=lambda t: t.__qualname__)
def test_fields_match_jazzy(message_type) -> None:
    assert message_type.get_fields_and_field_types() == JAZZY_FIELDS[message_type]


def test_constants_match_jazzy() -> None:
    result = FollowJointTrajectory.Result
    assert (result.SUCCESSFUL, result.INVALID_GOAL, result.INVALID_JOINTS) == (0, -1, -2)
    assert (result.OLD_HEADER_TIMESTAMP, result.PATH_TOLERANCE_VIOLATED) == (-3, -4)
    assert result.GOAL_TOLERANCE_VIOLATED == -5
    assert (JointComponentTolerance.X_AXIS, JointComponentTolerance.ROTATION) == (1, 5)


def test_goal_round_trips() -> None:
    goal = FollowJointTrajectory.Goal(goal_tolerance=[JointTolerance(name="iiwa_joint_4")])
    goal.trajectory.joint_names = [f"iiwa_joint_{i}" for i in range(1, 8)]
    again = deserialize_message(serialize_message(goal), FollowJointTrajectory.Goal)
    assert again == goal

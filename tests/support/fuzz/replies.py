"""Outcomes and verdicts: how each endpoint's reply is named (an error code's name, or
``ok``/``refused`` for services that answer with a success flag and a message) and what
is wrong with a reply whatever the request was."""

from __future__ import annotations

from action_msgs.msg import GoalStatus
from control_msgs.action import FollowJointTrajectory

from dombot_msgs.msg import WheelVelocities
from dombot_planner.errors import ErrorCode
from support.fuzz.harness import GoalReply

TRAJECTORY_CODES = {
    value: name
    for name, value in vars(FollowJointTrajectory.Result).items()
    if name.isupper() and isinstance(value, int)
}


def planner_outcome(reply) -> str:
    return ErrorCode(reply.error_code).name


def planner_problem(reply) -> str | None:
    if not reply.message:
        return "empty message"
    if reply.success != (reply.error_code == ErrorCode.SUCCESS):
        return f"success {reply.success} with {ErrorCode(reply.error_code).name}"
    return None


def flag_outcome(reply) -> str:
    return "ok" if reply.success else "refused"


def trajectory_outcome(reply: GoalReply) -> str:
    if reply.result is None:
        return "REJECTED"
    return TRAJECTORY_CODES.get(reply.result.error_code, str(reply.result.error_code))


def trajectory_problem(reply: GoalReply) -> str | None:
    """Aborted goals carry a code (or were preempted), succeeded ones SUCCESSFUL, all a text."""
    if reply.result is None:
        return None
    code, text = reply.result.error_code, reply.result.error_string
    if reply.status == GoalStatus.STATUS_UNKNOWN:  # the server no longer had the goal
        return "result asked for after the server dropped the goal (status UNKNOWN)"
    if not text:
        return f"empty error_string (status {reply.status})"
    succeeded = reply.status == GoalStatus.STATUS_SUCCEEDED
    if succeeded != (code == 0) and not (code == 0 and "preempted" in text):
        return f"status {reply.status} with error_code {code}"
    return None


def gripper_outcome(reply: GoalReply) -> str:
    names = {v: k for k, v in vars(GoalStatus).items() if k.startswith("STATUS_")}
    return "REJECTED" if reply.result is None else names[reply.status].removeprefix("STATUS_")


def gripper_problem(reply: GoalReply) -> str | None:
    """GripperCommand's result has no text (the reason is in the node's log): an aborted
    goal must not claim it reached the opening."""
    if reply.result is not None and reply.status == GoalStatus.STATUS_ABORTED:
        return "aborted but reached_goal" if reply.result.reached_goal else None
    return None


def layer_outcome(reply: WheelVelocities) -> str:
    names = {v: k for k, v in vars(WheelVelocities).items() if k.startswith("STATUS_")}
    return names.get(reply.status, str(reply.status))

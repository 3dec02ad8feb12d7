"""``ros2 action list|send_goal`` with ros2action's output."""

from __future__ import annotations

import rclpy
from action_msgs.msg import GoalStatus
from rclpy.action import ActionClient, get_action_names_and_types
from rclpy.node import Node

from dombot_ros2.graph import no_server
from dombot_ros2.interfaces import load_type
from dombot_ros2.message_yaml import message_to_yaml, parse_yaml_values, set_message_fields
from dombot_ros2.packages import CommandError

STATUS_NAMES = {
    GoalStatus.STATUS_ACCEPTED: "ACCEPTED",
    GoalStatus.STATUS_EXECUTING: "EXECUTING",
    GoalStatus.STATUS_CANCELING: "CANCELING",
    GoalStatus.STATUS_SUCCEEDED: "SUCCEEDED",
    GoalStatus.STATUS_CANCELED: "CANCELED",
    GoalStatus.STATUS_ABORTED: "ABORTED",
}


def action_list(node: Node, show_types: bool) -> list[str]:
    return [
        f"{name} [{', '.join(types)}]" if show_types else name
        for name, types in sorted(get_action_names_and_types(node))
    ]


def send_goal(
    node: Node, action: str, type_name: str, values: str, feedback: bool, timeout: float
) -> None:
    """Send one goal, print feedback (``feedback``) and the result as ros2action does;
    an action server that does not appear within ``timeout`` seconds is an error."""
    action_type = load_type(type_name, kind="action")
    goal = action_type.Goal()
    set_message_fields(goal, parse_yaml_values(values))
    client = ActionClient(node, action_type, action)
    print("Waiting for an action server to become available...", flush=True)
    if not client.wait_for_server(timeout_sec=timeout):
        raise CommandError(no_server("action", action, timeout))
    print(f"Sending goal:\n     {message_to_yaml(goal)}", flush=True)

    def on_feedback(message) -> None:
        print(f"Feedback:\n    {message_to_yaml(message.feedback)}", flush=True)

    sent = client.send_goal_async(goal, on_feedback if feedback else None)
    rclpy.spin_until_future_complete(node, sent)
    handle = sent.result()
    if handle is None:
        raise CommandError(f"Exception while sending goal: {sent.exception()!r}")
    if not handle.accepted:
        print("Goal was rejected.")
        return
    print(f"Goal accepted with ID: {bytes(handle.goal_id.uuid).hex()}\n", flush=True)
    finished = handle.get_result_async()
    rclpy.spin_until_future_complete(node, finished)
    result = finished.result()
    if result is None:
        raise CommandError(f"Exception while getting result: {finished.exception()!r}")
    print(f"Result:\n    {message_to_yaml(result.result)}")
    print(f"Goal finished with status: {STATUS_NAMES.get(result.status, 'UNKNOWN')}")

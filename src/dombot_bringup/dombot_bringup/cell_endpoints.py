"""The services and actions the bring-up asks (names, types, the node serving each, what
waiting for it counts as), and the action client that takes their answers safely."""

from __future__ import annotations

import threading

from rclpy.action import ActionClient

from dombot_msgs.srv import CheckPlacement, DetectDominoes, PlanPlace, PlanStrike, ResetSim

# The arm's and gripper's controllers, at ros2_control's names (a real cell's too).
TRAJECTORY_ACTION = "/arm_controller/follow_joint_trajectory"
GRIPPER_ACTION = "/gripper_controller/gripper_cmd"
SERVICES = {
    "/sim/reset": ResetSim,
    "/perception/detect": DetectDominoes,
    "/perception/check_placement": CheckPlacement,
    "/plan_place": PlanPlace,
    "/plan_strike": PlanStrike,
}

# The node that serves each service: its answer is asked again when it was restarted.
SERVERS = {
    "/sim/reset": "sim_node",
    "/perception/detect": "perception_node",
    "/perception/check_placement": "perception_node",
    "/plan_place": "planner_node",
    "/plan_strike": "planner_node",
}
DETECT_SERVICE = "/perception/detect"
# s of wall time for perception's answer: a liveness bound, not a speed target (a check
# took 27 s of wall time at load 30 on two cores; a dead node is seen by the process
# group at once, and a restarted one is asked again)
DETECT_TIMEOUT = 120.0
RESTART_TIMEOUT = 600.0  # s for a restarted server to come back (the planner builds plants)


# What simulated time spent waiting for each answer is counted as.
ACTIVITIES = {
    "/sim/reset": "reset",
    "/perception/detect": "perception",
    "/perception/check_placement": "perception",
    "/plan_place": "planning",
    "/plan_strike": "planning",
    TRAJECTORY_ACTION: "motion",
    GRIPPER_ACTION: "gripper",
    "simulated time": "waiting",  # for a domino to settle, or a camera period
}


class SerialActionClient(ActionClient):
    """rclpy's ActionClient with sending a request and taking a response serialized.

    rclpy 7.1 (Jazzy) records a request's sequence number only after sending it; an
    executor thread that takes the response in between drops it ("Ignoring unexpected
    goal response") and the future never completes (ros2/rclpy#1123; upstream fixed it
    with this lock in #1308). Seen here: a trajectory goal the simulator accepted and
    ran while the bring-up waited for its acceptance until it gave up.
    """

    def __init__(self, *args, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self._serial = threading.RLock()

    def send_goal_async(self, *args, **kwargs):
        with self._serial:
            return super().send_goal_async(*args, **kwargs)

    def _cancel_goal_async(self, goal_handle):
        with self._serial:
            return super()._cancel_goal_async(goal_handle)

    def _get_result_async(self, goal_handle):
        with self._serial:
            return super()._get_result_async(goal_handle)

    async def execute(self, taken_data):
        with self._serial:
            return await super().execute(taken_data)

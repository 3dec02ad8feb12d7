"""sim_node stopped by SIGINT (Ctrl-C, or the bring-up stopping it) while it executes a
goal: the goal's callback ends before the node is destroyed, the process exits 0 without a
traceback, and its last lines still say how many camera frames it rendered and how long
the cell was still. A request that waits for the ended simulation loop is answered."""

from __future__ import annotations

import signal
import subprocess
import threading

import numpy as np
import pytest
import rclpy
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory
from rclpy.action import ActionClient
from rclpy.node import Node
from sensor_msgs.msg import JointState
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from dombot_description.scenario import load_scenario
from dombot_msgs.srv import ResetSim
from dombot_sim.sim_node import SimNode
from support.ros_processes import installed_node, spin_until

pytestmark = pytest.mark.slow  # a sim_node process

ARM = list(load_scenario().arm_joints)
TRAJECTORY_ACTION = "/arm_controller/follow_joint_trajectory"
# what rclpy printed when a node was destroyed under a callback, or a callback failed
# once the context was down (rclpy issue 893)
STOP_ERRORS = ("Traceback", "never retrieved", "Destroyable", "Error raised in execute")


def a_minute_long_goal(start: list[float]) -> FollowJointTrajectory.Goal:
    """A slow move of the first joint: still running whenever the test stops the node."""
    end = np.array(start) + np.array([0.3, 0.0, 0.0, 0.0, 0.0, 0.0, 0.0])
    point = JointTrajectoryPoint(positions=end.tolist(), time_from_start=Duration(sec=60))
    return FollowJointTrajectory.Goal(trajectory=JointTrajectory(joint_names=ARM, points=[point]))


def test_sigint_during_a_goal_drains_it_and_keeps_the_shutdown_lines() -> None:
    rclpy.init()
    node = Node("shutdown_probe")
    states: list[JointState] = []
    node.create_subscription(JointState, "/joint_states", states.append, 5)
    arguments = ["--ros-args", "-p", "domino_count:=0", "-p", "real_time_factor:=1.0"]
    try:
        with installed_node("dombot_sim", "sim_node", *arguments, output=subprocess.PIPE) as sim:
            assert spin_until(node, lambda: bool(states), 300), sim.poll()
            start = [states[-1].position[states[-1].name.index(name)] for name in ARM]
            client = ActionClient(node, FollowJointTrajectory, TRAJECTORY_ACTION)
            assert client.wait_for_server(timeout_sec=120)
            feedback: list[object] = []
            sent = client.send_goal_async(a_minute_long_goal(start), feedback.append)
            assert spin_until(node, lambda: sent.done() and bool(feedback), 120)
            assert sent.result().accepted
            sim.send_signal(signal.SIGINT)  # the goal's callback is at work meanwhile
            output, _ = sim.communicate(timeout=120)
    finally:
        node.destroy_node()
        rclpy.shutdown()
    assert sim.returncode == 0, output
    assert not [error for error in STOP_ERRORS if error in output], output
    assert "[sim_node.shutdown]: camera frames rendered: camera_0 0" in output, output
    assert "of which the cell was still (no physics steps)" in output, output


def test_a_reset_the_ended_loop_never_runs_is_answered_not_left_waiting() -> None:
    """A reset runs in the simulation loop's thread; one that arrives as the loop ends
    waited for ever, and the executor could not drain its callback."""
    rclpy.init(args=["--ros-args", "-p", "domino_count:=0"])
    try:
        node = SimNode()
        ended = threading.Event()
        ended.set()
        node.run(ended)  # returns at once, as the loop does on Ctrl-C
        response = node._on_reset(ResetSim.Request(domino_count=3, seed=1), ResetSim.Response())
        node.destroy_node()
    finally:
        rclpy.shutdown()
    assert not response.success
    assert response.message == "sim_node is stopping: the request was not served"

"""How a node's main loop ends on Ctrl-C or when its supervisor stops it (no ROS graph
logic here, only rclpy's context)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import rclpy
from rclpy.executors import ExternalShutdownException


@contextmanager
def stop_quietly_on_shutdown() -> Iterator[None]:
    """Ctrl-C, and any error raised once the context is shut down, end the node normally.

    SIGINT shuts rclpy's context down from a signal handler, wherever the node is: a
    publish or an executor's wait then fails (RCLError: "publisher's context is invalid",
    "failed to initialize wait set"), and each bring-up run ended with such tracebacks
    from sim_node, planner_node and perception_node. An error while the context is still
    valid is raised as before.
    """
    try:
        yield
    except (KeyboardInterrupt, ExternalShutdownException):
        pass
    except Exception:
        if rclpy.ok():
            raise

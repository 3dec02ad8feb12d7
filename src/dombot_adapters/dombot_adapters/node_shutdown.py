"""How a node's main loop ends on Ctrl-C or when its supervisor stops it (no ROS graph
logic here, only rclpy's context and executor)."""

from __future__ import annotations

from collections.abc import Iterator
from contextlib import contextmanager

import rclpy
from rclpy.executors import ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node


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


class DrainingExecutor(MultiThreadedExecutor):
    """A MultiThreadedExecutor whose ``shutdown`` waits for the callbacks still running.

    rclpy 7.1.6's does not (rclpy issue 893, fixed upstream by pull request 1309): after
    SIGINT a node was destroyed under a service callback still at work on a pool thread,
    which then failed with InvalidHandle ("cannot use Destroyable because destruction was
    requested", "The following exception was never retrieved"). What a drained callback
    raised because the context went down is part of stopping, not an error.
    """

    def shutdown(self, timeout_sec: float | None = None) -> bool:
        stopped = super().shutdown(timeout_sec)
        self._executor.shutdown(wait=True)  # the pool upstream's fix joins
        for handler in self._futures:
            if handler.done():
                handler.exception()  # fetched: rclpy prints the unfetched ones at exit
        return stopped


def spin_until_shutdown(node: Node, num_threads: int) -> None:
    """Serve ``node`` with ``num_threads`` callback threads until Ctrl-C or the
    supervisor's SIGINT; destroy it only once its running callbacks have returned."""
    executor = DrainingExecutor(num_threads=num_threads)
    executor.add_node(node)
    try:
        with stop_quietly_on_shutdown():
            executor.spin()
    finally:
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()

"""How a node's main loop ends on Ctrl-C or when its supervisor stops it (no ROS graph
logic here, only rclpy's context and executor)."""

from __future__ import annotations

import threading
from collections.abc import Iterator
from contextlib import contextmanager

import rclpy
from rclpy.executors import Executor, ExternalShutdownException, MultiThreadedExecutor
from rclpy.node import Node
from rclpy.signals import uninstall_signal_handlers


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


def stop_signal_thread() -> None:
    """Uninstall rclpy's signal handlers, which joins the thread they wake; call it first
    when a node stops, before any executor is shut down.

    On SIGINT rclpy 7.1.6 wakes a thread of its own that triggers each executor's SIGINT
    guard condition, from a list it reads without a lock, and shuts the contexts down.
    Meanwhile the main thread, already in KeyboardInterrupt, shuts the executor down and
    destroys that guard condition: a use-after-free (SIGSEGV in
    ``rcl_trigger_guard_condition``, 1 Ctrl-C of layer_node in about 60). ``rclpy.try_shutdown``
    never joins that thread; the process's exit does, after the executors are collected.
    A Ctrl-C from here on is Python's plain KeyboardInterrupt.
    """
    uninstall_signal_handlers()


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


def spin_until_shutdown(node: Node, executor: Executor) -> None:
    """Serve ``node`` on ``executor`` until Ctrl-C or the supervisor's SIGINT; with a
    ``DrainingExecutor`` the node is destroyed only once its running callbacks returned."""
    try:
        with stop_quietly_on_shutdown():
            executor.add_node(node)
            executor.spin()
    finally:
        stop_signal_thread()
        executor.shutdown()
        node.destroy_node()
        rclpy.try_shutdown()


class BackgroundSpinner:
    """Spins ``executor`` on a thread of its own until ``stop``, for code whose main
    thread does other work (a client, the simulation loop, a test). A callback that
    raises is logged on ``node``'s logger and the others are still served.

    ``stop`` ends the spin loop before the executor shuts down: rclpy's shutdown from
    another thread destroys the executor's guard condition while the spinner may be
    building its wait set (rclpy issue 968: "'NoneType' object has no attribute
    'handle'" in the spin thread, which failed a partial build's test on a loaded CI).
    """

    def __init__(self, executor: Executor, node: Node, period: float = 0.1) -> None:
        self.executor = executor
        self._logger = node.get_logger()
        self._period = period  # s: how long one wait for work lasts before it looks at stop
        self._stopping = threading.Event()
        self._thread = threading.Thread(target=self._spin, daemon=True)
        self._thread.start()

    def _spin(self) -> None:
        while not self._stopping.is_set() and self.executor.context.ok():
            try:
                self.executor.spin_once(timeout_sec=self._period)
            except ExternalShutdownException:
                return
            except Exception as error:
                if not self.executor.context.ok():
                    return  # the context went down under the wait: stopping
                self._logger.error(f"callback failed: {error!r}; still serving")

    def stop(self, timeout_sec: float = 10.0) -> None:
        """Leave the spin loop, then shut the executor down (its running callbacks
        drain first with a ``DrainingExecutor``); rclpy's signal thread is joined before
        (``stop_signal_thread``)."""
        self._stopping.set()
        self._thread.join(timeout=timeout_sec)
        stop_signal_thread()
        self.executor.shutdown(timeout_sec=timeout_sec)

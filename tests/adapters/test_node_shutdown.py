"""A node stopped by SIGINT ends quietly, its running callbacks drained first; an error
while it runs is still raised."""

from __future__ import annotations

import gc
import subprocess
import sys
import threading
import time

import pytest
import rclpy

from dombot_adapters.node_shutdown import (
    BackgroundSpinner,
    DrainingExecutor,
    spin_until_shutdown,
    stop_quietly_on_shutdown,
)


def test_an_error_after_shutdown_is_a_normal_stop_and_one_before_it_is_raised() -> None:
    rclpy.init()
    try:
        with pytest.raises(RuntimeError), stop_quietly_on_shutdown():
            raise RuntimeError("a callback failed while the node was up")
        with stop_quietly_on_shutdown():
            raise KeyboardInterrupt
    finally:
        rclpy.shutdown()
    with stop_quietly_on_shutdown():  # as a publish after SIGINT's shutdown fails
        raise RuntimeError("Failed to publish: publisher's context is invalid")


def test_a_callback_running_at_shutdown_returns_before_its_node_is_destroyed(capfd) -> None:
    """As SIGINT does, the context goes down while a callback is still at work: the node
    stays usable until the callback returns, and what the callback raises because the
    graph went away is not reported (rclpy printed "The following exception was never
    retrieved: cannot use Destroyable because destruction was requested")."""
    rclpy.init()
    node = rclpy.create_node("draining_node")
    started, resolved = threading.Event(), []

    def at_work() -> None:
        timer.cancel()
        started.set()
        while node.context.ok():  # the context goes down while this callback runs
            time.sleep(0.01)
        time.sleep(0.2)  # time enough for a node destroyed under it to be gone
        resolved.append(node.resolve_topic_name("chatter"))  # InvalidHandle once destroyed
        raise RuntimeError("the graph went away")

    timer = node.create_timer(0.01, at_work)
    stopper = threading.Thread(target=lambda: started.wait(30) and rclpy.shutdown())
    stopper.start()
    spin_until_shutdown(node, DrainingExecutor(num_threads=2))
    stopper.join()
    gc.collect()  # rclpy reports an unfetched callback error when its task is collected
    assert resolved == ["/chatter"]
    assert "never retrieved" not in capfd.readouterr().err


def test_a_background_spinner_logs_a_failing_callback_and_keeps_serving(capfd) -> None:
    """sim_node's and the cell client's spinner: a callback that raises is logged and
    the next ones still run; ``stop`` leaves the loop before the executor shuts down
    (rclpy issue 968), so nothing is printed from the spin thread."""
    rclpy.init()
    node = rclpy.create_node("spinning_node")
    ticks = threading.Semaphore(0)

    def tick() -> None:
        ticks.release()
        raise RuntimeError("a bad callback")

    node.create_timer(0.01, tick)
    executor = DrainingExecutor(num_threads=2)
    executor.add_node(node)
    spinner = BackgroundSpinner(executor, node)
    try:
        assert all(ticks.acquire(timeout=30) for _ in range(5))
    finally:
        spinner.stop()
        node.destroy_node()
        rclpy.shutdown()
    err = capfd.readouterr().err
    assert "callback failed: RuntimeError('a bad callback'); still serving" in err
    assert "Traceback" not in err


INTERRUPTED_OFTEN = """
import os, signal
import rclpy
from rclpy.executors import SingleThreadedExecutor
from dombot_adapters.node_shutdown import spin_until_shutdown
for _ in range(200):
    rclpy.init()
    node = rclpy.create_node("interrupted")
    node.create_timer(0.001, lambda: os.kill(os.getpid(), signal.SIGINT))
    spin_until_shutdown(node, SingleThreadedExecutor())
print("stopped 200 times", flush=True)
"""


def test_a_node_stopped_by_sigint_200_times_never_crashes() -> None:
    """rclpy's signal thread triggers the executor's SIGINT guard condition while the main
    thread destroys it (``stop_signal_thread``): without the join this loop ended in
    SIGSEGV or glibc's "unaligned tcache chunk" abort within 100 stops, every time."""
    child = subprocess.run(
        [sys.executable, "-c", INTERRUPTED_OFTEN], capture_output=True, text=True, timeout=300
    )
    assert child.returncode == 0, child.stderr[-2000:]
    assert child.stdout == "stopped 200 times\n"

"""A node stopped by SIGINT ends quietly; an error while it runs is still raised."""

from __future__ import annotations

import pytest
import rclpy

from dombot_adapters.node_shutdown import stop_quietly_on_shutdown


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

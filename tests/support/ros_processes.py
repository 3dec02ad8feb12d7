"""Start ROS 2 code in separate OS processes, so tests cross real DDS."""

from __future__ import annotations

import os
import subprocess
import sys
import textwrap
import time
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from pathlib import Path
from typing import IO

import rclpy
from ament_index_python.packages import get_package_prefix
from rclpy.node import Node


@contextmanager
def _supervised(
    command: list[str], output: IO | int | None = None
) -> Iterator[subprocess.Popen[str]]:
    """``output``: where the child's stdout and stderr go. Default: this process's own,
    which pytest captures into a file and shows with a failure. ``subprocess.PIPE`` only
    for a child whose output the test reads: a child that logs into a pipe nobody reads
    blocks in the write once 64 KiB are waiting (a perception_node stopped answering
    /perception/detect that way)."""
    child = subprocess.Popen(
        command, env=dict(os.environ), stdout=output, stderr=subprocess.STDOUT, text=True
    )
    try:
        yield child
    finally:
        child.terminate()
        try:
            child.wait(timeout=10)
        except subprocess.TimeoutExpired:
            child.kill()
            child.wait()


@contextmanager
def python_process(source: str, output: IO | int | None = None) -> Iterator[subprocess.Popen[str]]:
    """Run ``source`` in a child interpreter with this session's environment."""
    with _supervised([sys.executable, "-c", textwrap.dedent(source)], output) as child:
        yield child


def executable_path(package: str, executable: str) -> Path:
    """An installed executable's path, found through the ament index as ros2 run does."""
    return Path(get_package_prefix(package)) / "lib" / package / executable


@contextmanager
def installed_node(
    package: str, executable: str, *args: str, output: IO | int | None = None
) -> Iterator[subprocess.Popen[str]]:
    """Run an installed node executable, found through the ament index as ros2 run does."""
    with _supervised([str(executable_path(package, executable)), *args], output) as child:
        yield child


def spin_until(node: Node, done: Callable[[], bool], timeout: float) -> bool:
    """Spin ``node`` until ``done()`` or the timeout; return ``done()``."""
    deadline = time.monotonic() + timeout
    while time.monotonic() < deadline and not done():
        rclpy.spin_once(node, timeout_sec=0.05)
    return done()


def call_service(node: Node, client, request, timeout: float, tries: int = 3):
    """The response to ``request``, sent again when none came within ``timeout``; None if
    no try got one. A new client's first request can lose its response under load: the
    server may answer before its reply writer has matched the client's reader (a Fast DDS
    service-discovery race, ros2/ros2#1253). Only for requests that are safe to repeat."""
    assert spin_until(node, client.service_is_ready, timeout=30), "service not available"
    for _ in range(tries):
        future = client.call_async(request)
        if spin_until(node, future.done, timeout=timeout):
            return future.result()
        client.remove_pending_request(future)
    return None

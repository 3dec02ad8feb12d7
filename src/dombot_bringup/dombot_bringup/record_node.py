"""record: every topic of the graph into an MCAP file (a ``ros2 bag record -a``-like).

Finds topics as they appear (every 0.5 s) and subscribes to each with its type and its
publishers' QoS (transient local for ``/tf_static`` or ``/robot_description``, best
effort for sensor-data cameras), taking messages raw: they go into the file as
published, with the complete message definition of their type as the schema, so
Foxglove and ``mcap_ros2`` decode them. Raw images are thinned to ``--image-rate`` (by
their stamps).
Hidden topics (actions' internals) are left out, as rosbag2 does by default.

    ros2 run dombot_bringup record -o run.mcap [--image-rate 1] [--duration 5]
        [--foxglove-port 8765] [--ros-args -p use_sim_time:=true]

With ``use_sim_time`` the log times are simulated time (the cell's ``/clock``), as the
messages' stamps; Ctrl-C or ``--duration`` (wall seconds) ends it and closes the file.
"""

from __future__ import annotations

import argparse
import importlib
import signal
import sys
import threading
import time
from functools import partial
from pathlib import Path

import rclpy
from ament_index_python.packages import get_package_share_directory
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, ReliabilityPolicy
from rclpy.signals import SignalHandlerOptions

from dombot_bringup.qos import matching_qos
from dombot_bringup.recording import (
    BEST_EFFORT,
    DURABILITY,
    RELIABILITY,
    RELIABLE,
    THROTTLED_TYPES,
    TRANSIENT_LOCAL,
    VOLATILE,
    DefinitionNotFoundError,
    FoxgloveSink,
    McapSink,
    Sink,
    Throttle,
    header_stamp,
    message_definition,
)

DISCOVERY_PERIOD = 0.5  # s wall


def message_class(type_name: str) -> type:
    """The generated class of 'pkg/msg/Type'."""
    package, kind, name = type_name.split("/")
    return getattr(importlib.import_module(f"{package}.{kind}"), name)


def is_hidden(topic: str) -> bool:
    return any(part.startswith("_") for part in topic.split("/"))


class Recorder(Node):
    """Subscribes to every (non-hidden) topic with a publisher and hands each message on."""

    def __init__(self, sinks: list[Sink], image_rate: float) -> None:
        super().__init__("recorder")
        self._sinks = sinks
        self._throttle = Throttle(image_rate)
        self._recorded: dict[str, object] = {}
        self._throttled: set[str] = set()
        self.create_timer(DISCOVERY_PERIOD, self._discover)
        self._discover()

    def _discover(self) -> None:
        for topic, types in self.get_topic_names_and_types():
            if topic in self._recorded or is_hidden(topic):
                continue
            publishers = self.get_publishers_info_by_topic(topic)
            if not publishers:
                continue  # only subscribers so far: the QoS to ask for is not known yet
            self._subscribe(topic, types[0], publishers)

    def _subscribe(self, topic: str, type_name: str, publishers: list) -> None:
        try:
            kind = message_class(type_name)
        except (ImportError, AttributeError, ValueError):
            self.get_logger().warning(f"not recording {topic}: type {type_name} not installed")
            self._recorded[topic] = None
            return
        try:
            definition = message_definition(type_name, get_package_share_directory)
        except DefinitionNotFoundError as error:  # recorded all the same, as rosbag2 does
            self.get_logger().warning(f"{topic}: {error}; recorded without it")
            definition = ""
        qos = matching_qos(publishers, depth=100)
        metadata = {
            DURABILITY: (
                TRANSIENT_LOCAL if qos.durability == DurabilityPolicy.TRANSIENT_LOCAL else VOLATILE
            ),
            RELIABILITY: RELIABLE if qos.reliability == ReliabilityPolicy.RELIABLE else BEST_EFFORT,
        }
        for sink in self._sinks:
            sink.add_channel(topic, type_name, definition, metadata)
        if type_name in THROTTLED_TYPES:
            self._throttled.add(topic)
        self._recorded[topic] = self.create_subscription(
            kind, topic, partial(self._on_message, topic), qos, raw=True
        )
        self.get_logger().info(f"recording {topic} [{type_name}]")

    def _on_message(self, topic: str, data: bytes) -> None:
        now = self.get_clock().now().nanoseconds
        if topic in self._throttled:
            stamp = header_stamp(data)
            if not self._throttle.keep(topic, now if stamp is None else stamp):
                return
        for sink in self._sinks:
            sink.write(topic, data, now, now)


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="record", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("-o", "--output", type=Path, help="MCAP file to write")
    parser.add_argument(
        "--image-rate", type=float, default=1.0, help="raw images kept per topic [Hz] (1; 0: none)"
    )
    parser.add_argument("--duration", type=float, default=0.0, help="stop after [s wall] (0: ^C)")
    parser.add_argument("--foxglove-port", type=int, help="also serve live to Foxglove here")
    args = parser.parse_args(argv)
    if args.output is None and args.foxglove_port is None:
        parser.error("give -o FILE.mcap, --foxglove-port PORT, or both")
    if not args.image_rate >= 0.0 or not args.duration >= 0.0:
        parser.error("--image-rate and --duration must be >= 0")
    return args


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv if argv is None else argv
    args = parse_args(rclpy.utilities.remove_ros_args(argv)[1:])
    sinks: list[Sink] = []
    try:
        if args.foxglove_port is not None:
            sinks.append(FoxgloveSink(port=args.foxglove_port))
            print(f"record: Foxglove: open {sinks[-1].url} in the Foxglove app", flush=True)
        if args.output is not None:
            sinks.append(McapSink(args.output))
    except (RuntimeError, OSError) as error:
        print(f"record: {error}", file=sys.stderr)
        return 2
    # Ctrl-C and the supervisor's SIGINT/SIGTERM only ask the loop to stop: raised inside
    # a write, KeyboardInterrupt left a half-written record in the file (unreadable chunk)
    rclpy.init(args=argv, signal_handler_options=SignalHandlerOptions.NO)
    stop = threading.Event()
    for signum in (signal.SIGINT, signal.SIGTERM):
        signal.signal(signum, lambda *_: stop.set())
    node = Recorder(sinks, args.image_rate)
    deadline = time.monotonic() + args.duration if args.duration > 0 else None
    try:
        while not stop.is_set() and (deadline is None or time.monotonic() < deadline):
            rclpy.spin_once(node, timeout_sec=0.1)
    finally:
        for sink in sinks:
            sink.close()
        node.destroy_node()
        rclpy.try_shutdown()
    if args.output is not None:
        print(f"record: wrote {args.output}", flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main())

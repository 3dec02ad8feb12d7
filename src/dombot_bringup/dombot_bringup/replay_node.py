"""replay: publish an MCAP recording again with its original timing (a ``ros2 bag
play``-like, for files written by ``record`` or rosbag2).

Each topic is published with its recorded type and its recorded publishers' durability
and reliability (so ``/tf_static`` and ``/robot_description`` reach late subscribers),
the messages as recorded, raw. Messages go out at their log-time spacing divided by
``--rate``; ``--loop`` starts over at the end. ``/clock`` carries the recording's time:
republished as recorded when the recording has it, else published from the log times
(as ``ros2 bag play --clock``), so nodes with ``use_sim_time`` follow the replay.

    ros2 run dombot_bringup replay out/run.mcap [--rate 2] [--loop]
"""

from __future__ import annotations

import argparse
import sys
import time
from pathlib import Path

import rclpy
from builtin_interfaces.msg import Time
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, HistoryPolicy, QoSProfile, ReliabilityPolicy
from rosgraph_msgs.msg import Clock

from dombot_adapters.node_shutdown import stop_quietly_on_shutdown
from dombot_bringup.record_node import message_class
from dombot_bringup.recording import (
    BEST_EFFORT,
    DURABILITY,
    RELIABILITY,
    TRANSIENT_LOCAL,
    recorded_channels,
    recorded_messages,
)

TAIL = 0.5  # s kept alive after the last message
CLOCK_PERIOD = 0.025  # s of recording time between /clock messages made from log times


def qos_of(metadata: dict[str, str]) -> QoSProfile:
    durable = metadata.get(DURABILITY) == TRANSIENT_LOCAL
    return QoSProfile(
        history=HistoryPolicy.KEEP_LAST,
        depth=1 if durable else 100,
        durability=DurabilityPolicy.TRANSIENT_LOCAL if durable else DurabilityPolicy.VOLATILE,
        reliability=(
            ReliabilityPolicy.BEST_EFFORT
            if metadata.get(RELIABILITY) == BEST_EFFORT
            else ReliabilityPolicy.RELIABLE
        ),
    )


class Player(Node):
    def __init__(self, path: Path, rate: float) -> None:
        super().__init__("replay")
        self.path, self.rate = path, rate
        channels = recorded_channels(path)
        self._by_topic = {
            topic: self._publisher(topic, type_name, metadata)
            for topic, (type_name, metadata) in channels.items()
        }
        self._own_clock = "/clock" not in channels
        self._clock = self.create_publisher(Clock, "/clock", 10) if self._own_clock else None
        self.published = 0

    def _publisher(self, topic: str, type_name: str, metadata: dict[str, str]):
        try:
            kind = message_class(type_name)
        except (ImportError, AttributeError, ValueError):
            self.get_logger().warning(f"skipping {topic}: type {type_name!r} not installed")
            return None
        return self.create_publisher(kind, topic, qos_of(metadata))

    def play_once(self) -> None:
        """Every message of the file, at its recorded spacing over ``rate``."""
        start_wall = time.monotonic()
        first = None
        next_clock = None
        for message in recorded_messages(self.path):
            if not rclpy.ok():
                return
            publisher = self._by_topic.get(message.topic)
            first = message.log_time if first is None else first
            delay = start_wall + (message.log_time - first) * 1e-9 / self.rate - time.monotonic()
            if delay > 0.0:
                time.sleep(delay)
            if self._clock is not None and (next_clock is None or message.log_time >= next_clock):
                stamp = Time(sec=message.log_time // 10**9, nanosec=message.log_time % 10**9)
                self._clock.publish(Clock(clock=stamp))
                next_clock = message.log_time + round(CLOCK_PERIOD * 1e9)
            if publisher is not None:
                publisher.publish(message.data)
                self.published += 1


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="replay", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("recording", type=Path, help="an MCAP file (record, rosbag2)")
    parser.add_argument("--rate", type=float, default=1.0, help="speed factor (1)")
    parser.add_argument("--loop", action="store_true", help="start over at the end")
    parser.add_argument(
        "--delay", type=float, default=1.0, help="[s] wait for subscribers to match first (1)"
    )
    args = parser.parse_args(argv)
    if not args.rate > 0.0 or not args.delay >= 0.0:
        parser.error(f"--rate must be > 0 and --delay >= 0, got {args.rate}, {args.delay}")
    if not args.recording.is_file():
        parser.error(f"no such file: {args.recording}")
    return args


def main(argv: list[str] | None = None) -> int:
    argv = sys.argv if argv is None else argv
    args = parse_args(rclpy.utilities.remove_ros_args(argv)[1:])
    rclpy.init(args=argv)
    try:
        node = Player(args.recording, args.rate)
    except Exception as error:  # not an MCAP file, or a damaged one
        print(f"replay: cannot read {args.recording}: {error}", file=sys.stderr)
        rclpy.try_shutdown()
        return 2
    try:
        with stop_quietly_on_shutdown():
            time.sleep(args.delay)
            node.play_once()
            while args.loop and rclpy.ok():
                node.play_once()
            print(f"replay: published {node.published} messages", flush=True)
            time.sleep(TAIL)  # reliable messages still in flight reach their subscribers
    finally:
        node.destroy_node()
        rclpy.try_shutdown()
    return 0


if __name__ == "__main__":
    sys.exit(main())

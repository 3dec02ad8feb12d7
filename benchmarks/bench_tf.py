"""Benchmark what sim_node's /tf costs against one simulation tick: the arm and gripper
links (every tick at the default ``tf_rate``) and 30 domino frames (``domino_tf_rate``),
each computed from the plant, converted to a message and published.

Prints one JSON object on stdout: medians in ms over ``--repeats``.
"""

from __future__ import annotations

import argparse
import json
import time
from collections.abc import Callable

import numpy as np
import rclpy
from tf2_msgs.msg import TFMessage

from dombot_sim.sim_messages import tf_message
from dombot_sim.world import CellWorld, WorldConfig

DOMINOES = 30
TICK = 0.01  # s simulated: sim_node's default joint_state_rate, 100 Hz


def median_ms(action: Callable[[], object], repeats: int) -> float:
    times = []
    for _ in range(repeats):
        start = time.perf_counter()
        action()
        times.append(time.perf_counter() - start)
    return float(np.median(times) * 1e3)


def flat_grid(count: int) -> dict[int, np.ndarray]:
    """Dominoes lying flat in rows on the table in front of the arm."""
    poses = {}
    for index in range(count):
        pose = np.eye(4)
        pose[:3, 3] = [0.45 + 0.06 * (index % 6), -0.4 + 0.04 * (index // 6), 0.00375]
        poses[index] = pose
    return poses


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--repeats", type=int, default=300)
    args = parser.parse_args()
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=DOMINOES))
    world.set_domino_poses(flat_grid(DOMINOES))
    world.advance(1.0)  # let them come to rest
    rclpy.init()
    node = rclpy.create_node("bench_tf")
    publisher = node.create_publisher(TFMessage, "/tf", 100)
    links = len(world.link_frames())
    result = {
        "tick_ms": median_ms(lambda: world.advance(TICK), args.repeats),
        "link_frames": links,
        "link_tf_ms": median_ms(
            lambda: publisher.publish(tf_message(world.time, world.link_frames())), args.repeats
        ),
        "domino_frames": DOMINOES,
        "domino_tf_ms": median_ms(
            lambda: publisher.publish(tf_message(world.time, world.domino_frames())),
            args.repeats,
        ),
        "repeats": args.repeats,
    }
    node.destroy_node()
    rclpy.shutdown()
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

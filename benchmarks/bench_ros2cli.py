"""Benchmark the ``ros2`` stand-in's graph discovery: with layer_node up, how many lines
each of several fresh ``ros2 service list`` calls prints and how long each takes, and
how long ``ros2 topic list`` takes on an empty graph.

Prints one JSON object on stdout. Runs in its own ROS domain, discovery on localhost.
"""

from __future__ import annotations

import argparse
import json
import os
import signal
import subprocess
import time


def timed(command: list[str], env: dict[str, str]) -> tuple[int, float]:
    """Lines printed by ``command`` and its wall time [s]."""
    start = time.monotonic()
    output = subprocess.run(command, env=env, capture_output=True, text=True, check=True).stdout
    return len(output.splitlines()), round(time.monotonic() - start, 2)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--calls", type=int, default=6, help="service list calls (6)")
    parser.add_argument("--domain", type=int, default=87, help="ROS_DOMAIN_ID (87)")
    args = parser.parse_args()
    env = dict(
        os.environ, ROS_DOMAIN_ID=str(args.domain), ROS_AUTOMATIC_DISCOVERY_RANGE="LOCALHOST"
    )
    node = subprocess.Popen(
        ["ros2", "run", "dombot_layer", "layer_node"],
        env=env,
        stdout=subprocess.DEVNULL,
        stderr=subprocess.DEVNULL,
    )
    try:
        calls = [timed(["ros2", "service", "list"], env) for _ in range(args.calls)]
    finally:
        node.send_signal(signal.SIGINT)
        node.wait(timeout=60)
    empty_lines, empty_seconds = timed(["ros2", "topic", "list"], env)
    print(
        json.dumps(
            {
                "service_list_lines": [lines for lines, _ in calls],
                "service_list_seconds": [seconds for _, seconds in calls],
                "empty_graph_topic_list_seconds": empty_seconds,
                "empty_graph_topic_list_lines": empty_lines,
                "load_average_1min": round(os.getloadavg()[0], 1),
            }
        )
    )


if __name__ == "__main__":
    main()

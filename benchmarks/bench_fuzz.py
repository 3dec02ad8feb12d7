"""Fuzz every service and layer_node's inputs over real DDS for a long run.

Starts planner_node, sim_node, perception_node and layer_node (tests/support/fuzz.py),
sends at least ``--requests`` hostile requests per endpoint in batches of up to 10 at
once (hypothesis, ``--seed``), a valid request after every batch, and prints one JSON object:
requests, outcome histogram, worst reply latency per endpoint, wrong outcomes, hangs,
crashes, and each node's RSS after warm-up and at the end. Progress on stderr.

    python benchmarks/bench_fuzz.py --requests 1000
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import tempfile
import time
from pathlib import Path

# its own ROS domain, discovery on localhost: other sessions' nodes must not answer
os.environ.setdefault("ROS_DOMAIN_ID", str(10 + os.getpid() % 90))
os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")

import rclpy
from rclpy.node import Node

sys.path.insert(0, str(Path(__file__).resolve().parent.parent / "tests"))

from support.fuzz import (
    Harness,
    fuzz,
    fuzzed_nodes,
    layer_endpoints,
    layer_parameter_cases,
    path_cases,
    radius_cases,
    service_endpoints,
)

LAYER_CASES = {
    "/layer/target_radius": radius_cases,
    "/layer/path": path_cases,
    "/layer_node/set_parameters": layer_parameter_cases,
}


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=1000, help="hostile requests per endpoint")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=300.0, help="s before a reply is a hang")
    parser.add_argument(
        "--logs", type=Path, default=Path(tempfile.gettempdir()) / "dombot_fuzz", help="node logs"
    )
    parser.add_argument("--only", nargs="*", help="endpoint names (default: all)")
    parser.add_argument(
        "--fewest-at-once", type=int, default=1, help="smallest batch (largest: 10)"
    )
    args = parser.parse_args()
    rclpy.init()
    began = time.monotonic()
    args.logs.mkdir(parents=True, exist_ok=True)
    with fuzzed_nodes(args.logs) as processes:
        node = Node("fuzz_bench")
        endpoints = service_endpoints(node)
        endpoints |= {e.name: (e, LAYER_CASES[e.name]) for e in layer_endpoints(node)}
        harness = Harness(processes, args.timeout)
        chosen = args.only or list(endpoints)
        for name in chosen:  # warm-up: every node has served once (plants built, caches)
            harness.warm_up(endpoints[name][0])
        harness.rss("after_warm_up")
        for name in chosen:
            endpoint, cases = endpoints[name]
            log(f"{name}: {args.requests} requests ...")
            target = harness.report.requests[name] + args.requests
            while harness.report.requests[name] < target:
                fuzz(
                    harness,
                    endpoint,
                    cases(),
                    batches=20,
                    random_seed=args.seed,
                    fewest_at_once=args.fewest_at_once,
                )
                args.seed += 1
            log(f"{name}: done after {time.monotonic() - began:.0f} s")
        harness.rss("end")
        node.destroy_node()
    rclpy.shutdown()
    result = harness.report.as_json()
    result["seconds"] = round(time.monotonic() - began, 1)
    for rss in result["rss_mb"].values():
        if "after_warm_up" in rss and "end" in rss:
            rss["growth"] = round(rss["end"] / rss["after_warm_up"] - 1, 4)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

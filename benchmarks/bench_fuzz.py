"""Fuzz every service, the arm and gripper actions and layer_node's inputs over real DDS.

Starts planner_node, sim_node, perception_node and layer_node (tests/support/fuzz/),
sends at least ``--requests`` hostile requests per endpoint in batches of up to 10 at
once (hypothesis, ``--seed``), a valid request after every batch, and prints one JSON
object: requests, outcome histogram, worst batch latency per endpoint, wrong outcomes,
hangs, crashes, each node's RSS after warm-up and at the end, and per endpoint the
serving node's RSS growth from its first WARM_UP_REQUESTS requests to its last (caches
and allocator arenas fill first) with its RSS after every 5 batches. Progress on stderr.

    python benchmarks/bench_fuzz.py --requests 1000
"""

from __future__ import annotations

import argparse
import json
import math
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
    action_endpoints,
    fuzz,
    fuzzed_nodes,
    layer_endpoints,
    layer_parameter_cases,
    path_cases,
    radius_cases,
    rss_mb,
    service_endpoints,
)

WARM_UP_REQUESTS = 100  # RSS growth is measured from here (caches fill, arenas grow)
LAYER_CASES = {
    "/layer/target_radius": radius_cases,
    "/layer/path": path_cases,
    "/layer_node/set_parameters": layer_parameter_cases,
}


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def node_rss(harness: Harness, node: str) -> float:
    process = harness.processes[node]
    return round(rss_mb(process.pid), 1) if process.poll() is None else float("nan")


def endpoint_growth(
    harness: Harness, node: str, start: int, name: str, trace: list[tuple[int, float]]
) -> dict:
    """The serving node's RSS after the endpoint's first WARM_UP_REQUESTS requests and
    after its last, the growth between them, and the RSS after every round of batches
    (``trace``: requests served, MB) to tell a plateau from a leak."""
    growth = {"node": node, "requests": harness.report.requests[name] - start}
    growth["rss_mb_end"] = node_rss(harness, node)
    settled = next(((n, mb) for n, mb in trace if n >= WARM_UP_REQUESTS), None)
    if settled is not None:
        growth["warm_up_requests"], growth["rss_mb_after_warm_up"] = settled
        growth["growth"] = round(growth["rss_mb_end"] / settled[1] - 1, 4)
    growth["rss_trace"] = trace
    return growth


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--requests", type=int, default=1000, help="hostile requests per endpoint")
    parser.add_argument("--seed", type=int, default=0)
    parser.add_argument("--timeout", type=float, default=300.0, help="s before a reply is a hang")
    parser.add_argument(
        "--logs", type=Path, default=Path(tempfile.gettempdir()) / "dombot_fuzz", help="node logs"
    )
    parser.add_argument(
        "--only", nargs="*", help="endpoint names (default: all); only their nodes are started"
    )
    parser.add_argument(
        "--fewest-at-once", type=int, default=1, help="smallest batch (largest: 10)"
    )
    parser.add_argument(
        "--max-seconds", type=float, default=math.inf, help="start no batch after this"
    )
    args = parser.parse_args()
    rclpy.init()
    began = time.monotonic()
    args.logs.mkdir(parents=True, exist_ok=True)
    node = Node("fuzz_bench")
    endpoints = service_endpoints(node) | action_endpoints(node)
    endpoints |= {e.name: (e, LAYER_CASES[e.name]) for e in layer_endpoints(node)}
    chosen = args.only or list(endpoints)
    with fuzzed_nodes(args.logs, {endpoints[name][0].node for name in chosen}) as processes:
        harness = Harness(processes, args.timeout)
        for name in chosen:  # warm-up: every node has served once (plants built, caches)
            harness.warm_up(endpoints[name][0])
        harness.rss("after_warm_up")
        growth = {}
        for name in chosen:
            endpoint, cases = endpoints[name]
            log(f"{name}: {args.requests} requests ...")
            start = harness.report.requests[name]
            trace = []  # (requests served, RSS) after each round of batches
            while harness.report.requests[name] < start + args.requests:
                if time.monotonic() - began > args.max_seconds:
                    log(f"{name}: stopped after --max-seconds")
                    break
                fuzz(
                    harness,
                    endpoint,
                    cases(),
                    batches=5,
                    random_seed=args.seed,
                    fewest_at_once=args.fewest_at_once,
                )
                args.seed += 1
                served = harness.report.requests[name] - start
                trace.append((served, node_rss(harness, endpoint.node)))
            growth[name] = endpoint_growth(harness, endpoint.node, start, name, trace)
            log(f"{name}: done after {time.monotonic() - began:.0f} s")
        harness.rss("end")
    node.destroy_node()
    rclpy.shutdown()
    result = harness.report.as_json()
    result["seconds"] = round(time.monotonic() - began, 1)
    result["rss_growth"] = growth
    for rss in result["rss_mb"].values():
        if "after_warm_up" in rss and "end" in rss:
            rss["growth"] = round(rss["end"] / rss["after_warm_up"] - 1, 4)
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

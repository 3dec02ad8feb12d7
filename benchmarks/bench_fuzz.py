"""Fuzz every service, the arm and gripper actions and layer_node's inputs over real DDS.

Starts planner_node, sim_node, perception_node and layer_node (tests/support/fuzz/),
sends at least ``--requests`` hostile requests per endpoint in batches of up to 10 at
once (hypothesis, ``--seed``), a valid request after every batch, and prints one JSON
object: requests, outcome histogram, worst batch latency per endpoint, wrong outcomes,
hangs, crashes, each node's RSS after warm-up and at the end, and per endpoint the
serving node's RSS growth over ``--requests`` hostile requests sent after ``--warm-up``
others (caches and allocator arenas fill first), the slope of its second half and its
RSS after every 5 batches. Progress on stderr.

    python benchmarks/bench_fuzz.py --warm-up 1000 --requests 1000
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

import numpy as np

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
    harness: Harness, node: str, warm_up: tuple[int, float], trace: list[tuple[int, float]]
) -> dict:
    """The serving node's RSS after the warm-up (``warm_up``: requests, MB) and at the
    end, the growth between them, the slope over the second half of the measured requests
    (MB per 1,000: a plateau is flat there, a leak is not) and the RSS after every round
    of batches (``trace``: requests served since the warm-up began, MB)."""
    served, baseline = warm_up
    end = node_rss(harness, node)
    measured = [(n, mb) for n, mb in trace if n > served]
    growth = {
        "node": node,
        "warm_up_requests": served,
        "requests": (measured[-1][0] - served) if measured else 0,
        "rss_mb_after_warm_up": baseline,
        "rss_mb_end": end,
        "growth": round(end / baseline - 1, 4),
    }
    second_half = [(n, mb) for n, mb in measured if n - served >= growth["requests"] / 2]
    if len(second_half) >= 3:
        n, mb = np.array(second_half).T
        growth["slope_mb_per_1000_second_half"] = round(1000 * np.polyfit(n, mb, 1)[0], 2)
    growth["rss_trace"] = trace
    return growth


def fuzz_rounds(harness: Harness, endpoint, cases, args, until: int, began: float) -> list:
    """Rounds of 5 batches until ``until`` requests to ``endpoint`` were sent (or
    ``--max-seconds``); returns (requests, serving node's RSS) after each round."""
    trace = []
    while harness.report.requests[endpoint.name] < until:
        if time.monotonic() - began > args.max_seconds:
            log(f"{endpoint.name}: stopped after --max-seconds")
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
        trace.append((harness.report.requests[endpoint.name], node_rss(harness, endpoint.node)))
    return trace


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument(
        "--requests", type=int, default=1000, help="measured hostile requests per endpoint"
    )
    parser.add_argument(
        "--warm-up",
        type=int,
        default=1000,
        help="hostile requests per endpoint sent before RSS growth is measured",
    )
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
            log(f"{name}: {args.warm_up} + {args.requests} requests ...")
            start = harness.report.requests[name]
            trace = fuzz_rounds(harness, endpoint, cases, args, start + args.warm_up, began)
            warm_up = (harness.report.requests[name], node_rss(harness, endpoint.node))
            trace += fuzz_rounds(harness, endpoint, cases, args, warm_up[0] + args.requests, began)
            trace = [(n - start, mb) for n, mb in trace]
            warm_up = (warm_up[0] - start, warm_up[1])
            growth[name] = endpoint_growth(harness, endpoint.node, warm_up, trace)
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

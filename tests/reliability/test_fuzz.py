"""A short fuzz run over real DDS (tests/support/fuzz/; the long one is
benchmarks/bench_fuzz.py): every service, the arm and gripper actions and layer_node's
inputs get batches of up to 10 hostile requests at once. Verdicts are on outcomes only:
each reply carries the error code (or success flag) that is right for what was broken and
a message, no node dies, nothing goes unanswered within a generous timeout, a valid
request is served after every batch."""

from __future__ import annotations

import pytest
import rclpy
from rclpy.node import Node

# support.fuzz (hypothesis: seconds to import) is imported by the fixture, not here:
# every pytest-xdist worker collects this module.

pytestmark = pytest.mark.slow  # every node, fuzzed over DDS

REPLY_TIMEOUT = 300.0  # s: a hang, not a slow machine (a search ends long before its budget)
BATCHES = {  # derandomized: the same batches every run
    "/plan_place": 6,
    "/plan_strike": 4,
    "/perception/detect": 2,
    "/perception/check_placement": 3,
    "/sim/reset": 2,
    "/arm_controller/follow_joint_trajectory": 4,
    "/gripper_controller/gripper_cmd": 2,
    "/layer/target_radius": 3,
    "/layer/path": 3,
    "/layer_node/set_parameters": 3,
}


@pytest.fixture(scope="module")
def session(tmp_path_factory):
    from support.fuzz import (
        Harness,
        action_endpoints,
        fuzzed_nodes,
        layer_endpoints,
        layer_parameter_cases,
        path_cases,
        radius_cases,
        service_endpoints,
    )

    layer_cases = {
        "/layer/target_radius": radius_cases,
        "/layer/path": path_cases,
        "/layer_node/set_parameters": layer_parameter_cases,
    }
    rclpy.init()
    with fuzzed_nodes(tmp_path_factory.mktemp("fuzz_logs")) as processes:
        node = Node("fuzz_probe")
        endpoints = service_endpoints(node) | action_endpoints(node)
        endpoints |= {e.name: (e, layer_cases[e.name]) for e in layer_endpoints(node)}
        yield Harness(processes, REPLY_TIMEOUT), endpoints
        node.destroy_node()
    rclpy.shutdown()


@pytest.mark.parametrize("name", list(BATCHES))
def test_hostile_requests_get_the_right_code_and_a_message(session, name: str) -> None:
    from support.fuzz import fuzz

    harness, endpoints = session
    endpoint, cases = endpoints[name]
    harness.warm_up(endpoint)
    fuzz(harness, endpoint, cases(), BATCHES[name])
    report = harness.report
    assert report.requests[name] > BATCHES[name]
    assert not report.crashes
    mine = [line for line in report.wrong + report.hangs + report.unserved if line.startswith(name)]
    assert not mine, "\n".join(mine)

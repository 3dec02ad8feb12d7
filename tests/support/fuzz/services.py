"""The service endpoints: the planner's, perception_node's and /sim/reset."""

from __future__ import annotations

from collections.abc import Callable

from hypothesis import strategies as st
from rclpy.node import Node

from dombot_msgs.srv import CheckPlacement, DetectDominoes, PlanPlace, PlanStrike, ResetSim
from support.fuzz.harness import Case, Endpoint, service_sender
from support.fuzz.planning import (
    VALID_BUDGET,
    changed,
    place_cases,
    random_place,
    strike_cases,
    valid_place,
    valid_strike,
)
from support.fuzz.replies import flag_outcome, planner_outcome, planner_problem
from support.fuzz.sensing import check_cases, detect_cases, reset_cases
from support.fuzz.values import PLACE, pose_of


def service_endpoints(node: Node) -> dict[str, tuple[Endpoint, Callable[[], st.SearchStrategy]]]:
    """Every service endpoint with its case strategy."""
    return {
        "/plan_place": (
            Endpoint(
                "/plan_place",
                "planner_node",
                service_sender(node, PlanPlace, "/plan_place"),
                planner_outcome,
                Case(
                    changed(valid_place(), time_budget=VALID_BUDGET),
                    "valid",
                    frozenset({"SUCCESS"}),
                ),
                planner_problem,
            ),
            lambda: st.one_of(place_cases(), random_place()),
        ),
        "/plan_strike": (
            Endpoint(
                "/plan_strike",
                "planner_node",
                service_sender(node, PlanStrike, "/plan_strike"),
                planner_outcome,
                Case(
                    changed(valid_strike(), time_budget=VALID_BUDGET),
                    "valid",
                    frozenset({"SUCCESS"}),
                ),
                planner_problem,
            ),
            strike_cases,
        ),
        "/perception/detect": (
            Endpoint(
                "/perception/detect",
                "perception_node",
                service_sender(node, DetectDominoes, "/perception/detect"),
                flag_outcome,
                Case(DetectDominoes.Request(), "valid", frozenset({"ok"})),
            ),
            detect_cases,
        ),
        "/perception/check_placement": (
            Endpoint(
                "/perception/check_placement",
                "perception_node",
                service_sender(node, CheckPlacement, "/perception/check_placement"),
                flag_outcome,
                Case(CheckPlacement.Request(expected=[pose_of(PLACE)]), "valid", frozenset({"ok"})),
            ),
            check_cases,
        ),
        "/sim/reset": (
            Endpoint(
                "/sim/reset",
                "sim_node",
                service_sender(node, ResetSim, "/sim/reset"),
                flag_outcome,
                Case(ResetSim.Request(domino_count=3, seed=1), "valid", frozenset({"ok"})),
            ),
            reset_cases,
        ),
    }

"""The real planner answering the task core's /plan_place requests in-process, as
planner_node would from the arm's home (no ROS): for tests that ask it real geometry."""

from __future__ import annotations

from collections.abc import Callable

from pydrake.math import RigidTransform

from dombot_bringup.task.cell import PlaceRequest, Plan
from dombot_description.scenario import load_scenario
from dombot_planner.errors import PlanningError
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest


def in_process(planner: PickPlacePlanner) -> Callable[[PlaceRequest], Plan]:
    """The planner answering /plan_place from the arm's home, as planner_node would."""
    home = load_scenario().home_position

    def place(request: PlaceRequest) -> Plan:
        try:
            planner.plan(
                PickPlaceRequest(
                    RigidTransform(request.domino),
                    RigidTransform(request.place),
                    home,
                    standing=tuple(RigidTransform(p) for p in request.standing),
                    pile_points=request.pile_points.reshape(-1, 3),
                    time_budget=request.time_budget,
                )
            )
        except PlanningError as error:
            return Plan(False, error.code, f"{error.code.name} at {error.stage}: {error.message}")
        return Plan(True, message="planned")

    return place

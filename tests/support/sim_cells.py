"""Drake cells for tests that plan and move without the nodes: the world without cameras
and the real planner, and a plan's segments run on it as the task does, without its checks
between them. Drake is imported when a cell is made, not when a test module is collected."""

from __future__ import annotations

from collections.abc import Sequence
from typing import TYPE_CHECKING

from dombot_bringup.task.cell import Segment
from support.planning_clock import UNHURRIED

if TYPE_CHECKING:
    from dombot_bringup.sim_cell import SimCell
    from dombot_sim.world import CellWorld


def blind_cell(domino_capacity: int) -> tuple[CellWorld, SimCell]:
    """The scenario's world with ``domino_capacity`` dominoes and no cameras, and a
    ``SimCell`` on it (no perception) whose planner has all the time it needs."""
    from dombot_bringup.sim_cell import SimCell
    from dombot_description.scenario import load_scenario
    from dombot_planner.planner import PickPlacePlanner
    from dombot_planner.settings import PlannerSettings
    from dombot_sim.world import CellWorld, WorldConfig

    scenario = load_scenario()
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=domino_capacity), scenario)
    planner = PickPlacePlanner(scenario, PlannerSettings(default_time_budget=UNHURRIED))
    return world, SimCell(world, None, planner)


def run_segments(cell, segments: Sequence[Segment]) -> None:
    """Each segment's trajectory (asserted to end well), then its gripper command."""
    for segment in segments:
        if len(segment.trajectory.times):
            assert cell.execute(segment.trajectory).ok
        if segment.gripper_after:
            cell.gripper(segment.gripper_position, segment.gripper_max_effort)

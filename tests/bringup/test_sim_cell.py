"""``SimCell``: the task core's ``Cell`` in one process (world, perception, planner), with
no ROS: it answers every question the protocol asks, and the real loop places a domino
from a poured pile through it."""

from __future__ import annotations

import inspect
import math
import subprocess
import sys

import numpy as np
import pytest

from dombot_bringup import layouts
from dombot_bringup.sim_cell import SimCell
from dombot_bringup.task.cell import Cell
from dombot_bringup.task.geometry import foot_distance
from dombot_bringup.task.loop import Turn, place_slot
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_description import tilt_from_vertical


def protocol_members() -> list[str]:
    return [name for name in vars(Cell) if not name.startswith("_")]


def test_sim_cell_has_every_member_of_the_cell_protocol() -> None:
    """Each method takes the protocol's parameters; each property is a property."""
    assert {"detect", "execute", "gripper", "plan_place", "sim_time"} <= set(protocol_members())
    for name in protocol_members():
        wanted, given = inspect.getattr_static(Cell, name), inspect.getattr_static(SimCell, name)
        if isinstance(wanted, property):
            assert isinstance(given, property), name
            continue
        assert list(inspect.signature(given).parameters) == list(
            inspect.signature(wanted).parameters
        ), name


def test_sim_cell_imports_no_ros() -> None:
    code = """
import sys
ROS = ("rclpy", "rosidl", "builtin_interfaces", "geometry_msgs", "sensor_msgs",
       "trajectory_msgs", "control_msgs", "dombot_msgs")
for name in ROS:
    sys.modules[name] = None  # importing it raises
import dombot_bringup.sim_cell
print(sorted(m for m in sys.modules if m.split(".")[0] in ROS and sys.modules[m] is not None))
"""
    answer = subprocess.run([sys.executable, "-c", code], capture_output=True, text=True)
    assert answer.returncode == 0, answer.stderr
    assert answer.stdout.strip() == "[]"


@pytest.mark.slow
def test_the_real_loop_places_a_domino_from_a_pile_through_sim_cell() -> None:
    """One slot of an arc, built by ``place_slot`` from a poured pile of 8: placed, and in
    the simulator's truth the nearest domino stands upright on its target."""
    from dombot_description.scenario import load_scenario
    from dombot_perception.pipeline import build_pipeline
    from dombot_planner.planner import PickPlacePlanner
    from dombot_sim.world import CellWorld, WorldConfig

    scenario = load_scenario()
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=8), scenario)
    cell = SimCell(world, build_pipeline(scenario), PickPlacePlanner(scenario))
    layout = layouts.arc((0.0, 0.0), 0.6, math.radians(5.0), 1)
    job = Job.new(cell, layout, "arc", ArmJobSettings(pile=8, seed=0))
    assert "poured 8 dominoes (seed 0); settled" in cell.reset(8, 0)

    assert place_slot(job, 0, may_defer=False) is Turn.PLACED
    assert job.report.dominoes[0].placed
    assert cell.time_spent["motion"] > 0.0 and cell.time_spent["gripper"] > 0.0
    poses = [pose for _, pose in cell.truth(newer_than=0.0)]
    nearest = min(poses, key=lambda pose: foot_distance(pose, job.targets[0]))
    assert foot_distance(nearest, job.targets[0]) < 0.004
    assert tilt_from_vertical(nearest) < math.radians(3.0)
    assert np.isclose(cell.sim_time, world.time)

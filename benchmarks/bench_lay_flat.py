"""Lay pile dominoes no grasp takes as they lie flat, in the Drake simulation.

Seeded scenes in the pile area: one domino standing on its long edge or on its end, at a
random spot and heading. For each, the planner is asked to
pick it for the bring-up's first slot (refused or not, as it lies); then the bring-up's
lay-flat pushes (``dombot_bringup.spread.lay_flat_pushes``, towards the pile's centre
first) are planned as sweeps and run in ``CellWorld`` until one runs; the domino's
posture after settling and whether its pick then plans are recorded.

Prints one JSON object on stdout.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
from collections import Counter

import numpy as np
from pydrake.math import RollPitchYaw

from dombot_bringup import layouts
from dombot_bringup.sim_cell import SimCell
from dombot_bringup.spread import lay_flat_pushes
from dombot_bringup.task.cell import PlaceRequest, StrikeRequest
from dombot_bringup.task.geometry import placement_pose
from dombot_description import DOMINO_SIZE
from dombot_description.scenario import load_scenario
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.settings import PlannerSettings
from dombot_sim.world import CellWorld, WorldConfig

POSTURES = ("on edge", "upright")
FLAT_Z = math.cos(math.radians(15.0))  # thickness axis this close to vertical: flat


def posture_of(pose: np.ndarray) -> str:
    """How a domino lies, as perception names it (body axis nearest vertical, 15°)."""
    vertical = np.abs(pose[2, :3])
    axis = int(np.argmax(vertical))
    if vertical[axis] < FLAT_Z:
        return "leaning"
    return ("upright", "on edge", "flat")[axis]


def scene(kind: str, rng: np.random.Generator, centre: np.ndarray) -> dict[int, np.ndarray]:
    """Domino 0 in posture ``kind`` at a random spot within 6 cm of ``centre``."""
    spot = centre + rng.uniform(-0.06, 0.06, 2)
    yaw = rng.uniform(0.0, math.pi)
    rotation = (
        {
            "on edge": RollPitchYaw(math.pi / 2, 0.0, yaw),
            "upright": RollPitchYaw(0.0, -math.pi / 2, yaw),
        }[kind]
        .ToRotationMatrix()
        .matrix()
    )
    pose = np.eye(4)
    pose[:3, :3] = rotation
    pose[:3, 3] = [*spot, np.abs(rotation[2, :]) @ np.asarray(DOMINO_SIZE) / 2 + 0.001]
    return {0: pose}


def run(cell: SimCell, poses: dict[int, np.ndarray], place: np.ndarray, centre) -> dict:
    world = cell.world
    world.set_domino_poses(poses)
    world.settle(2.0)
    lying = world.domino_truth()[0].X_WD
    others = [t.X_WD for t in world.domino_truth()[1:] if t.in_use]
    row = {"posture": posture_of(lying), "spot": lying[:2, 3].round(3).tolist()}
    before = cell.plan_place(PlaceRequest(lying, place, pile=tuple(others)))
    row["planned_before"] = before.error.name
    row["push"] = "none planned"
    for direction, distance in lay_flat_pushes(lying, centre):
        push = cell.plan_strike(
            StrikeRequest(lying, tuple(others), sweep=direction[:2], push_distance=distance)
        )
        if not push.success:
            row["push"] = push.message.split(" (")[0]
            continue
        for segment in push.segments:
            if len(segment.trajectory.times):
                cell.execute(segment.trajectory)
            if segment.gripper_after:
                cell.gripper(segment.gripper_position, segment.gripper_max_effort)
        cell.wait_for_sim_time(1.0)
        row["push"] = "ran"
        break
    after = world.domino_truth()[0].X_WD
    others = [t.X_WD for t in world.domino_truth()[1:] if t.in_use]
    row["posture_after"] = posture_of(after)
    planned = cell.plan_place(PlaceRequest(after, place, pile=tuple(others)))
    row["planned_after"] = planned.error.name
    return row


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--count", type=int, default=4, help="scenes per posture")
    parser.add_argument("--seed", type=int, default=0)
    args = parser.parse_args()
    load_before = os.getloadavg()
    scenario = load_scenario()
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=2), scenario)
    planner = PickPlacePlanner(scenario, PlannerSettings(default_time_budget=3600.0))
    cell = SimCell(world, None, planner)
    place = placement_pose(layouts.arc((0.0, 0.0), 0.6, math.radians(5.0), 1)[0])
    centre = np.asarray(scenario.pile_center)
    rng = np.random.default_rng(args.seed)
    rows = []
    for kind in POSTURES:
        for _ in range(args.count):
            rows.append({"scene": kind, **run(cell, scene(kind, rng, centre), place, centre)})
            print(json.dumps(rows[-1]), flush=True, file=sys.stderr)
    counts = Counter(
        (
            r["posture"],
            r["planned_before"] == "SUCCESS",
            r["posture_after"],
            r["planned_after"] == "SUCCESS",
        )
        for r in rows
    )
    print(
        json.dumps(
            {
                "benchmark": "lay_flat",
                "scenes": len(rows),
                "seed": args.seed,
                "planned_before": sum(r["planned_before"] == "SUCCESS" for r in rows),
                "pushed": sum(r["push"] == "ran" for r in rows),
                "flat_after": sum(r["posture_after"] == "flat" for r in rows),
                "planned_after": sum(r["planned_after"] == "SUCCESS" for r in rows),
                "by_posture": [[*k, n] for k, n in counts.items()],
                "rows": rows,
                "load_average": {"before": load_before, "after": os.getloadavg()},
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()

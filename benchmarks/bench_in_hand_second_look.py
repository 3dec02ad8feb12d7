"""What the in-hand check's second look (issue 23: ``ArmJobSettings.in_hand_look_turn``)
costs and finds for a domino carried above a slot where the gripper hides it from every
camera, in the physics and the cameras of one process (``SimCell``).

For each ``--slots`` of ``--layout``, every slot before it standing (its safety gaps
dropped, as at s_curve30's 22 mm in the ledger runs: more than ``in_hand_look_risk`` at
risk) and a flat domino at the pile's centre turned ``--pile-yaw``, the slot is planned
and the plan run by the task (``placing.execute``: pick, carry, the in-hand check, place)
from the same start once per ``--turns`` (the base turned so for the second look; 0: none). Prints
one JSON object: per slot and run the simulated seconds of the plan's execution, what the
task logged of the hold, and where the domino stands after the release by the simulator's
truth (foot from its target, tilt); progress on stderr.
"""

from __future__ import annotations

import argparse
import io
import json
import math
import sys
from contextlib import redirect_stdout

import numpy as np
from bench_in_hand import foot_and_tilt
from bench_run_slots import LAYOUTS, placements_of

from dombot_bringup.sim_cell import SimCell
from dombot_bringup.task.cell import PlaceRequest
from dombot_bringup.task.placing import Hold, execute
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_description.grasp import flat_pose
from dombot_description.scenario import load_scenario
from dombot_perception.pipeline import build_pipeline
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.settings import PlannerSettings
from dombot_sim.world import CellWorld, WorldConfig


def run_slot(cell: SimCell, args: argparse.Namespace, slot: int) -> dict:
    """The slot planned from home, the run before it standing, and the plan run by the
    task from there once per ``args.turns``."""
    world, run = cell.world, placements_of(args.layout)
    standing = range(slot - 1)
    picked = flat_pose(*cell.planner.scenario.pile_center, args.pile_yaw).GetAsMatrix4()
    rows: dict[str, dict] = {}
    plan = None
    for turn in args.turns:
        settings = ArmJobSettings(in_hand_look_turn=math.radians(turn))
        job = Job.new(cell, run, args.layout, settings)
        world.set_robot_positions()
        world.set_domino_poses({0: picked} | {k + 1: job.targets[k] for k in standing})
        job.state.standing = {k: job.targets[k] for k in standing}
        if plan is None:
            standing_poses = tuple(job.state.standing.values())
            plan = cell.plan_place(PlaceRequest(picked, job.releases[slot - 1], standing_poses))
            if not plan.success:
                return {"refused": plan.message}
        said, start = io.StringIO(), cell.sim_time
        with redirect_stdout(said):
            ran = execute(job, plan.segments, Hold(slot - 1, plan.held_above_place, picked))
        truth = [t.X_WD for t in world.domino_truth()]  # in the order of set_domino_poses
        foot, tilt = foot_and_tilt(truth[0], job.targets[slot - 1])
        leaning = [k + 1 for k in standing if tilt_of(truth[k + 1]) > math.radians(3.0)]
        rows[f"turn {turn:+.0f}°"] = row = {
            "ran": ran.ran.value,
            "simulated s": round(cell.sim_time - start, 2),
            "said": [
                line for line in said.getvalue().splitlines() if "hand" in line or "base" in line
            ],
            "stands: foot mm, tilt deg": [round(foot * 1e3, 2), round(math.degrees(tilt), 2)],
            "run dominoes leaning over 3°": leaning,
        }
        print(f"slot {slot} turn {turn:+.0f}°: {row}", file=sys.stderr)
    return rows


def tilt_of(pose: np.ndarray) -> float:
    """The angle of a domino's length axis from vertical."""
    return math.acos(min(1.0, abs(float(pose[2, 0]))))


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layout", default="s_curve30", choices=LAYOUTS)
    parser.add_argument("--slots", type=int, nargs="+", default=[21, 22, 23])
    default = math.degrees(ArmJobSettings.in_hand_look_turn)
    parser.add_argument("--turns", type=float, nargs="+", default=[0.0, default], help="°")
    parser.add_argument("--pile-yaw", type=float, default=0.3, help="rad")
    args = parser.parse_args()
    scenario = load_scenario()
    world = CellWorld(
        WorldConfig(cameras=True, domino_capacity=len(placements_of(args.layout)) + 1)
    )
    planner = PickPlacePlanner(scenario, PlannerSettings(default_time_budget=3600.0))
    cell = SimCell(world, build_pipeline(scenario), planner)
    rows = {f"slot {slot}": run_slot(cell, args, slot) for slot in args.slots}
    print(json.dumps({"benchmark": "in_hand_second_look", "runs": rows}, indent=1))


if __name__ == "__main__":
    main()

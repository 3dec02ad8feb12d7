"""Benchmark the planner on every slot of the bring-up's 30-domino runs.

For each layout of bench_bringup's 30-domino cases (the same command-line options, parsed
by dombot_bringup.bringup), every slot is planned as the bring-up asks for it: its release
pose (``place_lead`` ahead), the run standing as the build order leaves it (safety gaps
last, ``--section`` 4), a flat domino in the middle of the pile (seeded yaw), the arm at
home. ``--both-neighbours`` also stands the slot's two neighbours (a slot rebuilt late).
The budget is unhurried (3600 s): a verdict never depends on the machine's load, the
planning time does. Prints one JSON object: per layout the slots planned, the refused ones
with their code and reasons, and planning time p50/p95/max.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import sys
import time
from collections import Counter

import numpy as np
from bench_bringup import CASES
from pydrake.math import RigidTransform

from dombot_bringup import bringup, layouts
from dombot_bringup.task.geometry import placement_pose
from dombot_bringup.task.settings import ArmJobSettings
from dombot_description.grasp import flat_pose
from dombot_description.scenario import load_scenario
from dombot_planner.errors import PlanningError
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings

LAYOUTS = ("circle30", "s_curve30", "spiral30")


def build_order(placements: list[layouts.DominoPlacement], section: int) -> list[int]:
    """The bring-up's queue: every slot but the safety gaps in run order, then the gaps."""
    gaps = layouts.safety_gaps(placements, section)
    return [i for i in range(len(placements)) if i not in gaps] + gaps


def run(args: argparse.Namespace) -> dict:
    scenario = load_scenario()
    area = layouts.BuildArea(*scenario.build_x, *scenario.build_y, *scenario.build_reach)
    planner = PickPlacePlanner(scenario, PlannerSettings(default_time_budget=3600.0))
    rng = np.random.default_rng(args.seed)
    lead = ArmJobSettings.place_lead
    result = {"benchmark": "run_slots", "seed": args.seed, "layouts": {}}
    for name in args.layouts:
        placements = bringup.make_layout(bringup.parse_args(CASES[name]), area)
        poses = [RigidTransform(placement_pose(p)) for p in placements]
        order = build_order(placements, ArmJobSettings.section)
        times, refused, codes = [], {}, Counter()
        for position, index in enumerate(order):
            standing = set(order[:position])
            if args.both_neighbours:
                standing |= {i for i in (index - 1, index + 1) if 0 <= i < len(poses)}
            request = PickPlaceRequest(
                flat_pose(*scenario.pile_center, rng.uniform(-math.pi, math.pi)),
                RigidTransform(placement_pose(placements[index], lead)),
                scenario.home_position,
                standing=tuple(poses[i] for i in sorted(standing)),
            )
            began = time.perf_counter()
            try:
                planner.plan(request)
                verdict = "ok"
            except PlanningError as error:
                refused[index + 1] = str(error)
                codes[error.code.name] += 1
                verdict = error.code.name
            times.append(time.perf_counter() - began)
            print(f"{name} slot {index + 1}: {verdict} {times[-1]:.2f} s", file=sys.stderr)
        result["layouts"][name] = {
            "slots": len(order),
            "planned": len(order) - len(refused),
            "refused": refused,
            "codes": dict(codes),
            "planning_time_s": {
                "p50": float(np.percentile(times, 50)),
                "p95": float(np.percentile(times, 95)),
                "max": max(times),
            },
        }
    result["load_average"] = os.getloadavg()
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--layouts", nargs="+", default=list(LAYOUTS), choices=LAYOUTS)
    parser.add_argument("--seed", type=int, default=0, help="seed of the pile dominoes' yaw")
    parser.add_argument("--both-neighbours", action="store_true")
    print(json.dumps(run(parser.parse_args()), indent=2))


if __name__ == "__main__":
    main()

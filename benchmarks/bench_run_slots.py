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
from dataclasses import dataclass
from functools import cache

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


@cache
def placements_of(name: str) -> tuple[layouts.DominoPlacement, ...]:
    """The slots of bench_bringup's case ``name``, as the bring-up lays them out."""
    scenario = load_scenario()
    area = layouts.BuildArea(*scenario.build_x, *scenario.build_y, *scenario.build_reach)
    return tuple(bringup.make_layout(bringup.parse_args(CASES[name]), area))


@dataclass(frozen=True)
class SlotCase:
    """A slot of a layout as the bring-up asks for it (also what
    bench_planner_execution.run_case executes): its release pose, ``place_lead`` ahead,
    with ``neighbours`` (slot numbers, 1-based as the run report's) standing, and a flat
    domino at ``domino`` (x, y, yaw) to carry there."""

    index: int
    layout: str
    slot: int
    neighbours: tuple[int, ...]
    domino: tuple[float, float, float]

    def place_pose(self) -> RigidTransform:
        placement = placements_of(self.layout)[self.slot - 1]
        return RigidTransform(placement_pose(placement, ArmJobSettings.place_lead))

    def standing(self) -> tuple[RigidTransform, ...]:
        run = placements_of(self.layout)
        return tuple(RigidTransform(placement_pose(run[n - 1])) for n in self.neighbours)

    def request(self, start: np.ndarray) -> PickPlaceRequest:
        return PickPlaceRequest(
            flat_pose(*self.domino), self.place_pose(), start, standing=self.standing()
        )


def build_order(placements: tuple[layouts.DominoPlacement, ...], section: int) -> list[int]:
    """The bring-up's queue: every slot but the safety gaps (as laid out, before the planner
    is asked about them: ``task.gaps``) in run order, then the gaps."""
    gaps = [i for gap in layouts.safety_gaps(list(placements), section) for i in gap]
    return [i for i in range(len(placements)) if i not in gaps] + gaps


def run(args: argparse.Namespace) -> dict:
    scenario = load_scenario()
    planner = PickPlacePlanner(scenario, PlannerSettings(default_time_budget=3600.0))
    rng = np.random.default_rng(args.seed)
    result = {"benchmark": "run_slots", "seed": args.seed, "layouts": {}}
    for name in args.layouts:
        order = build_order(placements_of(name), ArmJobSettings.section)
        times, refused, codes = [], {}, Counter()
        for position, index in enumerate(order):
            standing = set(order[:position])
            if args.both_neighbours:
                standing |= {i for i in (index - 1, index + 1) if 0 <= i < len(order)}
            yaw = rng.uniform(-math.pi, math.pi)
            case = SlotCase(
                position,
                name,
                index + 1,
                tuple(i + 1 for i in sorted(standing)),
                (*scenario.pile_center, yaw),
            )
            request = case.request(scenario.home_position)
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

"""Pick dominoes from poured piles and place them into a run, in the Drake simulation.

The arm job's task core (``dombot_bringup.task``: the slot loop, offers, picks, checks)
run in one process through ``dombot_bringup.sim_cell.SimCell``, to measure what the
isolated pairs of bench_planner cannot: picks out of a real pile. For each seeded pile
(poured and settled by dombot_sim), the bring-up's default run (an arc of ``--count`` at
0.6 m about the arm base, from 5°) is built as the bring-up builds it (safety gaps last,
deferrals, sweeps and spreads, the grasp and in-hand checks, perception's placement
check); no strike. Every segment and gripper event is judged as sim_node judges it
(``dombot_sim.goal_monitor``). The figures: how many slots were placed, at which
attempt, why attempts failed (the task's own words, numbers masked), what the planner
refused, planning times, and the placed dominoes' error in the simulator's truth.

Prints one JSON object on stdout (a report per pile; the task's log on stderr).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import re
import sys
import time
from collections import Counter
from contextlib import redirect_stdout
from dataclasses import asdict
from pathlib import Path

import numpy as np
from bench_plan_replay import RecordingPlanner
from bench_planner import log

from dombot_bringup import layouts
from dombot_bringup.run_report import RunReport
from dombot_bringup.sim_cell import SimCell
from dombot_bringup.task.loop import build, place_slot
from dombot_bringup.task.records import record_truth
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_description.scenario import load_scenario
from dombot_perception.pipeline import build_pipeline
from dombot_planner.errors import ErrorCode
from dombot_planner.settings import PlannerSettings
from dombot_sim.world import CellWorld, WorldConfig

RUN = {"center": (0.0, 0.0), "radius": 0.6, "start_angle": math.radians(5.0)}  # bring-up's


def build_pile(cell: SimCell, seed: int, args: argparse.Namespace) -> RunReport:
    """Pour pile ``seed`` and build the run from it with the task core; its report."""
    settings = ArmJobSettings(
        pile=args.pile_size,
        seed=seed,
        max_attempts=args.max_attempts,
        plan_budget=args.budget,
        record_picks=args.record_picks and args.record_picks / f"pile{seed}",
        **({"max_candidates": args.candidates} if args.candidates else {}),
    )
    layout = layouts.arc(RUN["center"], RUN["radius"], RUN["start_angle"], args.count)
    job = Job.new(cell, layout, "arc", settings)
    started = time.monotonic()
    with redirect_stdout(sys.stderr):  # the task's log; stdout is the JSON
        print(cell.reset(settings.pile, seed), flush=True)
        build(job, place_slot)
        record_truth(job, before_strike=True)
    job.report.built = len(job.state.standing) == len(layout)
    job.report.wall_s = time.monotonic() - started
    return job.report


def kind(failure: str) -> str:
    """A failure's words without its figures, to count alike ones together."""
    return re.sub(r"-?\d+(\.\d+)?", "#", failure.split(" (")[0].split(";")[0])


def percentile(values: list[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None


def summarise(reports: list[RunReport], cell: SimCell) -> dict:
    dominoes = [d for report in reports for d in report.dominoes]
    placed = [d for d in dominoes if d.placed]
    first = [d for d in placed if d.attempts == 1 and not d.off_target]
    attempts = sum(d.attempts for d in dominoes)
    places = [p for p in cell.plans if p.kind == "place"]
    planned = [p for p in places if p.error is ErrorCode.SUCCESS]
    times = [p.wall_s for p in places]
    built = [d.truth_built for d in placed if d.truth_built is not None]
    wall = sum(report.wall_s for report in reports)
    return {
        "slots": len(dominoes),
        "placed": len(placed),
        "success_first_attempt": len(first),
        "first_attempt_rate": len(first) / max(1, len(dominoes)),
        "attempts": attempts,
        "outcomes": dict(
            Counter([kind(f) for d in dominoes for f in d.failures] + ["placed"] * len(placed))
        ),
        "deferrals": sum(len(d.deferrals) for d in dominoes),
        "corrected_in_hand": sum(len(d.corrected_in_hand) for d in dominoes),
        "put_back_on_pile": sum(len(d.put_back) for d in dominoes),
        "debris_swept": sum(len(d.sweeps) for d in dominoes),
        "pile_spread": sum(len(d.spreads) for d in dominoes),
        "pile_laid_flat": sum(len(d.laid_flat) for d in dominoes),
        "pile_out_of_reach": sum(len(report.pile_out_of_reach) for report in reports),
        "plan_requests": len(places),
        "refused_candidates": dict(
            Counter(p.error.name for p in places if p.error is not ErrorCode.SUCCESS)
        ),
        "regrasped": sum(p.regrasped for p in planned),
        "nudged": sum(p.nudged for p in planned),
        "planning_s": {
            "p50": percentile(times, 50),
            "p95": percentile(times, 95),
            "max": max(times, default=None),
        },
        "placed_error_max_by_truth": {
            "mm": max((t.error_mm for t in built), default=None),
            "tilt_deg": max((t.tilt_deg for t in built), default=None),
        },
        "wall_s_per_attempt": wall / attempts if attempts else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--piles", type=int, default=4, help="piles (seeds seed..seed+piles-1)")
    parser.add_argument("--seed", type=int, default=0, help="first pile seed")
    parser.add_argument("--pile-size", type=int, default=30, help="dominoes poured per pile")
    parser.add_argument("--count", type=int, default=10, help="dominoes in each run")
    parser.add_argument("--max-attempts", type=int, default=4, help="per slot (bring-up's 4)")
    parser.add_argument(
        "--candidates",
        type=int,
        default=0,
        help="pile detections offered per attempt with their pile (0: the bring-up's 16)",
    )
    parser.add_argument("--budget", type=float, default=5.0, help="planning budget [s]")
    parser.add_argument("--settings", help="JSON object of PlannerSettings overrides")
    parser.add_argument(
        "--record-picks",
        type=Path,
        help="folder for each executed pick's record (benchmarks/replay_pick.py replays it)",
    )
    parser.add_argument(
        "--record-requests",
        type=Path,
        help=".npz file for every /plan_place request (benchmarks/bench_plan_replay.py)",
    )
    args = parser.parse_args()
    load_before = os.getloadavg()
    scenario = load_scenario()
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=args.pile_size), scenario)
    settings = PlannerSettings(**json.loads(args.settings or "{}"))
    planner = RecordingPlanner(scenario, settings, path=args.record_requests)
    cell = SimCell(world, build_pipeline(scenario), planner)
    reports = []
    for seed in range(args.seed, args.seed + args.piles):
        reports.append(build_pile(cell, seed, args))
        log(f"pile {seed}: {json.dumps(reports[-1].summary())}")
    result = {
        "benchmark": "pile_picks",
        "piles": args.piles,
        "pile_size": args.pile_size,
        "run_length": args.count,
        "candidates_per_attempt": args.candidates or ArmJobSettings().max_candidates,
        **summarise(reports, cell),
        "reports": [
            {
                "seed": r.seed,
                "built": r.built,
                "dominoes": [asdict(d) for d in r.dominoes],
                "pile_out_of_reach": [asdict(d) for d in r.pile_out_of_reach],
            }
            for r in reports
        ],
        "load_average": {"before": load_before, "after": os.getloadavg()},
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

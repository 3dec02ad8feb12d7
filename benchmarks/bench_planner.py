"""Benchmark /plan_place's planner on a fixed, seeded set of pick/place pairs.

Pairs: a flat domino with random yaw anywhere in the pile disc; an upright placement
anywhere in the build area (box ∩ reach annulus of the scenario) with a random run
heading, 80 % standing on the table (the lowest legal height) and 20 % on a 10–40 mm
step (not modelled: only the height changes); neighbours already standing 60 % of the
domino height away along the run on both sides (half of the pairs), behind only (a
quarter) or none. Every other request starts where the previous plan ended (a run built
in sequence), the others at the scenario's home position.

Every plan is checked by dombot_planner.verify (a separate plant, dense samples). Prints
one JSON object on stdout: success rate and failures by code, planning time p50/p95/max,
minimum clearances per phase, final pose errors, joint limit use, and trajectory duration
against the time-optimal duration of the same path (TOPP-RA on a 10× finer grid).
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import sys
import time
from collections import Counter

import numpy as np

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import flat_pose, upright_pose
from dombot_description.scenario import Scenario, load_scenario
from dombot_planner.errors import PlanningError
from dombot_planner.planner import PickPlacePlanner, Plan
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings
from dombot_planner.timing import retime
from dombot_planner.verify import TrajectoryChecker

SPACING_RATIO = 0.6
RAISED_FRACTION = 0.2
STEP_HEIGHT = (0.010, 0.040)  # m
OPTIMAL_GRID_FACTOR = 10


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@dataclasses.dataclass(frozen=True)
class Case:
    index: int
    domino: tuple[float, float, float]  # x, y, yaw
    place: tuple[float, float, float, float]  # x, y, heading, base height
    neighbours: tuple[int, ...]  # -1 behind, +1 ahead (along the run heading)

    def place_pose(self):
        x, y, heading, base = self.place
        return upright_pose(x, y, heading, base)

    def standing(self):
        x, y, heading, base = self.place
        step = SPACING_RATIO * DOMINO_SIZE[0] * np.array([math.cos(heading), math.sin(heading)])
        return tuple(
            upright_pose(x + s * step[0], y + s * step[1], heading, base) for s in self.neighbours
        )


def make_cases(scenario: Scenario, count: int, seed: int) -> list[Case]:
    rng = np.random.default_rng(seed)
    cases = []
    for index in range(count):
        radius, angle = scenario.pile_radius * math.sqrt(rng.uniform()), rng.uniform(0, 2 * math.pi)
        domino = (
            scenario.pile_center[0] + radius * math.cos(angle),
            scenario.pile_center[1] + radius * math.sin(angle),
            rng.uniform(-math.pi, math.pi),
        )
        while True:
            x, y = rng.uniform(*scenario.build_x), rng.uniform(*scenario.build_y)
            if scenario.build_reach[0] <= math.hypot(x, y) <= scenario.build_reach[1]:
                break
        base = rng.uniform(*STEP_HEIGHT) if rng.uniform() < RAISED_FRACTION else 0.0
        neighbours = [(-1, 1), (-1, 1), (-1,), ()][index % 4]
        cases.append(Case(index, domino, (x, y, rng.uniform(-math.pi, math.pi), base), neighbours))
    return cases


def optimal_duration(plan: Plan, planner: PickPlacePlanner) -> float:
    """Sum over pieces of the TOPP-RA duration on a finer grid (same path, same limits)."""
    total = 0.0
    plant = planner.plants.get(DOMINO_SIZE[1]).plant
    tcp = plant.GetFrameByName(planner.scenario.tcp_frame)
    for segment in plan.segments:
        for piece in segment.pieces:
            grid = OPTIMAL_GRID_FACTOR * (100 if not piece.fine else 40)
            fine = retime(
                piece.label,
                piece.path,
                plant,
                planner.limits,
                fine=piece.fine,
                tcp=tcp if piece.fine else None,
                tcp_speed=planner.settings.approach_speed if piece.fine else None,
                grid_points=grid,
            )
            total += fine.duration if fine is not None else math.nan
    return total


def percentile(values: list[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None


def run(args: argparse.Namespace) -> dict:
    scenario = load_scenario()
    overrides = json.loads(args.settings) if args.settings else {}
    settings = PlannerSettings(**overrides)
    planner = PickPlacePlanner(scenario, settings)
    cases = make_cases(scenario, args.count, args.seed)
    times, failures, rows = [], Counter(), []
    previous_end = None
    load_before = os.getloadavg()
    for case in cases:
        start = (
            previous_end
            if case.index % 2 and previous_end is not None
            else (scenario.home_position)
        )
        domino = flat_pose(*case.domino)
        request = PickPlaceRequest(
            domino,
            case.place_pose(),
            start,
            standing=case.standing(),
            time_budget=args.time_budget,
        )
        began = time.perf_counter()
        try:
            plan = planner.plan(request)
        except PlanningError as error:
            elapsed = time.perf_counter() - began
            times.append(elapsed)
            failures[error.code.name] += 1
            previous_end = None
            log(f"{case.index:3d} FAIL {elapsed:.2f} s {error.code.name}: {error}")
            continue
        elapsed = time.perf_counter() - began
        times.append(elapsed)
        checker = TrajectoryChecker(
            scenario,
            domino,
            request.place_pose,
            request.standing,
            settings.acceleration_limit,
            DOMINO_SIZE[1],
        )
        check = checker.check(
            plan.sampled(settings.sample_period),
            start,
            (settings.pick_approach_distance, settings.place_approach_distance),
        )
        duration = sum(segment.duration for segment in plan.segments)
        optimal = optimal_duration(plan, planner) if args.optimal else math.nan
        check.regrasped = plan.regrasped
        rows.append((case, elapsed, check, duration, optimal))
        previous_end = plan.segments[-1].pieces[-1].sample(np.array([1e9]))[0][0]
        log(
            f"{case.index:3d} ok   {elapsed:.2f} s  coarse "
            f"{coarse_min(check) * 1000:5.1f} mm  duration {duration:.2f} s"
        )
    return summarise(args, settings, cases, times, failures, rows, load_before)


def coarse_min(check) -> float:
    return min(
        (
            v
            for (phase, _, other), v in check.clearance.items()
            if phase == "coarse" and other != "self"
        ),
        default=math.inf,
    )


def clearance_summary(rows, phase: str) -> dict[str, float]:
    result: dict[str, float] = {}
    for _, _, check, _, _ in rows:
        for (p, moving, other), value in check.clearance.items():
            if p == phase:
                key = f"{moving}-{other}"
                result[key] = min(result.get(key, math.inf), value)
    return {key: round(value * 1000, 3) for key, value in sorted(result.items())}


def pose_error_summary(errors: list[tuple[float, float]]) -> dict[str, float]:
    return {
        "mm": max((e[0] for e in errors), default=0.0) * 1000,
        "deg": math.degrees(max((e[1] for e in errors), default=0.0)),
    }


def summarise(args, settings, cases, times, failures, rows, load_before) -> dict:
    successes = len(rows)
    ratios = [d / o for *_, d, o in rows if math.isfinite(o) and o > 0]
    return {
        "benchmark": "planner",
        "pairs": len(cases),
        "seed": args.seed,
        "success_rate": successes / len(cases),
        "failures": dict(failures),
        "regrasped": sum(1 for _, _, c, _, _ in rows if c.regrasped),
        "planning_time_s": {
            "p50": percentile(times, 50),
            "p95": percentile(times, 95),
            "max": max(times) if times else None,
        },
        "min_clearance_mm": {
            "coarse_moves": clearance_summary(rows, "coarse"),
            "final_approach_and_retreat": clearance_summary(rows, "fine"),
        },
        "grasp_error_max": pose_error_summary([c.grasp_error for _, _, c, _, _ in rows]),
        "place_error_max": {
            **pose_error_summary([c.place_error for _, _, c, _, _ in rows]),
            "note": f"includes the {settings.release_height * 1000} mm release height",
        },
        "joint_limits": {
            "position_excess_rad": max(
                (c.position_limit_excess for _, _, c, _, _ in rows), default=None
            ),
            "velocity_use_max": max((c.velocity_use for _, _, c, _, _ in rows), default=None),
            "acceleration_use_max": max(
                (c.acceleration_use for _, _, c, _, _ in rows), default=None
            ),
            "largest_jump_rad": max((c.largest_jump for _, _, c, _, _ in rows), default=None),
        },
        "trajectory_duration_s": {
            "p50": percentile([d for *_, d, _ in rows], 50),
            "max": max((d for *_, d, _ in rows), default=None),
        },
        "duration_over_time_optimal": {
            "p50": percentile(ratios, 50),
            "max": max(ratios, default=None),
        },
        "settings": dataclasses.asdict(settings),
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
        "cpu_count": os.cpu_count(),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--count", type=int, default=200, help="pick/place pairs")
    parser.add_argument("--seed", type=int, default=2026, help="seed of the pair set")
    parser.add_argument("--time-budget", type=float, default=0.0, help="s; 0: default")
    parser.add_argument("--settings", help="JSON object of PlannerSettings overrides")
    parser.add_argument(
        "--no-optimal",
        dest="optimal",
        action="store_false",
        help="skip the time-optimal duration comparison",
    )
    print(json.dumps(run(parser.parse_args()), indent=2))


if __name__ == "__main__":
    main()

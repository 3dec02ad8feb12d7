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
from dombot_description.grasp import (
    OrientedBox,
    domino_in_tcp,
    flat_pose,
    gripper_geometry,
    pick_grasps,
    place_grasps,
    upright_pose,
)
from dombot_description.scenario import Scenario, load_scenario
from dombot_planner.errors import PlanningError
from dombot_planner.pick_place_plan import PickPlacePlan
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings
from dombot_planner.timing import retime
from dombot_planner.verify import Check, TrajectoryChecker

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

    @property
    def on_table(self) -> bool:
        return self.place[3] == 0.0

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


@dataclasses.dataclass
class Row:
    case: Case
    planning_time: float
    plan: PickPlacePlan
    check: Check
    duration: float  # s of motion
    optimal: float  # s, the same path's time-optimal duration


def optimal_duration(plan: PickPlacePlan, planner: PickPlacePlanner) -> float:
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
            free_acceleration=settings.free_acceleration_limits,
        )
        check = checker.check(
            plan.sampled(settings.sample_period),
            start,
            (settings.pick_approach_distance, settings.place_approach_distance),
        )
        duration = sum(segment.duration for segment in plan.segments)
        optimal = optimal_duration(plan, planner) if args.optimal else math.nan
        rows.append(Row(case, elapsed, plan, check, duration, optimal))
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


def clearance_summary(checks: list[Check], phase: str) -> dict[str, float]:
    result: dict[str, float] = {}
    for check in checks:
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
    ratios = [r.duration / r.optimal for r in rows if math.isfinite(r.optimal) and r.optimal > 0]
    checks = [row.check for row in rows]
    return {
        "benchmark": "planner",
        "pairs": len(cases),
        "seed": args.seed,
        "success_rate": successes / len(cases),
        "failures": dict(failures),
        "regrasped": sum(1 for row in rows if row.plan.regrasped),
        "kto_attempts": dict(
            sorted(Counter(a for row in rows for a in row.plan.kto_attempts.values()).items())
        ),
        "planning_time_s": {
            "p50": percentile(times, 50),
            "p95": percentile(times, 95),
            "max": max(times) if times else None,
        },
        "min_clearance_mm": {
            "coarse_moves": clearance_summary(checks, "coarse"),
            "final_approach_and_retreat": clearance_summary(checks, "fine"),
            "escape_from_start": clearance_summary(checks, "escape"),
        },
        "grasp_error_max": pose_error_summary([c.grasp_error for c in checks]),
        "place_error_max": {
            **pose_error_summary([c.place_error for c in checks]),
            "note": f"includes the {settings.release_height * 1000} mm release height",
        },
        "joint_limits": {
            "position_excess_rad": max((c.position_limit_excess for c in checks), default=None),
            "velocity_use_max": max((c.velocity_use for c in checks), default=None),
            "acceleration_use_max": max((c.acceleration_use for c in checks), default=None),
            "largest_jump_rad": max((c.largest_jump for c in checks), default=None),
        },
        "trajectory_duration_s": {
            "p50": percentile([r.duration for r in rows], 50),
            "max": max((r.duration for r in rows), default=None),
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


def draw(axis, box: OrientedBox, **style) -> None:
    """A box's outline seen along world y (x–z plane, mm) on a matplotlib axis."""
    from matplotlib.patches import Polygon
    from scipy.spatial import ConvexHull

    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
    corners = (box.pose @ (signs * box.size / 2).T).T[:, [0, 2]] * 1000
    axis.add_patch(Polygon(corners[ConvexHull(corners).vertices], closed=True, **style))


def write_grasp_figure(path: str) -> None:
    """Side views of the canonical grasp at pick and at place between two neighbours."""
    import matplotlib.pyplot as plt

    def domino_box(pose):
        return OrientedBox(pose, np.array(DOMINO_SIZE))

    figure, axes = plt.subplots(1, 2, figsize=(11, 4.8))
    flat = flat_pose(0.0, 0.0, 0.0)
    pick = pick_grasps(flat)[0]
    upright = upright_pose(0.0, 0.0, 0.0)
    held_in_tcp = domino_in_tcp(pick.pose, flat)
    place = place_grasps(upright, held_in_tcp)[0]
    step = SPACING_RATIO * DOMINO_SIZE[0]
    neighbours = [upright_pose(s * step, 0.0, 0.0) for s in (-1, 1)]
    views = [
        (
            axes[0],
            pick.pose,
            pick.pregrasp_opening,
            [flat],
            "pick: flat, gripper 63° from vertical",
        ),
        (
            axes[1],
            place,
            pick.closed_opening,
            [upright, *neighbours],
            "place: between neighbours 28.8 mm away, 27°",
        ),
    ]
    gripper = gripper_geometry()
    for axis, tcp, opening, dominoes, title in views:
        body = gripper.body_box_in_tcp()
        draw(axis, OrientedBox(tcp @ body.pose, body.size), color="0.3", alpha=0.8)
        for pad in gripper.pad_boxes_in_tcp(opening):
            draw(axis, OrientedBox(tcp @ pad.pose, pad.size), color="tab:blue", alpha=0.6)
        for index, pose in enumerate(dominoes):
            colour = "tab:orange" if index == 0 else "wheat"
            draw(axis, domino_box(pose), color=colour, ec="k", lw=0.8)
        axis.axhline(0.0, color="saddlebrown", lw=3)
        x, _, z = tcp.translation() * 1000
        axis.plot(x, z, "r+", ms=12, mew=2)
        axis.set(title=title, xlabel="world x [mm]", ylabel="world z [mm]", aspect="equal")
        axis.set_xlim(*((-170, 50) if axis is axes[0] else (-60, 160)))
        axis.set_ylim(-5, 170)
        axis.grid(alpha=0.3)
    figure.suptitle("dombot_description.grasp: pads (blue), gripper body (grey), TCP (+)")
    figure.tight_layout()
    figure.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--count", type=int, default=200, help="pick/place pairs")
    parser.add_argument("--seed", type=int, default=2026, help="seed of the pair set")
    parser.add_argument("--time-budget", type=float, default=0.0, help="s; 0: default")
    parser.add_argument("--settings", help="JSON object of PlannerSettings overrides")
    parser.add_argument("--figure", help="also write docs/PLANNER_GRASPS.md's grasp figure here")
    parser.add_argument(
        "--no-optimal",
        dest="optimal",
        action="store_false",
        help="skip the time-optimal duration comparison",
    )
    args = parser.parse_args()
    if args.figure:
        write_grasp_figure(args.figure)
    print(json.dumps(run(args), indent=2))


if __name__ == "__main__":
    main()

"""Benchmark /plan_strike's planner on a seeded set of domino runs, optionally executed.

Runs: 3–5 upright dominoes in a straight line at 60 % of the domino height, the whole
run inside the scenario's build area (box ∩ reach annulus), its first domino anywhere
there, the heading random. Every other request starts where the previous plan ended
(fingers closed), the others at the home position with the fingers open as a place
leaves them (so the plan closes them first).

Every plan is checked by dombot_planner.verify.StrikeChecker (a separate plant, dense
samples): clearances per segment, fingertip height at the push, travel past first
contact and the speed there, joint limit use. ``--execute N`` then runs the first N plans
in the Drake simulation (dombot_sim.world.CellWorld, as bench_planner_execution does):
how far any domino moved before the push began, and every domino's tilt from vertical
3 s after the retreat (fallen: > 45°). ``--sweeps N`` also plans and executes N sweeps
(/plan_strike with a sweep direction) of a domino fallen flat across a run between two
standing neighbours, 13 mm off the run's line to alternate sides and turned up to 24°
from square (as a cascade left one in S-curve seed 2), pushed by the bring-up's own
choice (``dombot_bringup.debris``): where the swept domino ends, and how far the
neighbours moved and tilted. Prints one JSON object on stdout.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import os
import time
from collections import Counter

import numpy as np
from bench_planner import clearance_summary, draw, log, percentile
from bench_planner_execution import gripper_event, plan_force, track
from pydrake.math import RigidTransform

from dombot_bringup.debris import sweep_pushes
from dombot_bringup.layouts import DOMINO_WIDTH, DominoPlacement
from dombot_description import DOMINO_SIZE, domino_corners, tilt_from_vertical
from dombot_description.grasp import (
    OrientedBox,
    flat_pose,
    gripper_geometry,
    release_opening,
    upright_pose,
)
from dombot_description.pusher import PUSHER_STANDOFF
from dombot_description.scenario import Scenario, load_scenario
from dombot_planner.errors import PlanningError
from dombot_planner.request import StrikeRequest
from dombot_planner.settings import PlannerSettings
from dombot_planner.strike import CLOSED, StrikePlan, StrikePlanner, pusher_rotations, strike_pose
from dombot_planner.verify import StrikeCheck, StrikeChecker
from dombot_sim.world import CellWorld, WorldConfig

SPACING_RATIO = 0.6
SWEEP_MARGIN = 0.008  # m beyond the run's side, as the bring-up asks
DEBRIS_OFFSET = 0.013  # m off the run's line
RUN_LENGTHS = (3, 4, 5)
TOPPLE_WAIT = 3.0  # s simulated after the retreat, as the bring-up waits
FALLEN = math.radians(45.0)


@dataclasses.dataclass(frozen=True)
class Run:
    index: int
    start: tuple[float, float]  # first domino x, y
    heading: float  # rad, the direction the run topples
    count: int

    def poses(self) -> list:
        step = SPACING_RATIO * DOMINO_SIZE[0]
        direction = np.array([math.cos(self.heading), math.sin(self.heading)])
        return [
            upright_pose(*(np.array(self.start) + i * step * direction), self.heading)
            for i in range(self.count)
        ]


def inside_build_area(scenario: Scenario, x: float, y: float) -> bool:
    (x0, x1), (y0, y1), (r0, r1) = scenario.build_x, scenario.build_y, scenario.build_reach
    return x0 <= x <= x1 and y0 <= y <= y1 and r0 <= math.hypot(x, y) <= r1


def make_runs(scenario: Scenario, count: int, seed: int) -> list[Run]:
    rng = np.random.default_rng(seed)
    runs = []
    while len(runs) < count:
        run = Run(
            len(runs),
            (rng.uniform(*scenario.build_x), rng.uniform(*scenario.build_y)),
            rng.uniform(-math.pi, math.pi),
            RUN_LENGTHS[len(runs) % len(RUN_LENGTHS)],
        )
        if all(inside_build_area(scenario, *p.translation()[:2]) for p in run.poses()):
            runs.append(run)
    return runs


def execute(world: CellWorld, run: Run, planner: StrikePlanner, request: StrikeRequest) -> dict:
    """Plan from the simulated arm, run the segments, wait TOPPLE_WAIT s, measure."""
    poses = run.poses()
    world.reset(domino_count=0, seed=run.index)
    world.set_domino_poses(dict(enumerate(poses)))
    world.settle(1.0)
    before = [d.X_WD for d in world.domino_truth()[: run.count]]
    joints = world.joint_state().position
    request = dataclasses.replace(
        request, start=joints[:7], finger_opening=float(joints[7] + joints[8])
    )
    plan = planner.plan(request)
    began = time.perf_counter()
    moved = tilted = math.nan
    for segment in plan.sampled(planner.settings.sample_period):
        if segment.label == "push":
            now = [d.X_WD for d in world.domino_truth()[: run.count]]
            moved = max(
                np.linalg.norm(a[:3, 3] - b[:3, 3]) for a, b in zip(now, before, strict=True)
            )
            tilted = max(
                abs(tilt_from_vertical(a) - tilt_from_vertical(b))
                for a, b in zip(now, before, strict=True)
            )
        track(world, segment)
        gripper_event(world, segment, plan_force(plan, segment.label))
    world.advance(TOPPLE_WAIT)
    tilts = [math.degrees(tilt_from_vertical(d.X_WD)) for d in world.domino_truth()[: run.count]]
    return {
        "pusher_lean_deg": pusher_lean(plan),
        "moved_before_push_mm": moved * 1000,
        "tilted_before_push_deg": math.degrees(tilted),
        "tilts_deg": [round(t, 1) for t in tilts],
        "all_fallen": all(t > math.degrees(FALLEN) for t in tilts),
        "wall_s": time.perf_counter() - began,
    }


def sweep_case(world: CellWorld, run: Run, planner: StrikePlanner) -> dict:
    """Domino 2 of ``run`` fallen flat across it: swept clear of the run's side?"""
    poses = run.poses()
    slot = poses[1].translation()
    across = np.array([-math.sin(run.heading), math.cos(run.heading), 0.0])
    side = 1.0 if run.index % 2 == 0 else -1.0
    centre = slot + side * DEBRIS_OFFSET * across
    neighbours = [poses[0], poses[2]]
    yaw = run.heading + math.pi / 2 + side * math.radians(8.0 * (run.index % 4))
    world.reset(domino_count=0, seed=run.index)
    world.set_domino_poses({0: flat_pose(*centre[:2], yaw), 1: neighbours[0], 2: neighbours[1]})
    world.settle(1.0)
    truth = [d.X_WD for d in world.domino_truth()[:3]]
    placement = DominoPlacement(1, *slot[:2], run.heading)
    direction, distance = sweep_pushes(truth[0], placement, SWEEP_MARGIN)[0]
    joints = world.joint_state().position
    request = StrikeRequest(
        RigidTransform(truth[0]),
        joints[:7],
        float(joints[7] + joints[8]),
        tuple(RigidTransform(pose) for pose in truth[1:]),
        push_distance=distance,
        sweep=direction,
    )
    began = time.perf_counter()
    try:
        plan = planner.plan(request)
    except PlanningError as error:
        return {"run": run.index, "planned": False, "why": str(error)}
    for segment in plan.sampled(planner.settings.sample_period):
        track(world, segment)
        gripper_event(world, segment, plan_force(plan, segment.label))
    world.advance(TOPPLE_WAIT)
    after = [d.X_WD for d in world.domino_truth()[:3]]
    moved = [float(np.linalg.norm(a[:3, 3] - b[:3, 3])) for a, b in zip(after, truth, strict=True)]
    # the swept domino's nearest corner to the run's line, beyond its side (>0: clear)
    offsets = (domino_corners(after[0]) - slot) @ across
    clear = np.min(np.abs(offsets)) - DOMINO_WIDTH / 2
    crossed = np.sign(offsets)
    return {
        "run": run.index,
        "planned": True,
        "push_mm": round(distance * 1000, 1),
        "beyond_side_mm": round(float(clear) * 1000 if len(set(crossed)) == 1 else -1.0, 1),
        "neighbours_moved_mm": round(max(moved[1:]) * 1000, 2),
        "neighbours_tilt_deg": round(
            math.degrees(max(tilt_from_vertical(a) for a in after[1:])), 2
        ),
        "wall_s": round(time.perf_counter() - began, 1),
    }


def pusher_lean(plan: StrikePlan) -> float:
    """Degrees between the fingers and straight down at the strike pose."""
    approach = plan.strike_pose.rotation().matrix()[:, 2]
    return round(math.degrees(math.acos(-approach[2])), 1)


def check_plan(scenario, settings, run: Run, request: StrikeRequest, plan: StrikePlan):
    poses = run.poses()
    checker = StrikeChecker(scenario, poses[0], poses[1:], settings.acceleration_limit)
    opening = request.finger_opening
    return checker.check(
        plan.sampled(settings.sample_period),
        request.start,
        opening if opening is not None else release_opening(DOMINO_SIZE[1]),
    )


def phase_clearances(checks: list[StrikeCheck]) -> dict:
    return {phase: clearance_summary(checks, phase) for phase in ("approach", "push", "retreat")}


def summary(values: list[float], scale: float = 1.0) -> dict:
    finite = [v * scale for v in values if math.isfinite(v)]
    return {"min": min(finite, default=None), "max": max(finite, default=None)}


def write_strike_figure(path: str, settings: PlannerSettings) -> None:
    """Side view of a run and the closed gripper at the top of the descent, the strike pose
    and the end of the push (the planner's own geometry, no arm)."""
    import matplotlib.pyplot as plt

    run = Run(0, (0.0, 0.0), 0.0, 3).poses()
    along = run[0].rotation().matrix()[:, 2]  # upright: body z is horizontal
    start = strike_pose(
        run[0],
        pusher_rotations(along)[0],
        along,
        settings.strike_height,
        PUSHER_STANDOFF,
    )
    push = PUSHER_STANDOFF + settings.push_distance
    gripper = gripper_geometry()
    figure, axis = plt.subplots(figsize=(7, 6))
    for shift, alpha in (
        ((0.0, 0.0, settings.strike_approach_height), 0.2),
        ((0.0, 0.0, 0.0), 0.8),
        ((push, 0.0, 0.0), 0.4),
    ):
        tcp = RigidTransform(np.array(shift)) @ start
        body = gripper.body_box_in_tcp()
        draw(axis, OrientedBox(tcp @ body.pose, body.size), color="0.3", alpha=alpha)
        for pad in gripper.pad_boxes_in_tcp(CLOSED):
            draw(axis, OrientedBox(tcp @ pad.pose, pad.size), color="tab:blue", alpha=alpha)
    for index, pose in enumerate(run):
        colour = "tab:orange" if index == 0 else "wheat"
        draw(axis, OrientedBox(pose, np.array(DOMINO_SIZE)), color=colour, ec="k", lw=0.8)
    axis.axhline(0.0, color="saddlebrown", lw=3)
    axis.axhline(settings.strike_height * DOMINO_SIZE[0] * 1000, color="tab:red", lw=0.6, ls=":")
    axis.annotate(
        "",
        xy=(push * 1000 - 20, 40),
        xytext=(-20, 40),
        arrowprops={"arrowstyle": "->", "color": "tab:red"},
    )
    axis.set(
        title="strike: descent top (faint), strike pose, push end (dominoes where they stood)",
        xlabel="along the run [mm]",
        ylabel="height [mm]",
        aspect="equal",
    )
    axis.set_xlim(-60, 90)
    axis.set_ylim(-5, 215)
    axis.grid(alpha=0.3)
    figure.tight_layout()
    figure.savefig(path, dpi=120)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--count", type=int, default=100, help="runs to plan")
    parser.add_argument("--seed", type=int, default=2026, help="seed of the run set")
    parser.add_argument("--execute", type=int, default=0, help="execute the first N runs")
    parser.add_argument("--sweeps", type=int, default=0, help="sweep debris in the first N runs")
    parser.add_argument("--push-distance", type=float, default=0.0, help="m; 0: default")
    parser.add_argument("--push-speed", type=float, default=0.0, help="m/s; 0: default")
    parser.add_argument("--time-budget", type=float, default=0.0, help="s; 0: default")
    parser.add_argument("--settings", help="JSON object of PlannerSettings overrides")
    parser.add_argument("--figure", help="also write the strike figure of docs/STRIKE.md here")
    args = parser.parse_args()
    scenario = load_scenario()
    settings = PlannerSettings(**json.loads(args.settings or "{}"))
    if args.figure:
        write_strike_figure(args.figure, settings)
    planner = StrikePlanner(scenario, settings)
    load_before = os.getloadavg()
    times, failures, checks, durations, leans, executed = [], Counter(), [], [], [], []
    previous_end = None
    world = None
    for run in make_runs(scenario, args.count, args.seed):
        poses = run.poses()
        if run.index % 2 and previous_end is not None:
            start, opening = previous_end, 0.0
        else:
            start, opening = scenario.home_position, release_opening(DOMINO_SIZE[1])
        request = StrikeRequest(
            poses[0],
            start,
            opening,
            tuple(poses[1:]),
            args.push_distance,
            args.push_speed,
            args.time_budget,
        )
        began = time.perf_counter()
        try:
            plan = planner.plan(request)
        except PlanningError as error:
            times.append(time.perf_counter() - began)
            failures[error.code.name] += 1
            previous_end = None
            log(f"{run.index:3d} FAIL {times[-1]:.2f} s {error}")
            continue
        times.append(time.perf_counter() - began)
        previous_end = plan.final_positions()
        checks.append(check_plan(scenario, settings, run, request, plan))
        durations.append(sum(s.duration for s in plan.segments))
        leans.append(pusher_lean(plan))
        row = {"run": dataclasses.asdict(run), "planning_s": round(times[-1], 3)}
        if run.index < args.execute:
            if world is None:
                world = CellWorld(WorldConfig(cameras=False, domino_capacity=5), scenario)
            row.update(execute(world, run, planner, request))
            executed.append(row)
        log(json.dumps(row))
    swept = []
    for run in make_runs(scenario, args.count, args.seed)[: args.sweeps]:
        if world is None:
            world = CellWorld(WorldConfig(cameras=False, domino_capacity=5), scenario)
        swept.append(sweep_case(world, run, planner))
        log(json.dumps(swept[-1]))
    result = {
        "benchmark": "strike",
        "runs": args.count,
        "seed": args.seed,
        "success_rate": len(checks) / args.count if args.count else None,
        "failures": dict(failures),
        "planning_time_s": {
            "p50": percentile(times, 50),
            "p95": percentile(times, 95),
            "max": max(times, default=None),
        },
        "min_clearance_mm": phase_clearances(checks),
        "with_leaning_pusher": sum(lean > 1.0 for lean in leans),
        "fingertip_height_mm": summary([c.fingertip_height for c in checks], 1000),
        "push_past_contact_mm": summary([c.push_past_contact for c in checks], 1000),
        "contact_speed_m_s": summary([c.contact_speed for c in checks]),
        "joint_limits": {
            "position_excess_rad": max((c.position_limit_excess for c in checks), default=None),
            "velocity_use_max": max((c.velocity_use for c in checks), default=None),
            "acceleration_use_max": max((c.acceleration_use for c in checks), default=None),
            "largest_jump_rad": max((c.largest_jump for c in checks), default=None),
        },
        "trajectory_duration_s": {
            "p50": percentile(durations, 50),
            "max": max(durations, default=None),
        },
        "executed": {
            "runs": len(executed),
            "all_fallen": sum(r["all_fallen"] for r in executed),
            "moved_before_push_mm_max": max(
                (r["moved_before_push_mm"] for r in executed), default=None
            ),
            "tilted_before_push_deg_max": max(
                (r["tilted_before_push_deg"] for r in executed), default=None
            ),
            "wall_s_per_run": percentile([r["wall_s"] for r in executed], 50),
            "with_leaning_pusher": sum(r["pusher_lean_deg"] > 1.0 for r in executed),
            "rows": executed,
        },
        "sweeps": {
            "runs": len(swept),
            "planned": sum(r["planned"] for r in swept),
            "cleared": sum(r.get("beyond_side_mm", -1.0) > 0.0 for r in swept),
            "neighbours_moved_mm_max": max(
                (r["neighbours_moved_mm"] for r in swept if r["planned"]), default=None
            ),
            "neighbours_tilt_deg_max": max(
                (r["neighbours_tilt_deg"] for r in swept if r["planned"]), default=None
            ),
            "rows": swept,
        },
        "settings": dataclasses.asdict(settings),
        "push_distance": args.push_distance or settings.push_distance,
        "push_speed": args.push_speed or settings.push_speed,
        "load_average_before": load_before,
        "load_average_after": os.getloadavg(),
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

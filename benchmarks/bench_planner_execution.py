"""Execute planned pick-and-places in the Drake simulation (dombot_sim) and measure them.

Pairs come from bench_planner's seeded set, those standing on the table (the simulation
has no step for the raised ones). For each: the pick domino and its standing
neighbours are put in the simulated cell, the plan is made from the arm's simulated joint
state, and every segment is tracked by the simulated arm (a cubic Hermite spline through
the published samples, as a robot driver would interpolate), followed by its gripper
event. Measured: the held domino against the place pose just before release (≤ 1 mm,
≤ 0.5° wanted) and how far it slipped in the hand on the way there (its hold in the TCP
against the plan's), where it stands once everything has settled (≤ 2 mm, ≤ 2°), and
how far the standing neighbours moved. The simulation runs in simulated time, unpaced,
and a found plan does not depend on the time it took: the figures repeat bit for bit on
a machine (the planner's time budget only decides whether a pair is planned). Prints one
JSON object on stdout (progress on stderr). ``--slots`` executes slots of the bring-up's
30-domino layouts instead (bench_run_slots.SlotCase: its release pose, the slots given
standing, a flat domino from the pile's middle).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time

import numpy as np
from bench_planner import log, make_cases
from bench_run_slots import SlotCase
from pydrake.math import RigidTransform
from pydrake.trajectories import PiecewisePolynomial

from dombot_bringup.task.placing import OPEN_SEGMENT
from dombot_bringup.task.settings import ArmJobSettings
from dombot_description.grasp import SYMMETRIES, flat_pose
from dombot_description.scenario import load_scenario
from dombot_planner.errors import PlanningError
from dombot_planner.plan_segments import GRIPPER_CLOSE, GRIPPER_OPEN, SampledSegment
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings
from dombot_planner.verify import nearest_error
from dombot_sim.goal_monitor import GripperMonitor
from dombot_sim.world import CellWorld, WorldConfig

TRACKING_SETTLE = 0.1  # s held at the end of each segment before the gripper event
GRIPPER_STEP = 0.01  # s simulated between looks at the fingers
FINAL_SETTLE = 2.0  # s limit for the dominoes to come to rest at the end
PICKED = 0
OPEN_WHILE_MOVING = ArmJobSettings().open_while_moving


def domino_pose(world: CellWorld, index: int) -> RigidTransform:
    return RigidTransform(world.domino_truth()[index].X_WD)


def place_error(pose: RigidTransform, place: RigidTransform) -> tuple[float, float]:
    return nearest_error(pose, [place @ RigidTransform(s) for s in SYMMETRIES])


def track(world: CellWorld, segment: SampledSegment) -> None:
    """Follow a segment's samples (cubic Hermite, as a driver interpolates), then settle."""
    if len(segment.times) > 1:
        spline = PiecewisePolynomial.CubicHermite(
            segment.times, segment.positions.T, segment.velocities.T
        )
        world.advance_to(world.follow_trajectory(spline) + TRACKING_SETTLE)


def gripper_event(world: CellWorld, segment: SampledSegment, force: float) -> bool:
    """Command the segment's gripper event, if any, and wait for it; True if there was one."""
    if segment.gripper_after not in (GRIPPER_OPEN, GRIPPER_CLOSE):
        return False
    world.command_gripper(segment.gripper_position, force)
    wait_for_gripper(world)
    return True


def execute(world: CellWorld, plan, period: float) -> dict:
    """Run every segment and gripper event; the held domino and its hold in the TCP just
    before release. The fingers open for a grasp as the bring-up opens them
    (``placing.opens_while_moving``): while the approach moves when they stand within
    ``open_while_moving`` of the opening, else first."""
    before_release = {}
    holding = opening = False
    for segment in plan.sampled(period):
        track(world, segment)
        if opening:  # the fingers opened while this approach moved
            wait_for_gripper(world)
            opening = False
        if segment.gripper_after == GRIPPER_OPEN and holding:
            before_release = {
                "domino": domino_pose(world, PICKED),
                "hold": RigidTransform(world.domino_in_tcp(PICKED)),
            }
        near = abs(world.gripper_state().opening - segment.gripper_position) <= OPEN_WHILE_MOVING
        if segment.label.endswith(OPEN_SEGMENT) and near:
            world.command_gripper(segment.gripper_position, 0.0)
            opening = True
        elif gripper_event(world, segment, plan_force(plan, segment.label)):
            holding = segment.gripper_after == GRIPPER_CLOSE
    return before_release


def wait_for_gripper(world: CellWorld) -> None:
    """Advance until the simulator's gripper action would end: the fingers at the
    commanded opening, stalled on the domino, or out of time."""
    state = world.gripper_state()
    monitor = GripperMonitor(state.goal, world.time, world.gripper_stroke_time)
    while not monitor.check(
        world.time, state.opening, state.opening_rate, state.force, state.force_limit
    ).done:
        world.advance(GRIPPER_STEP)
        state = world.gripper_state()


def plan_force(plan, label: str) -> float:
    return next(s.gripper_effort for s in plan.segments if s.label == label)


def run_case(world: CellWorld, planner: PickPlacePlanner, case) -> dict:
    world.reset(domino_count=0, seed=case.index)
    standing = case.standing()
    world.set_domino_poses(
        {PICKED: flat_pose(*case.domino), **{i + 1: p for i, p in enumerate(standing)}}
    )
    world.settle(1.0)
    start_poses = [domino_pose(world, i + 1) for i in range(len(standing))]
    request = PickPlaceRequest(
        domino_pose(world, PICKED),
        case.place_pose(),
        world.joint_state().position[:7],
        standing=tuple(start_poses),
    )
    try:
        plan = planner.plan(request)
    except PlanningError as error:
        return {"index": case.index, "planned": False, "error": str(error)}
    began = time.perf_counter()
    result = execute(world, plan, planner.settings.sample_period)
    world.settle(FINAL_SETTLE)
    held = place_error(result["domino"], request.place_pose)
    slip = place_error(result["hold"], plan.held_in_tcp)
    final = place_error(domino_pose(world, PICKED), request.place_pose)
    moved = [
        np.linalg.norm(domino_pose(world, i + 1).translation() - p.translation())
        for i, p in enumerate(start_poses)
    ]
    return {
        "index": case.index,
        "neighbours": list(case.neighbours),
        "planned": True,
        "regrasped": plan.regrasped,
        "before_release_mm": held[0] * 1000,
        "before_release_deg": math.degrees(held[1]),
        "slip_in_hand_mm": slip[0] * 1000,
        "slip_in_hand_deg": math.degrees(slip[1]),
        "after_release_mm": final[0] * 1000,
        "after_release_deg": math.degrees(final[1]),
        "neighbours_moved_mm": max(moved, default=0.0) * 1000,
        "simulated_s": sum(s.duration for s in plan.segments),
        "wall_s": time.perf_counter() - began,
    }


def slot_cases(specs: list[str], scenario, seed: int) -> list[SlotCase]:
    """``LAYOUT:SLOT:STANDING,STANDING`` (e.g. circle30:20:19,21) as SlotCases, each
    carrying a flat domino from the pile's middle turned by a seeded yaw."""
    rng = np.random.default_rng(seed)
    cases = []
    for index, spec in enumerate(specs):
        layout, slot, standing = spec.split(":")
        yaw = rng.uniform(-math.pi, math.pi)
        neighbours = tuple(int(n) for n in standing.split(",") if n)
        cases.append(SlotCase(index, layout, int(slot), neighbours, (*scenario.pile_center, yaw)))
    return cases


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--count", type=int, default=10, help="pairs to execute")
    parser.add_argument("--seed", type=int, default=2026, help="seed of the pair set")
    parser.add_argument("--settings", help="JSON object of PlannerSettings overrides")
    parser.add_argument(
        "--slots", nargs="+", metavar="LAYOUT:SLOT:STANDING", help="e.g. circle30:20:19,21"
    )
    args = parser.parse_args()
    scenario = load_scenario()
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=4), scenario)
    planner = PickPlacePlanner(scenario, PlannerSettings(**json.loads(args.settings or "{}")))
    rows = []
    on_table = [case for case in make_cases(scenario, 4 * args.count, args.seed) if case.on_table]
    cases = slot_cases(args.slots, scenario, args.seed) if args.slots else on_table[: args.count]
    for case in cases:
        row = run_case(world, planner, case)
        rows.append(row)
        log(json.dumps(row))
    executed = [r for r in rows if r["planned"]]
    held_ok = [r["before_release_mm"] <= 1.0 and r["before_release_deg"] <= 0.5 for r in executed]
    stands_ok = [r["after_release_mm"] <= 2.0 and r["after_release_deg"] <= 2.0 for r in executed]
    print(
        json.dumps(
            {
                "benchmark": "planner_execution",
                "pairs": len(rows),
                "planned": len(executed),
                "held_within_1mm_0.5deg_before_release": sum(held_ok),
                "standing_within_2mm_2deg_after_release": sum(stands_ok),
                "max": {
                    key: max((r[key] for r in executed), default=None)
                    for key in (
                        "before_release_mm",
                        "before_release_deg",
                        "slip_in_hand_mm",
                        "slip_in_hand_deg",
                        "after_release_mm",
                        "after_release_deg",
                        "neighbours_moved_mm",
                    )
                },
                "wall_s_per_pair": float(np.mean([r["wall_s"] for r in executed]))
                if executed
                else None,
                "rows": rows,
                "load_average": os.getloadavg(),
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()

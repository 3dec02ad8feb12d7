"""Pick dominoes from poured piles and place them into a run, in the Drake simulation.

The arm job's loop (dombot_bringup.arm_job) without ROS, to measure what the isolated
pairs of bench_planner cannot: picks out of a real pile. For each seeded pile (poured
and settled by dombot_sim), the bring-up's default run (an arc of 10 at 0.6 m from the
base) is built in order. Each attempt: perceive with both pile cameras
(dombot_perception's pipeline); take the best detection lying flat or leaning, not where
an attempt at this slot already failed (those perception scored as leaving the fingers
room first, then the others with the most room; flat before leaning); pass the other
detections within 25 cm as the pile (``PickPlaceRequest.pile``), the dominoes already
placed as standing and perception's grasp as the preferred one, as the bring-up does
(``--no-perception-grasp``: none, the planner chooses); plan from the simulated arm's
joints. A detection
the planner refuses is recorded (request included, to plan it again) and, up to
``--candidates`` per attempt, the next one is planned (the bring-up offers 16 with their
pile: ``--candidates 16``; its last resort, planning without the pile, is
``--ignore-pile``). Then every segment is executed (as bench_planner_execution does) and
judged as the simulator's action server judges it (every joint within 0.01 rad of the
end within 0.5 s, else the goal is aborted), and every gripper event is run; a grasp is
checked by where the fingers stopped (the bring-up's 3 mm) and a placement by the
simulator's ground truth after 0.5 s (the bring-up's 3 mm horizontal / 3° tilt). After a
missed grasp or an aborted approach the gripper opens and the arm retraces the approach,
as the bring-up does: the next plan starts there. A domino carried but not placed, and a
run domino knocked out of its place, are taken out of the cell (the knocked slots are
built again first); an attempt succeeds when its domino is placed and no run domino was
knocked. A slot gets up to ``--max-attempts``; a slot not placed by then ends the pile.

Prints one JSON object on stdout (a row per attempt; progress on stderr).
"""

from __future__ import annotations

import argparse
import json
import math
import os
import time
from collections import Counter
from dataclasses import dataclass

import numpy as np
from bench_planner import log
from bench_planner_execution import TRACKING_SETTLE, plan_force, track, wait_for_gripper
from pydrake.math import RigidTransform

from dombot_bringup import layouts
from dombot_bringup.offers import NEIGHBOUR_RADIUS, with_pile_first
from dombot_description import DOMINO_SIZE
from dombot_description.grasp import pregrasp_opening, upright_pose
from dombot_description.scenario import load_scenario
from dombot_perception.frames import POSTURE_FLAT, POSTURE_TILTED, CameraView, Detection
from dombot_perception.pipeline import build_pipeline
from dombot_planner.errors import PlanningError
from dombot_planner.motion import GRIPPER_CLOSE, GRIPPER_OPEN
from dombot_planner.planner import PickPlacePlan, PickPlacePlanner, steeper_grasps
from dombot_planner.request import PickPlaceRequest
from dombot_planner.scene import ARM, PADS, PILE, QUERY_DISTANCE, Scene
from dombot_planner.settings import PlannerSettings
from dombot_sim.goal_monitor import (
    GOAL_SETTLE_TIME,
    Outcome,
    Tolerances,
    TrajectoryMonitor,
    Verdict,
)
from dombot_sim.trajectory import build_trajectory
from dombot_sim.world import CellWorld, WorldConfig

PILE_CAMERAS = ("camera_0", "camera_1")
PICKABLE = (POSTURE_FLAT, POSTURE_TILTED)  # the bring-up picks leaning dominoes too
FAILED_SPOT_RADIUS = 0.01  # m: a detection this close to a failed attempt is skipped
FRESH_FRAMES = 0.55  # s simulated before perceiving (the bring-up waits one camera period)
SETTLE_AFTER_PLACE = 0.5  # s simulated before the placement is judged
GRASP_TOLERANCE = 0.003  # m: the fingers stop this close to the domino width, or missed
SQUEEZE_LIMIT = 0.00085  # m: ... and no further inside it, or the pads met an edge (bring-up's)
PLACE_TOLERANCE = (0.003, math.radians(3.0))  # horizontal m, tilt rad (bring-up's)
BACK_OUT_OPENING = 0.04  # m wider than the pre-grasp: the bring-up's opening to back out
BACK_OUT_LEAD = 0.5  # s to ease from where the arm stopped onto the reversed approach
RUN = {"center": (0.0, 0.0), "radius": 0.6, "start_angle": math.radians(-2.0)}


def run_targets(count: int) -> list[RigidTransform]:
    """The bring-up's default layout: an arc about the base, 0.6 m out, from −2°."""
    placements = layouts.arc(RUN["center"], RUN["radius"], RUN["start_angle"], count)
    return [upright_pose(p.x, p.y, p.heading) for p in placements]


def placement_error(pose: np.ndarray, target: RigidTransform) -> tuple[float, float]:
    """Horizontal distance of the centres [m] and tilt of the length axis from vertical."""
    offset = pose[:2, 3] - target.translation()[:2]
    return float(np.linalg.norm(offset)), math.acos(min(1.0, abs(pose[2, 0])))


def request_record(request: PickPlaceRequest) -> dict:
    """The request's poses (4×4 lists) and start: enough to plan it again."""

    def matrices(poses) -> list:
        return [pose.GetAsMatrix4().tolist() for pose in poses]

    return {
        "domino_pose": request.domino_pose.GetAsMatrix4().tolist(),
        "place_pose": request.place_pose.GetAsMatrix4().tolist(),
        "start": request.start.tolist(),
        "standing": matrices(request.standing),
        "pile": matrices(request.pile),
    }


def within(error: float, tilt: float) -> bool:
    """The bring-up's placement check passes."""
    return error <= PLACE_TOLERANCE[0] and tilt <= PLACE_TOLERANCE[1]


@dataclass(frozen=True)
class PileOffer:
    """A detection as the bring-up's ranking sees it (``offers.Offer``)."""

    detection: Detection

    @property
    def scored(self) -> bool:
        return self.detection.score > 0.0

    @property
    def leaning(self) -> bool:
        return self.detection.posture == POSTURE_TILTED

    @property
    def clearance(self) -> float:
        return self.detection.clearance


class PileRun:
    """One pile in the simulated cell and the run being built from it."""

    def __init__(self, world: CellWorld, planner: PickPlacePlanner, pipeline, args) -> None:
        self.world, self.planner, self.pipeline, self.args = world, planner, pipeline, args
        self.targets = run_targets(args.count)
        self.placed: dict[int, int] = {}  # slot → index of the simulated domino standing there
        self.failed_spots: list[np.ndarray] = []  # of the slot being built (as the bring-up)
        self.slot = -1
        self.detections: list = []
        self.chosen = None  # the detection planned last

    def perceive(self) -> list:
        self.world.advance(FRESH_FRAMES)
        frames = self.world.render(list(PILE_CAMERAS), labels=False)
        views = [CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC) for f in frames.values()]
        self.detections = self.pipeline.run(views).detections
        return self.detections

    def candidates(self, detections: list) -> list:
        """The bring-up's offers with the pile, best first (``offers.with_pile_first``):
        lying flat or leaning, not where an attempt failed."""
        pickable = [
            detection
            for detection in detections
            if detection.posture in PICKABLE
            and all(
                np.linalg.norm(detection.X_WD[:2, 3] - f) >= FAILED_SPOT_RADIUS
                for f in self.failed_spots
            )
        ]
        return [offer.detection for offer in with_pile_first([PileOffer(d) for d in pickable])]

    def nearest_truth(self, position: np.ndarray) -> tuple[int, float]:
        """Index of the simulated domino nearest ``position`` and its distance [m]."""
        truths = [t for t in self.world.domino_truth() if t.in_use]
        distances = [np.linalg.norm(t.X_WD[:3, 3] - position) for t in truths]
        best = int(np.argmin(distances))
        return truths[best].index, float(distances[best])

    def request(self, chosen, detections: list, slot: int) -> PickPlaceRequest:
        """What the bring-up asks for: the detection, the other detections within
        NEIGHBOUR_RADIUS as its pile, the run standing so far; no grasp (the planner
        chooses) unless ``--perception-grasp``."""
        spot = chosen.X_WD[:2, 3]
        pile = tuple(
            RigidTransform(d.X_WD)
            for d in detections
            if d is not chosen and np.linalg.norm(d.X_WD[:2, 3] - spot) < NEIGHBOUR_RADIUS
        )
        return PickPlaceRequest(
            domino_pose=RigidTransform(chosen.X_WD),
            place_pose=self.targets[slot],
            start=self.world.joint_state().position[:7],
            grasp_pose=RigidTransform(chosen.grasp_pose) if self.args.perception_grasp else None,
            standing=tuple(self.targets[s] for s in self.placed),
            **({} if self.args.ignore_pile else {"pile": pile}),
            time_budget=self.args.budget,
        )

    def plan(self, detections: list, slot: int, row: dict) -> PickPlacePlan | None:
        """A plan for the first of ``--candidates`` detections that the planner accepts; the
        refused ones are recorded in ``row`` (and not tried again in this pile)."""
        candidates = self.candidates(detections)
        row.update(detections=len(detections), pickable=len(candidates))
        for chosen in candidates[: self.args.candidates or len(candidates)]:
            request = self.request(chosen, detections, slot)
            try:
                plan = self.planner.plan(request)
            except PlanningError as error:
                self.failed_spots.append(chosen.X_WD[:2, 3].copy())
                row["refused"].append(
                    {"code": error.code.name, "error": str(error), **request_record(request)}
                )
                continue
            row.update(
                planned=True,
                planning_s=plan.planning_time,
                regrasped=plan.regrasped,
                nudged=plan.nudged,
                grasp_lean_deg=math.degrees(math.acos(-plan.grasp_pose.rotation().matrix()[2, 2])),
                steeper_grasp=any(
                    plan.grasp_pose.IsNearlyEqualTo(g, 1e-6)
                    for g in steeper_grasps(
                        request.domino_pose, self.planner.settings.steeper_grasp_turn
                    )
                ),
                score=chosen.score,
                posture=int(chosen.posture),
                neighbours=len(request.pile),
                detection_error_mm=self.nearest_truth(chosen.X_WD[:3, 3])[1] * 1e3,
                spot=chosen.X_WD[:2, 3].tolist(),
            )
            self.chosen = chosen
            return plan
        return None

    def attempt(self, slot: int) -> dict:
        """Perceive, plan, execute and judge one pick-and-place into ``slot``."""
        began, simulated = time.perf_counter(), self.world.time
        if slot != self.slot:
            self.slot, self.failed_spots = slot, []
        row: dict = {"placed": False, "knocked": [], "refused": []}
        plan = self.plan(self.perceive(), slot, row)
        if plan is None:
            row["outcome"] = "not planned" if row["refused"] else "no candidate"
            return {**row, "wall_s": time.perf_counter() - began}
        row.update(self.pads_against_truth(plan, self.chosen))
        carried = self.execute(plan, row)
        if carried is None:
            self.failed_spots.append(np.array(row["spot"]))
        else:
            row.update(self.judge(slot, carried))
        row.update(
            knocked=self.clear_knocked(),
            simulated_s=self.world.time - simulated,
            wall_s=time.perf_counter() - began,
        )
        return row

    def pads_against_truth(self, plan: PickPlacePlan, chosen) -> dict:
        """Where the open pads come at the planned grasp against the simulator's true
        dominoes around the picked one (the true domino nearest the detection): the
        smallest distance, and the dominoes closer than 1 mm, with whether perception saw
        them (another detection whose nearest true domino it is)."""
        approaches = [s for s in plan.sampled(1.0) if s.label.endswith("approach_grasp")]
        approach = approaches[-1]  # after a regrasp, the approach to the turned domino
        q = approach.positions[-1]
        target, _ = self.nearest_truth(chosen.X_WD[:3, 3])
        seen = {self.nearest_truth(d.X_WD[:3, 3])[0] for d in self.detections if d is not chosen}
        spot = chosen.X_WD[:2, 3]
        near = [
            t
            for t in self.world.domino_truth()
            if t.in_use
            and t.index != target
            and np.linalg.norm(t.X_WD[:2, 3] - spot) < 2 * NEIGHBOUR_RADIUS
        ]
        shadow = self.planner.plants.get(pregrasp_opening(DOMINO_SIZE[1]))
        tcp = self.planner.scenario.tcp_frame
        closest, touching = {PADS: QUERY_DISTANCE, ARM: QUERY_DISTANCE}, []
        for truth in near:
            clearance = Scene(shadow, tcp, pile=[RigidTransform(truth.X_WD)]).clearance(q)
            for part in closest:
                closest[part] = min(closest[part], clearance.get((part, PILE), QUERY_DISTANCE))
            distance = min(clearance.get((part, PILE), QUERY_DISTANCE) for part in closest)
            if distance < 1e-3:
                touching.append(
                    {"index": truth.index, "mm": distance * 1e3, "detected": truth.index in seen}
                )
        return {
            "target": target,
            "pads_to_true_pile_mm": closest[PADS] * 1e3,
            "arm_to_true_pile_mm": closest[ARM] * 1e3,
            "pads_touch": touching,
        }

    def execute(self, plan: PickPlacePlan, row: dict) -> int | None:
        """Run the plan; the index of the domino carried at the last close, or None when
        a grasp missed or a segment was aborted (``row`` says which and how)."""
        carried = None
        for segment in plan.sampled(self.planner.settings.sample_period):
            track(self.world, segment)
            verdict = self.goal_verdict(segment)
            if verdict.outcome is not Outcome.SUCCEEDED:
                error = float(np.abs(verdict.error).max())
                row.update(outcome=f"aborted {segment.label}", goal_error_rad=error)
                if segment.label.endswith("approach_grasp"):
                    self.back_out(segment)
                else:  # the domino is dropped and an operator clears it
                    self.world.command_gripper(segment.gripper_position + BACK_OUT_OPENING, 0.0)
                    wait_for_gripper(self.world)
                    if carried is not None:
                        self.remove([carried])
                return None
            if segment.gripper_after not in (GRIPPER_OPEN, GRIPPER_CLOSE):
                continue
            self.world.command_gripper(segment.gripper_position, plan_force(plan, segment.label))
            wait_for_gripper(self.world)
            if segment.gripper_after == GRIPPER_CLOSE:
                opening = self.world.gripper_state().opening
                inside = DOMINO_SIZE[1] - opening
                if abs(inside) > GRASP_TOLERANCE or inside > SQUEEZE_LIMIT:
                    above = self.world.tcp_pose()[2, 3] - plan.grasp_pose.translation()[2]
                    row.update(
                        outcome="grasp missed" if abs(inside) > GRASP_TOLERANCE else "on an edge",
                        closed_mm=opening * 1e3,
                        tcp_above_grasp_mm=above * 1e3,
                    )
                    self.back_out(segment)
                    return None
                held = self.world.tcp_pose() @ plan.held_in_tcp.GetAsMatrix4()
                carried = self.nearest_truth(held[:3, 3])[0]
        self.world.advance(SETTLE_AFTER_PLACE)
        return carried

    def goal_verdict(self, segment) -> Verdict:
        """The simulator's verdict on the segment's goal with the default tolerances (the
        bring-up sends none); ``track`` left the arm TRACKING_SETTLE past the end."""
        if len(segment.times) < 2:
            return Verdict(Outcome.SUCCEEDED)
        names = self.world.arm_joint_names
        monitor = TrajectoryMonitor(
            names, self.world.time - TRACKING_SETTLE, Tolerances.defaults(len(names))
        )
        while True:
            position = self.world.joint_state().position[:7]
            verdict = monitor.check(self.world.time, position, segment.positions[-1])
            if verdict.outcome is not Outcome.RUNNING:
                return verdict
            self.world.advance(0.05)

    def back_out(self, segment) -> None:
        """The bring-up's back-out: open wider than the pre-grasp, then run the approach
        backwards, easing over BACK_OUT_LEAD from where the arm stopped onto it."""
        self.world.command_gripper(segment.gripper_position + BACK_OUT_OPENING, 0.0)
        wait_for_gripper(self.world)
        if len(segment.times) < 2:
            return
        end = segment.times[-1]
        spline = build_trajectory(
            self.world.arm_joint_names,
            (BACK_OUT_LEAD + end - segment.times)[::-1],
            segment.positions[::-1],
            -segment.velocities[::-1],
            self.world.joint_state().position[:7],
            self.world.arm_limits(),
        )
        self.world.advance_to(self.world.follow_trajectory(spline) + GOAL_SETTLE_TIME)

    def judge(self, slot: int, carried: int) -> dict:
        """Placed within the bring-up's tolerance, or "misplaced" (and taken out)."""
        error, tilt = placement_error(self.world.domino_truth()[carried].X_WD, self.targets[slot])
        placed = within(error, tilt)
        if placed:
            self.placed[slot] = carried
        else:
            self.remove([carried])
        return {
            "placed": placed,
            "outcome": "placed" if placed else "misplaced",
            "place_error_mm": error * 1e3,
            "tilt_deg": math.degrees(tilt),
        }

    def clear_knocked(self) -> list[int]:
        """Slots whose domino is no longer within the tolerance: taken out, to be built again."""
        truths = self.world.domino_truth()
        knocked = [
            slot
            for slot, index in self.placed.items()
            if not within(*placement_error(truths[index].X_WD, self.targets[slot]))
        ]
        if knocked:
            self.remove([self.placed.pop(slot) for slot in knocked])
        return knocked

    def remove(self, indices: list[int]) -> None:
        """Take dominoes out of the cell (an operator clears what the robot dropped)."""
        poses = {
            t.index: t.X_WD
            for t in self.world.domino_truth()
            if t.in_use and t.index not in indices
        }
        self.world.set_domino_poses(poses)


def build_run(world: CellWorld, planner: PickPlacePlanner, pipeline, seed: int, args) -> list[dict]:
    """Pour pile ``seed`` and build the run from it (knocked slots again first); a row per
    attempt. A slot not placed within ``max_attempts`` ends the pile, as in the bring-up."""
    report = world.reset(args.pile_size, seed)
    log(
        f"pile {seed}: {args.pile_size} poured, settled={report.settled} ({report.wall_time:.0f} s)"
    )
    run = PileRun(world, planner, pipeline, args)
    rows: list[dict] = []
    tries: Counter = Counter()
    queue = list(range(args.count))
    while queue:
        slot = queue.pop(0)
        tries[slot] += 1
        row = {"pile": seed, "slot": slot, "attempt": tries[slot], **run.attempt(slot)}
        row["success"] = row["placed"] and not row["knocked"]
        rows.append(row)
        log(json.dumps(row))
        queue = row["knocked"] + ([] if row["placed"] else [slot]) + queue
        if not row["placed"] and tries[slot] >= args.max_attempts:
            log(f"pile {seed}: slot {slot} not placed after {args.max_attempts} attempts")
            break
    return rows


def percentile(values: list[float], q: float) -> float | None:
    return float(np.percentile(values, q)) if values else None


def summarise(rows: list[dict]) -> dict:
    first = [r for r in rows if r["attempt"] == 1]
    planned = [r for r in rows if r.get("planned")]
    times = [r["planning_s"] for r in planned]
    placed = [r for r in rows if r["placed"]]
    missed = [r for r in rows if r["outcome"] == "grasp missed"]
    return {
        "slots": len(first),
        "placed": len(placed),
        "success_first_attempt": sum(r["success"] for r in first),
        "first_attempt_rate": sum(r["success"] for r in first) / max(1, len(first)),
        "attempts": len(rows),
        "outcomes": dict(Counter(r["outcome"] for r in rows)),
        "attempts_that_knocked_the_run": sum(bool(r["knocked"]) for r in rows),
        "first_attempt_outcomes": dict(Counter(r["outcome"] for r in first)),
        "pickable_detections_at_first_attempts": [r.get("pickable") for r in first],
        "refused_candidates": dict(Counter(f["code"] for r in rows for f in r["refused"])),
        "grasp_misses": {
            "pads_on_a_true_neighbour": sum(bool(r["pads_touch"]) for r in missed),
            "of_which_undetected": sum(
                any(not t["detected"] for t in r["pads_touch"]) for r in missed
            ),
            "tcp_above_grasp_mm": [round(r["tcp_above_grasp_mm"], 1) for r in missed],
        },
        "planned_with_pads_on_a_true_neighbour": sum(bool(r["pads_touch"]) for r in planned),
        "regrasped": sum(r.get("regrasped", False) for r in planned),
        "nudged": sum(r.get("nudged", False) for r in planned),
        "first_attempt_outcomes_nudged": dict(
            Counter(r["outcome"] for r in first if r.get("nudged"))
        ),
        "steeper_grasps": sum(r.get("steeper_grasp", False) for r in planned),
        "planning_s": {
            "p50": percentile(times, 50),
            "p95": percentile(times, 95),
            "max": max(times, default=None),
        },
        "placed_error_max": {
            "mm": max((r["place_error_mm"] for r in placed), default=None),
            "tilt_deg": max((r["tilt_deg"] for r in placed), default=None),
        },
        "wall_s_per_attempt": float(np.mean([r["wall_s"] for r in rows])) if rows else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--piles", type=int, default=4, help="piles (seeds seed..seed+piles-1)")
    parser.add_argument("--seed", type=int, default=0, help="first pile seed")
    parser.add_argument("--pile-size", type=int, default=30, help="dominoes poured per pile")
    parser.add_argument("--count", type=int, default=10, help="dominoes in each run")
    parser.add_argument("--max-attempts", type=int, default=4, help="per slot (bring-up's 4)")
    parser.add_argument(
        "--candidates", type=int, default=0, help="detections planned per attempt (0: all)"
    )
    parser.add_argument("--budget", type=float, default=5.0, help="planning budget [s]")
    parser.add_argument("--ignore-pile", action="store_true", help="plan without the pile")
    parser.add_argument(
        "--perception-grasp",
        action=argparse.BooleanOptionalAction,
        default=True,
        help="prefer perception's grasp, as the bring-up does (default)",
    )
    parser.add_argument("--settings", help="JSON object of PlannerSettings overrides")
    args = parser.parse_args()
    load_before = os.getloadavg()
    scenario = load_scenario()
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=args.pile_size), scenario)
    planner = PickPlacePlanner(scenario, PlannerSettings(**json.loads(args.settings or "{}")))
    pipeline = build_pipeline(scenario)
    rows = []
    for seed in range(args.seed, args.seed + args.piles):
        rows += build_run(world, planner, pipeline, seed, args)
    result = {
        "benchmark": "pile_picks",
        "piles": args.piles,
        "pile_size": args.pile_size,
        "run_length": args.count,
        "ignore_pile": args.ignore_pile,
        "perception_grasp": args.perception_grasp,
        "candidates_per_attempt": args.candidates,
        **summarise(rows),
        "rows": rows,
        "load_average": {"before": load_before, "after": os.getloadavg()},
    }
    print(json.dumps(result, indent=2))


if __name__ == "__main__":
    main()

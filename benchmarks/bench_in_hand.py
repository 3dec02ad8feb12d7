"""How often the in-hand check (``/perception/check_placement`` with ``in_hand``) sees a
held domino above its slot, over a grid of holds (issue 23: 48 of 118 checks in the
30-domino ledger runs were "not seen well enough").

For every ``--step``-th slot of bench_bringup's 30-domino layouts (``--layouts``), the
domino is held where the bring-up looks at it: ``place_approach_distance`` straight above
its release pose (``place_lead`` ahead), the arm at an IK solution for the TCP, the
fingers closed, the slot before it standing. The gripper leans over the slot's +z side
(``lean`` +1: where the planner leans it while the run is built in order, the free side
ahead) or its -z side (-1: a slot built after the next one). The holds: as planned, hanging
``--low`` lower, turned ``--yaw`` about the vertical, leaning ``--lean`` about the pinch
axis, and the planner's flatter and steeper grasps (``canonical_grasp`` turned by
``--grasp-turn``). Each scene is checked with every camera of the cell (the node's
``in_hand_cameras``), with each camera alone (``seen_by``) and, with ``--without``, with
every camera but that one (``without``: the cell before it was added); ``--scenario``
another cell, e.g. one with a camera more (its ``model_directives`` an absolute path).

Prints one JSON object on stdout: per side the gripper leans to as seen from
``--build-camera`` (towards it, away from it, across its view) and per hold and lean the
scenes, seen (STANDING), misread (seen, but the foot off by more than ``--foot-tolerance``
or the length axis by more than ``--tilt-tolerance`` from the truth); per side also how
many each camera alone sees (``seen_by``); the median wall seconds of a check with every
camera (and without ``--without``'s); progress on stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import statistics
import sys
import time
from collections import Counter, defaultdict

import numpy as np
from bench_run_slots import LAYOUTS, placements_of
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from dombot_bringup.task.geometry import placement_pose
from dombot_bringup.task.settings import ArmJobSettings
from dombot_description import DOMINO_SIZE
from dombot_description.cell import build_shadow_plant
from dombot_description.grasp import canonical_grasp, place_grasps
from dombot_perception import placement_check as check
from dombot_perception.frames import CameraView
from dombot_perception.pipeline import build_pipeline
from dombot_planner.settings import PlannerSettings
from dombot_sim.world import CellWorld, WorldConfig

CLOSED = DOMINO_SIZE[1]  # m: the fingers closed on the domino's width


class HeldScenes:
    """The cell with its arm holding one domino and up to two standing, rendered."""

    def __init__(self, scenario_path: str | None) -> None:
        config = WorldConfig(scenario_path=scenario_path, cameras=True, domino_capacity=3)
        self.world = CellWorld(config)
        scenario = self.world.scenario
        self.plant = build_shadow_plant(scenario, CLOSED).plant
        self.tcp_frame = self.plant.GetFrameByName(scenario.tcp_frame)
        self.home = np.asarray(scenario.home_position, dtype=float)

    def arm_at(self, tcp: RigidTransform) -> np.ndarray | None:
        ik = InverseKinematics(self.plant, self.plant.CreateDefaultContext())
        where = tcp.translation()
        world = self.plant.world_frame()
        ik.AddPositionConstraint(self.tcp_frame, np.zeros(3), world, where, where)
        ik.AddOrientationConstraint(world, tcp.rotation(), self.tcp_frame, RotationMatrix(), 0.0)
        ik.get_mutable_prog().AddQuadraticErrorCost(np.eye(7), self.home, ik.q())
        result = Solve(ik.prog(), self.home)
        return result.GetSolution(ik.q()) if result.is_success() else None

    def held(
        self,
        expected: RigidTransform,
        grasp: RigidTransform,
        lean: int,
        hold: dict[str, float],
        standing: list[np.ndarray],
    ) -> tuple[list[CameraView], np.ndarray] | None:
        """The views of every camera and the true pose of a domino held by ``grasp``
        (X_DG) at ``expected`` with the gripper over its ``lean``·z side, moved in the hand
        by ``hold``: ``low`` [m] down, ``yaw`` [rad] about the vertical, ``lean`` [rad]
        about the pinch axis through the TCP. None: no IK for the TCP."""
        tcp = place_grasps(expected, grasp.inverse(), lean * expected.rotation().matrix()[:, 2])[0]
        arm = self.arm_at(tcp)
        if arm is None:
            return None
        # the TCP on the domino's mid plane (of the symmetric hold place_grasps chose)
        pinch = (expected.inverse() @ tcp).translation() * [1.0, 1.0, 0.0]
        tilted = RotationMatrix.MakeYRotation(hold.get("lean", 0.0))
        domino = expected @ RigidTransform(pinch) @ RigidTransform(tilted) @ RigidTransform(-pinch)
        turned = RotationMatrix.MakeZRotation(hold.get("yaw", 0.0)) @ domino.rotation()
        low = [0.0, 0.0, -hold.get("low", 0.0)]
        domino = RigidTransform(turned, domino.translation() + low)
        self.world.set_robot_positions(arm, CLOSED)
        self.world.set_domino_poses({0: domino} | dict(enumerate(standing, start=1)))
        frames = self.world.render(labels=False).values()
        return [CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC) for f in frames], (
            domino.GetAsMatrix4()
        )


def foot_and_tilt(measured: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Horizontal distance of the feet [m] and angle between the length axes [rad]."""

    def up_and_foot(pose: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        up = pose[:3, 0] * np.sign(pose[2, 0])
        return up, pose[:3, 3] - DOMINO_SIZE[0] / 2.0 * up

    (up_m, foot_m), (up_t, foot_t) = up_and_foot(measured), up_and_foot(truth)
    return float(np.hypot(*(foot_m - foot_t)[:2])), float(np.arccos(np.clip(up_m @ up_t, -1, 1)))


def holds(args: argparse.Namespace) -> dict[str, tuple[RigidTransform, dict[str, float]]]:
    planned = canonical_grasp()
    turn = math.radians(args.grasp_turn)
    return {
        "planned": (planned, {}),
        f"low {args.low * 1e3:.0f} mm": (planned, {"low": args.low}),
        f"yaw {args.yaw:.0f}°": (planned, {"yaw": math.radians(args.yaw)}),
        f"lean {args.lean:.0f}°": (planned, {"lean": math.radians(args.lean)}),
        f"flatter grasp ({args.grasp_turn:.0f}°)": (canonical_grasp(turn, 0.004), {}),
        f"steeper grasp ({args.grasp_turn:.0f}°)": (canonical_grasp(-turn), {}),
    }


def gripper_side(expected: RigidTransform, lean: int, camera: CameraView) -> str:
    """Where the gripper leans (over the slot's ``lean``·z side) seen from ``camera``:
    towards it, away from it or across its view (within 60° of either)."""
    over = lean * expected.rotation().matrix()[:2, 2]
    to_camera = camera.X_WC[:2, 3] - expected.translation()[:2]
    cosine = float(over @ to_camera / np.linalg.norm(over) / np.linalg.norm(to_camera))
    return "towards" if cosine > 0.5 else "away from" if cosine < -0.5 else "across"


def run(args: argparse.Namespace) -> dict:
    scenes = HeldScenes(args.scenario)
    pipeline = build_pipeline(scenes.world.scenario)
    config = check.PlacementConfig(in_hand=True)
    above = RigidTransform(PlannerSettings().place_approach_distance * np.array([0, 0, 1.0]))

    def tally() -> dict:
        return {"scenes": 0, "seen": 0, "misread": 0}

    by_hold: dict[str, dict] = defaultdict(tally)
    by_side: dict[str, dict] = defaultdict(lambda: {**tally(), "seen_by": Counter()})
    seconds: dict[str, list[float]] = defaultdict(list)  # per check, by the cameras checked

    def judged(
        target: np.ndarray, truth: np.ndarray, views: list[CameraView], cameras: str
    ) -> tuple[bool, bool]:
        """Seen, misread: the check of ``views`` (timed under ``cameras``)."""
        start = time.perf_counter()
        [placement] = check.check_placements([target], views, pipeline, config)
        seconds[cameras].append(time.perf_counter() - start)
        seen = placement.status == check.STANDING
        errors = foot_and_tilt(placement.measured, truth)
        tolerances = (args.foot_tolerance, math.radians(args.tilt_tolerance))
        return seen, seen and any(e > t for e, t in zip(errors, tolerances, strict=True))

    for layout in args.layouts:
        run_slots = placements_of(layout)
        for slot in range(0, len(run_slots), args.step):
            release = placement_pose(run_slots[slot], ArmJobSettings.place_lead)
            expected = above @ RigidTransform(release)
            target = expected.GetAsMatrix4()
            standing = [placement_pose(run_slots[slot - 1])] if slot else []
            for name, (grasp, hold) in holds(args).items():
                for lean in (1, -1):
                    scene = scenes.held(expected, grasp, lean, hold, standing)
                    if scene is None:
                        continue
                    views, truth = scene
                    seen, misread = judged(target, truth, views, "every camera")
                    build_camera = next(v for v in views if v.name == args.build_camera)
                    side = (
                        f"gripper {gripper_side(expected, lean, build_camera)} {args.build_camera}"
                    )
                    for row in (by_hold[f"{name}, lean {lean:+d}"], by_side[side]):
                        row["scenes"] += 1
                        row["seen"] += seen
                        row["misread"] += misread
                    for view in views:
                        [alone] = check.check_placements([target], [view], pipeline, config)
                        by_side[side]["seen_by"][view.name] += alone.status == check.STANDING
                    if args.without:
                        rest = [v for v in views if v.name != args.without]
                        before = judged(target, truth, rest, f"without {args.without}")
                        without = by_side[side].setdefault("without", Counter())
                        without.update(seen=before[0], misread=before[1])
                    print(
                        f"{layout} slot {slot + 1} {name} lean {lean:+d} ({side}): "
                        f"{'seen' if seen else 'not seen'}",
                        file=sys.stderr,
                    )
    scenes.world.set_robot_positions()
    return {
        "benchmark": "in_hand",
        "by_side": by_side,
        "by_hold": by_hold,
        "seconds_per_check": {k: statistics.median(v) for k, v in seconds.items()},
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layouts", nargs="+", default=list(LAYOUTS), choices=LAYOUTS)
    parser.add_argument(
        "--scenario", help="scenario file (e.g. with another camera); default: the cell's"
    )
    parser.add_argument(
        "--build-camera", default="camera_2", help="the gripper's side is told from it"
    )
    parser.add_argument(
        "--without", help="also check every scene without this camera (e.g. camera_3)"
    )
    parser.add_argument("--step", type=int, default=5, help="every step-th slot")
    parser.add_argument("--low", type=float, default=0.006, help="m the hold hangs low")
    parser.add_argument("--yaw", type=float, default=12.0, help="deg about the vertical")
    parser.add_argument("--lean", type=float, default=6.0, help="deg about the pinch axis")
    parser.add_argument("--grasp-turn", type=float, default=10.0, help="deg, grasp families")
    parser.add_argument("--foot-tolerance", type=float, default=0.002, help="m: misread")
    parser.add_argument("--tilt-tolerance", type=float, default=1.5, help="deg: misread")
    print(json.dumps(run(parser.parse_args()), indent=1))


if __name__ == "__main__":
    main()

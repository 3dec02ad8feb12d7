"""Replay a pick the bring-up recorded (``bringup --record-picks``), offline, from the truth.

Why a grasp missed is rarely in the logs: perception had the domino within a millimetre,
the arm tracked its plan, and the fingers closed on nothing. The record holds what the
pick was planned from (the offer, its pile, the points seen on no detected domino, the
plan's segments) and the simulator's truth at the time, so this script can say:

* where the pads' path (open pads down the approach, then each pad's stroke closing on
  the domino: ``Grasp.pad_paths``) comes within ``--near`` of a true domino, and whether
  perception had detected that domino (a pile domino of the offer) or not;
* with ``--physics``, what happens when the recorded approach and close run in a fresh
  ``CellWorld`` holding the true dominoes: where the fingers stop and what moved; with
  ``--carry`` also the carry to above the slot: how far the domino turned and slid in
  the hand on the way (or whether it left it); with ``--place`` on through the release
  and the retreat: whether it is still in the hand, where it lies and how far from the
  release pose (records that hold the release pose).

Prints one JSON object. In ``./dombot shell``: ``python benchmarks/replay_pick.py RECORD
[--physics]``.
"""

from __future__ import annotations

import argparse
import json
import math
from pathlib import Path

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description import DOMINO_SIZE, tilt_from_vertical
from dombot_description.grasp import Grasp, OrientedBox, nearest_distance, pregrasp_opening
from dombot_msgs.msg import TrajectorySegment
from dombot_planner.settings import PlannerSettings
from dombot_sim.trajectory import build_trajectory
from dombot_sim.world import CellWorld, WorldConfig

CLOSE, OPEN = TrajectorySegment.GRIPPER_CLOSE, TrajectorySegment.GRIPPER_OPEN
SURFACE_STEP = 0.001  # m between the sampled points of a true domino's faces
DETECTED_WITHIN = 0.005  # m: a pile domino this close to a true one is its detection
MOVED = 0.0005  # m: a domino that moved more than this during the close is listed
GRIPPER_SETTLE = 1.5  # s simulated for the fingers to close or stall
TRACKING_SETTLE = 0.3  # s simulated after each trajectory


def box_surface(pose: np.ndarray) -> np.ndarray:
    """Points on the six faces of a domino at ``pose`` (4x4), world frame."""
    return OrientedBox(RigidTransform(pose), np.asarray(DOMINO_SIZE)).surface(SURFACE_STEP)


def truth_of(record: dict) -> dict[int, np.ndarray]:
    """The simulator's dominoes by index (names are ``domino_<index>``)."""
    return {int(name.rsplit("_", 1)[1]): np.array(m) for name, m in record["truth"].items()}


def nearest(truth: dict[int, np.ndarray], pose: np.ndarray) -> tuple[int, float]:
    index = min(truth, key=lambda i: np.linalg.norm(truth[i][:3, 3] - pose[:3, 3]))
    return index, float(np.linalg.norm(truth[index][:3, 3] - pose[:3, 3]))


def grasp_of(world: CellWorld, record: dict) -> tuple[Grasp, np.ndarray]:
    """The TCP where the last approach of the plan ends (after a regrasp: the second), and
    the direction its approach line came down along (unit, from the grasp back up)."""
    approach = [s for s in record["segments"] if s["label"].endswith("approach_grasp")][-1]
    tcp = []
    for positions in approach["positions"][::-1]:
        world.set_robot_positions(np.array(positions))
        tcp.append(RigidTransform(world.tcp_pose()))
        back = tcp[-1].translation() - tcp[0].translation()
        if np.linalg.norm(back) > 0.005:  # m: on the straight line, far enough to aim
            break
    width = DOMINO_SIZE[1]
    grasp = Grasp(tcp[0], width, pregrasp_opening(width))
    return grasp, back / np.linalg.norm(back)


def pads_against_truth(record: dict, grasp: Grasp, retreat: np.ndarray, near: float) -> dict:
    """The true dominoes the pads' path comes within ``near`` of (mm, detected or not)."""
    truth = truth_of(record)
    target, seen_off = nearest(truth, np.array(record["domino_pose"]))
    detected = {nearest(truth, np.array(p))[0] for p in record["pile_dominoes"]}
    paths = grasp.pad_paths(PlannerSettings().pick_approach_distance, retreat)
    points = np.array(record["pile_points"]).reshape(-1, 3)
    met = []
    for index, pose in sorted(truth.items()):
        if index == target:
            continue
        surface = box_surface(pose)
        distance = nearest_distance(paths, surface)
        if distance < near:
            met.append(
                {"domino": index, "mm": round(distance * 1e3, 2), "detected": index in detected}
            )
    return {
        "target": target,
        "seen_off_mm": round(seen_off * 1e3, 2),
        "pads_path_meets": met,
        "pile_points_in_pads_path": int(
            sum(np.count_nonzero(path.signed_distance(points) < 0.0) for path in paths)
        ),
    }


def replay(world: CellWorld, record: dict, carry: bool, place: bool = False) -> dict:
    """Run the recorded segments in a world holding the true dominoes, up to the close
    (``carry``: to the end of "transfer"; ``place``: to the end, the release and the
    retreat); where the fingers stopped, which dominoes moved during the close, how the
    domino sat in the hand after the carry, and where it was after the retreat."""
    truth = truth_of(record)
    target, _ = nearest(truth, np.array(record["domino_pose"]))
    result: dict = {}
    world.set_domino_poses(truth)
    start = dict(zip(record["start"]["names"], record["start"]["positions"], strict=True))
    world.set_robot_positions(np.array([start[name] for name in world.arm_joint_names]))
    world.settle(1.0)
    for segment in record["segments"]:
        if len(segment["times"]) > 1:
            spline = build_trajectory(
                segment["joint_names"],
                segment["times"],
                segment["positions"],
                segment["velocities"],
                world.joint_state().position[:7],
                world.arm_limits(),
            )
            world.advance_to(world.follow_trajectory(spline) + TRACKING_SETTLE)
        if segment["gripper_after"] == OPEN:
            world.command_gripper(segment["gripper_position"], 0.0)
            world.advance(GRIPPER_SETTLE)
        elif segment["gripper_after"] == CLOSE:
            before = {t.index: t.X_WD[:3, 3] for t in world.domino_truth() if t.in_use}
            world.command_gripper(segment["gripper_position"], segment["gripper_max_effort"])
            world.advance(GRIPPER_SETTLE)
            moved = {
                t.index: np.linalg.norm(t.X_WD[:3, 3] - before[t.index])
                for t in world.domino_truth()
                if t.in_use
            }
            result = {
                "fingers_stopped_mm": round(world.gripper_state().opening * 1e3, 2),
                "moved_mm": {i: round(d * 1e3, 2) for i, d in sorted(moved.items()) if d > MOVED},
            }
            if not carry:
                return result
            held = world.domino_in_tcp(target)
        if segment["label"] == "transfer" and "fingers_stopped_mm" in result:
            now = world.domino_in_tcp(target)
            turn = RotationMatrix(held[:3, :3].T @ now[:3, :3]).ToAngleAxis().angle()
            result["carried"] = {
                "slid_mm": round(float(np.linalg.norm(now[:3, 3] - held[:3, 3])) * 1e3, 2),
                "turned_deg": round(math.degrees(turn), 2),
                "fingers_mm": round(world.gripper_state().opening * 1e3, 2),
            }
            if not place:
                return result
    if place and "fingers_stopped_mm" in result:
        world.advance(TRACKING_SETTLE)
        released = next(t.X_WD for t in world.domino_truth() if t.index == target)
        release = np.array(record["place_pose"]) if "place_pose" in record else None
        result["after_retreat"] = {
            "in_hand_mm": round(float(np.linalg.norm(world.domino_in_tcp(target)[:3, 3])) * 1e3, 2),
            "tilt_deg": round(math.degrees(tilt_from_vertical(released)), 2),
            "position": released[:3, 3].round(4).tolist(),
            "from_place_mm": None
            if release is None
            else round(float(np.linalg.norm(released[:2, 3] - release[:2, 3])) * 1e3, 2),
        }
    return result


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("record", type=Path, help="a pick record (OUT/picks/pickNNN_slotK.json)")
    parser.add_argument("--near", type=float, default=2.0, help="[mm] list dominoes this close")
    parser.add_argument("--physics", action="store_true", help="replay the approach and close")
    parser.add_argument("--carry", action="store_true", help="--physics on to above the slot")
    parser.add_argument(
        "--place", action="store_true", help="--physics on through the release and retreat"
    )
    args = parser.parse_args()
    record = json.loads(args.record.read_text())
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=len(record["truth"])))
    grasp, retreat = grasp_of(world, record)
    result = {
        "benchmark": "replay_pick",
        "record": str(args.record),
        "slot": record["slot"],
        "plan": record["plan"],
        "failure": record.get("failure"),
        "grasp_tilt_deg": round(math.degrees(math.acos(-grasp.approach[2])), 1),
        "approach_line_tilt_deg": round(math.degrees(math.acos(retreat[2])), 1),
        **pads_against_truth(record, grasp, retreat, args.near * 1e-3),
    }
    if args.physics or args.carry or args.place:
        result["replayed"] = replay(world, record, args.carry or args.place, args.place)
    print(json.dumps(result, indent=1))


if __name__ == "__main__":
    main()

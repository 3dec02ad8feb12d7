"""How much of the pile the pile cameras lose while the arm places a domino near it.

The bring-up asks for the next pick's look at the pile as the carry ends above a slot at
least ``look_while_placing`` from the pile's centre, and the frames are taken while the
arm holds the domino there, descends, lets go and retreats (``placing.look_while_placing``).
This pours a seeded pile in Drake (no ROS), plans a flat pile domino's pick and place
at slots at the given distances from the pile's centre (bearings across the build area,
runs heading along and across it; the default S-curve's slots 1-6 too), and renders the
pile cameras with the arm where the carry ends, down the descent, at the release and where
the retreat ends, the domino held or let go, against the arm at home: the pile's pixels
each camera loses (render labels), and what perception's detect finds in both renders
(dominoes lost or gained, how far the matched ones moved). One JSON object per slot.

    python benchmarks/bench_pile_view.py                       # seed 0, pile of 40
    python benchmarks/bench_pile_view.py --distances 0.20 0.24 --bearings 1
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time

import numpy as np
from pydrake.math import RigidTransform

from dombot_description.grasp import upright_pose
from dombot_perception.frames import CameraView
from dombot_perception.pipeline import build_pipeline
from dombot_planner.errors import PlanningError
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings
from dombot_sim.world import CellWorld, WorldConfig

PILE_CAMERAS = ("camera_0", "camera_1")
# the default S-curve of SPEED.md's table (start, heading, length, amplitude, count)
S_CURVE = ((0.50, -0.07), 90.0, 0.55, 0.05, 20)
S_CURVE_SLOTS = 6  # its first six: 0.235-0.377 m from the pile's centre
MATCH_DISTANCE = 0.002  # m between a detection at home and one with the arm placing
PLACE_SAMPLES = 3  # arm positions down the descent, its end (the release) included


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0, help="pile seed (0)")
    parser.add_argument("--pile", type=int, default=40, help="dominoes poured (40)")
    parser.add_argument(
        "--distances",
        type=float,
        nargs="+",
        default=[0.20, 0.22, 0.24, 0.26, 0.28, 0.30, 0.32, 0.34, 0.36],
        help="m from the pile's centre",
    )
    parser.add_argument(
        "--bearings", type=int, default=3, help="slots per distance across the build area (3)"
    )
    parser.add_argument(
        "--headings", type=float, nargs="+", default=[90.0, 0.0], help="runs' headings [deg]"
    )
    return parser.parse_args(argv)


def slots(world: CellWorld, args: argparse.Namespace) -> list[tuple[str, float, float, float]]:
    """(name, x, y, heading) of each slot to place at: at each distance, ``bearings`` spots
    from the pile's centre spread over the arc of that circle inside the build area; then
    the default S-curve's first slots."""
    from dombot_bringup.layouts import s_curve

    scenario = world.scenario
    (cx, cy), (x_low, x_high), (y_low, _) = (
        scenario.pile_center,
        scenario.build_x,
        scenario.build_y,
    )
    found = []
    for distance in args.distances:
        if distance < y_low - cy:
            continue
        angles = [
            a
            for a in np.linspace(0.0, math.pi, 721)
            if cy + distance * math.sin(a) >= y_low - 1e-9
            and x_low <= cx + distance * math.cos(a) <= x_high
        ]
        picks = np.linspace(angles[0], angles[-1], args.bearings) if args.bearings > 1 else []
        for angle in sorted(set(np.round(picks, 6))) if len(picks) else [math.pi / 2]:
            x, y = cx + distance * math.cos(angle), cy + distance * math.sin(angle)
            for heading in args.headings:
                name = f"{distance:.2f} m, bearing {math.degrees(angle):.0f}°"
                found.append((name, x, y, math.radians(heading)))
    start, heading, length, amplitude, count = S_CURVE
    for placement in s_curve(start, math.radians(heading), length, amplitude, count)[
        :S_CURVE_SLOTS
    ]:
        found.append(
            (f"S-curve slot {placement.index + 1}", placement.x, placement.y, placement.heading)
        )
    return found


def flat_pile_dominoes(world: CellWorld) -> list[int]:
    """Indices of the pile's dominoes lying flat, the highest first (the bring-up's picks)."""
    truths = [t for t in world.domino_truth() if t.in_use]
    flat = [t for t in truths if abs(t.X_WD[2, 2]) > 0.95]
    return [t.index for t in sorted(flat, key=lambda t: -t.X_WD[2, 3])]


def arm_positions(plan) -> list[tuple[str, np.ndarray, bool, float]]:
    """(where, arm joints, held, finger opening) from the carry's end to the retreat's."""
    by_label = {segment.label: segment for segment in plan.segments}
    transfer, place, retreat = by_label["transfer"], by_label["place"], by_label["retreat"]
    _, above, _, _ = transfer.sample(1e9)
    _, down, _, _ = place.sample(place.duration / (PLACE_SAMPLES - 1) * 0.999)
    _, back, _, _ = retreat.sample(1e9)
    positions = [("above", above[-1], True, transfer.finger_opening)]
    for k in range(1, PLACE_SAMPLES):
        where = "released" if k == PLACE_SAMPLES - 1 else f"descent {k}/{PLACE_SAMPLES - 1}"
        q = down[-1] if k == PLACE_SAMPLES - 1 else down[min(k, len(down) - 1)]
        positions.append((where, q, True, place.finger_opening))
    positions.append(("retreated", back[-1], False, retreat.finger_opening))
    return positions


def views(world: CellWorld) -> tuple[list[CameraView], dict[str, np.ndarray]]:
    frames = world.render(list(PILE_CAMERAS), labels=True)
    return (
        [CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC) for f in frames.values()],
        {name: f.label for name, f in frames.items()},
    )


def detect(world: CellWorld, camera_views: list[CameraView]) -> tuple[np.ndarray, int]:
    """Centres of the dominoes perception's detect finds (a fresh pipeline: no memory),
    and how many scene points lie on none of them (obstacles for the planner)."""
    result = build_pipeline(world.scenario).run(camera_views)
    centres = np.array([d.X_WD[:3, 3] for d in result.detections]).reshape(-1, 3)
    return centres, len(result.unexplained)


def compare(
    home: tuple[np.ndarray, int],
    detected: tuple[np.ndarray, int],
    home_labels: dict,
    labels: dict,
    pile: set[int],
) -> dict:
    """The pile's pixels lost per camera, the detections lost, gained and moved, and the
    scene points on no detection gained."""
    (home, home_unexplained), (placing, unexplained) = home, detected
    lost_pixels = {}
    for name, before in home_labels.items():
        on_pile = np.isin(before, list(pile))
        lost = on_pile & (labels[name] != before)
        lost_pixels[name] = round(float(lost.sum()) / max(int(on_pile.sum()), 1), 4)
    lost = gained = 0
    moved = 0.0
    if len(home) and len(placing):
        distances = np.linalg.norm(home[:, None, :] - placing[None, :, :], axis=2)
        lost = int((distances.min(axis=1) > MATCH_DISTANCE).sum())
        gained = int((distances.min(axis=0) > MATCH_DISTANCE).sum())
        matched = distances.min(axis=1)[distances.min(axis=1) <= MATCH_DISTANCE]
        moved = float(matched.max()) if len(matched) else 0.0
    else:
        lost, gained = len(home), len(placing)
    return {
        "pile_pixels_lost": lost_pixels,
        "detections_lost": lost,
        "detections_gained": gained,
        "matched_moved_mm": round(moved * 1e3, 2),
        "unexplained_points_gained": unexplained - home_unexplained,
    }


def measure(
    world: CellWorld,
    planner: PickPlacePlanner,
    pile: dict[int, np.ndarray],
    candidates: list[int],
    place: RigidTransform,
) -> dict | None:
    """The first of the ``candidates`` (pile dominoes) that plans, carried to ``place``:
    the pile's look (the rest of ``pile``) at each arm position from the carry's end to
    the retreat's against the arm at home (``compare``); None: none plans."""
    home_q = np.asarray(world.scenario.home_position)
    for picked in candidates:
        request = PickPlaceRequest(RigidTransform(pile[picked]), place, home_q)
        try:
            plan = planner.plan(request)
        except PlanningError:
            continue
        rest = {i: pose for i, pose in pile.items() if i != picked}
        world.set_domino_poses({**rest, picked: place.GetAsMatrix4()})
        world.set_robot_positions(home_q)
        home_views, home_labels = views(world)
        home = detect(world, home_views)
        entry: dict = {"picked": picked, "detected_at_home": len(home[0]), "positions": {}}
        for where, q, held, opening in arm_positions(plan):
            world.set_robot_positions(q, opening)
            if held:
                in_hand = world.tcp_pose() @ plan.held_in_tcp.GetAsMatrix4()
                world.set_domino_poses({**rest, picked: in_hand})
            placing_views, labels = views(world)
            entry["positions"][where] = compare(
                home, detect(world, placing_views), home_labels, labels, set(rest)
            )
            world.set_domino_poses({**rest, picked: place.GetAsMatrix4()})
        return entry
    return None


def main(argv: list[str]) -> int:
    args = parse_args(argv)
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=args.pile))
    poured = world.reset(args.pile, args.seed)
    planner = PickPlacePlanner(world.scenario, PlannerSettings())
    pile = {t.index: t.X_WD for t in world.domino_truth() if t.in_use}
    flat = flat_pile_dominoes(world)
    print(json.dumps({"seed": args.seed, "pile": args.pile, "settled": poured.settled}), flush=True)
    for name, x, y, heading in slots(world, args):
        started = time.perf_counter()
        entry = {
            "slot": name,
            "xy": [round(x, 3), round(y, 3)],
            "heading_deg": round(math.degrees(heading)),
            "distance": round(float(np.hypot(*(np.array([x, y]) - world.scenario.pile_center))), 3),
        }
        measured = measure(world, planner, pile, flat, upright_pose(x, y, heading))
        entry.update(measured or {"refused": "no flat pile domino plans"})
        entry["wall_s"] = round(time.perf_counter() - started, 1)
        print(json.dumps(entry), flush=True)
    return 0


if __name__ == "__main__":
    sys.exit(main(sys.argv[1:]))

"""How often the in-hand check sees the hold the planner itself plans above a slot, with
the run before it standing (issue 23: bench_in_hand's IK holds over a lone neighbour were
seen at 176 of 188 scenes while the 30-domino ledger runs placed 115 of 567 blind).

For each ``--slots`` of a bench_bringup 30-domino case (``--layout``), the slot is planned
as bench_run_slots asks for it (every slot before it in the build order standing, a flat
pile domino turned ``--pile-yaw``; a slot refused so is left out); the arm is put where
the plan's "transfer" ends, the domino at the plan's ``held_in_tcp`` turned ``--turns``
about the pinch axis (the TCP's y), the run before it standing, and every camera renders;
so again with the arm's base joint turned ``--looks`` from there (the arm and the hold
turned rigidly about the world's z axis, the base's: the second look from a turned base,
``ArmJobSettings.in_hand_look_turn``), the expected hold turned with it.
Each scene is checked with every camera (the node's ``in_hand_cameras``) and with each
alone. ``--scenes FILE`` keeps the renders (pickled; read back when the file exists, so
the same scenes can be checked by another commit's code). Prints one JSON object: per
slot, turn and look the status with every camera and each camera's alone, the seen counts,
and per look how many holds not seen as planned that look sees; progress on stderr.
"""

from __future__ import annotations

import argparse
import json
import math
import os
import pickle
import sys
from collections import Counter

import numpy as np
from bench_in_hand import foot_and_tilt
from bench_run_slots import LAYOUTS, SlotCase, build_order, placements_of
from pydrake.math import RigidTransform, RotationMatrix

from dombot_bringup.task.geometry import placement_pose
from dombot_bringup.task.settings import ArmJobSettings
from dombot_description import DOMINO_SIZE
from dombot_description.scenario import load_scenario
from dombot_perception import placement_check as check
from dombot_perception.frames import CameraView
from dombot_perception.pipeline import build_pipeline
from dombot_planner.errors import PlanningError
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.settings import PlannerSettings
from dombot_sim.world import CellWorld, WorldConfig

STATUS = {check.STANDING: "seen", check.NOT_SEEN: "not seen"}


def render(args: argparse.Namespace) -> list[dict]:
    """The scenes: per slot and turn, the target, the true pose and every camera's view."""
    scenario = load_scenario()
    planner = PickPlacePlanner(scenario, PlannerSettings(default_time_budget=3600.0))
    run = placements_of(args.layout)
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=len(run) + 1))
    order = build_order(run, ArmJobSettings.section)
    scenes = []
    for slot in args.slots:
        position = order.index(slot - 1)
        standing = tuple(i + 1 for i in sorted(order[:position]))
        pile = (*scenario.pile_center, args.pile_yaw)
        case = SlotCase(position, args.layout, slot, standing, pile)
        try:
            plan = planner.plan(case.request(scenario.home_position))
        except PlanningError as error:
            print(f"{args.layout} slot {slot}: refused ({error.code.name})", file=sys.stderr)
            continue
        transfer = next(s for s in plan.segments if s.label == "transfer").pieces[-1]
        above = transfer.sample(np.array([transfer.duration]))[0][0]
        run_poses = {k: placement_pose(run[n - 1]) for k, n in enumerate(standing, start=1)}
        world.set_robot_positions(above, DOMINO_SIZE[1])
        tcp_above = world.tcp_pose()
        for look in args.looks:
            base = RigidTransform(RotationMatrix.MakeZRotation(math.radians(look)))
            arm = above + np.eye(len(above))[0] * math.radians(look)
            world.set_robot_positions(arm, DOMINO_SIZE[1])
            # the base joint turns about the world's z axis: the TCP turned rigidly with it
            assert np.allclose(world.tcp_pose(), base.GetAsMatrix4() @ tcp_above, atol=1e-9)
            target = base @ plan.held_above_place
            tcp = target @ plan.held_in_tcp.inverse()
            for turn in args.turns:
                turned = RigidTransform(RotationMatrix.MakeYRotation(math.radians(turn)))
                truth = tcp @ turned @ plan.held_in_tcp
                world.set_domino_poses({0: truth} | run_poses)
                frames = world.render(labels=False).values()
                views = [CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC) for f in frames]
                scenes.append(
                    {
                        "slot": slot,
                        "turn": turn,
                        "look": look,
                        "target": target.GetAsMatrix4(),
                        "truth": truth.GetAsMatrix4(),
                        "views": views,
                    }
                )
                print(
                    f"{args.layout} slot {slot} turn {turn:+.0f}° look {look:+.0f}°: rendered",
                    file=sys.stderr,
                )
    world.set_robot_positions()
    return scenes


def run(args: argparse.Namespace) -> dict:
    if args.scenes and os.path.exists(args.scenes):
        with open(args.scenes, "rb") as file:
            scenes = pickle.load(file)
    else:
        scenes = render(args)
        if args.scenes:
            with open(args.scenes, "wb") as file:
                pickle.dump(scenes, file)
    pipeline = build_pipeline(load_scenario())
    config = check.PlacementConfig(in_hand=True)
    rows, seen, seen_by, misread = [], Counter(), Counter(), 0
    looked: dict[tuple[int, float], dict[float, bool]] = {}  # (slot, turn) -> look -> seen
    for scene in scenes:
        views, look = scene["views"], scene.get("look", 0.0)
        [every] = check.check_placements([scene["target"]], views, pipeline, config)
        alone = {
            view.name: check.check_placements([scene["target"]], [view], pipeline, config)[0]
            for view in views
        }
        foot, tilt = foot_and_tilt(every.measured, scene["truth"])
        wrong = every.status == check.STANDING and (foot > 0.002 or tilt > math.radians(1.5))
        misread += wrong
        seen[look, scene["turn"]] += every.status == check.STANDING
        seen_by.update((look, n) for n, p in alone.items() if p.status == check.STANDING)
        looked.setdefault((scene["slot"], scene["turn"]), {})[look] = every.status == check.STANDING
        rows.append(
            {
                "slot": scene["slot"],
                "turn": scene["turn"],
                "look": look,
                "every camera": STATUS.get(every.status, every.status),
                "seen by": [name for name, p in alone.items() if p.status == check.STANDING],
                "foot mm, tilt deg": [round(foot * 1e3, 2), round(math.degrees(tilt), 2)],
            }
        )
    looks = sorted({look for look, _ in seen})
    hidden = [looks_of for looks_of in looked.values() if not looks_of.get(0.0, True)]
    return {
        "benchmark": "in_hand_planned",
        "scenes": len(scenes),
        "seen, by look and turn": {
            f"{look:+.0f}°": {
                f"{turn:+.0f}°": n for (lk, turn), n in sorted(seen.items()) if lk == look
            }
            for look in looks
        },
        "seen, by look": {
            f"{look:+.0f}°": sum(n for (lk, _), n in seen.items() if lk == look) for look in looks
        },
        "seen by each camera alone, by look": {
            f"{look:+.0f}°": {name: n for (lk, name), n in sorted(seen_by.items()) if lk == look}
            for look in looks
        },
        "not seen as planned": len(hidden),
        "of them seen from each look": {
            f"{look:+.0f}°": sum(looks_of.get(look, False) for looks_of in hidden) for look in looks
        },
        "misread": misread,
        "rows": rows,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--layout", default="s_curve30", choices=LAYOUTS)
    parser.add_argument("--slots", type=int, nargs="+", default=list(range(10, 25)))
    parser.add_argument("--turns", type=float, nargs="+", default=[-6.0, 0.0, 6.0])
    parser.add_argument(
        "--looks", type=float, nargs="+", default=[0.0], help="° the arm's base turned"
    )
    parser.add_argument("--pile-yaw", type=float, default=0.3, help="rad")
    parser.add_argument("--scenes", help="pickle of the renders: read if it exists, else written")
    print(json.dumps(run(parser.parse_args()), indent=1))


if __name__ == "__main__":
    main()

"""What the placement check answers for two flat dominoes lying long side to long side,
looked at again where a box was fitted across a half of each (``side_by_side``; arc
cycles seed 1: three picks closed on nothing over such a pair).

For each of ``--yaws`` (deg) and each of ``--places`` (positions along a run in front of
the build cameras), the pair is rendered by the placement cameras (camera_2, camera_3)
and ``check_placements`` asked about the box across them (turned 90° at the pair's
centre); and, as a control, about one domino lying alone where it lies (it must stay
fitted). Prints one JSON object on stdout: per case the answers counted as ``right``
(within ``--tolerance`` mm and 5° of a domino of the pair, or of the lone one),
``unfitted`` (down, no pose: an obstacle, never picked) or ``wrong`` (a pose off both).
"""

from __future__ import annotations

import argparse
import json
import sys

import numpy as np

from dombot_description.grasp import flat_pose
from dombot_description.scenario import load_scenario
from dombot_perception.frames import CameraView
from dombot_perception.pipeline import build_pipeline
from dombot_perception.placement_check import PlacementConfig, check_placements
from dombot_sim.world import CellWorld, WorldConfig

HEADING = 0.4  # rad: the run the places lie along (tests/perception's)
START, SPACING = np.array([0.50, 0.12]), 0.0288  # m
HALF_WIDTH = 0.012  # m
CAMERAS = ["camera_2", "camera_3"]


def pair_at(centre: np.ndarray, yaw: float, gap: float) -> list[np.ndarray]:
    """Two flat dominoes turned ``yaw``, long side to long side ``gap`` apart."""
    across = np.array([-np.sin(yaw), np.cos(yaw)]) * (HALF_WIDTH + gap / 2)
    return [flat_pose(*(centre + s * across), yaw).GetAsMatrix4() for s in (1.0, -1.0)]


def verdict(answer, asked: np.ndarray, truths: list[np.ndarray], tolerance: float) -> str:
    if answer.measured is asked:
        return "unfitted"
    for truth in truths:
        off = np.linalg.norm(answer.measured[:2, 3] - truth[:2, 3])
        turn = np.degrees(np.arccos(min(1.0, abs(answer.measured[:3, 0] @ truth[:3, 0]))))
        if off < tolerance and turn < 5.0:
            return "right"
    return "wrong"


def main() -> int:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--yaws", type=float, nargs="+", default=list(range(0, 180, 15)))
    parser.add_argument("--places", type=int, nargs="+", default=[0, 2, 4])
    parser.add_argument("--gap", type=float, default=0.2, help="mm between the pair")
    parser.add_argument("--tolerance", type=float, default=3.0, help="mm")
    args = parser.parse_args()
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=2))
    pipeline = build_pipeline(load_scenario())
    step = SPACING * np.array([np.cos(HEADING), np.sin(HEADING)])
    counts = {case: dict.fromkeys(("right", "unfitted", "wrong"), 0) for case in ("pair", "lone")}
    for yaw in np.radians(args.yaws):
        for place in args.places:
            centre = START + place * step
            pair = pair_at(centre, yaw, args.gap * 1e-3)
            across = flat_pose(*centre, yaw + np.pi / 2).GetAsMatrix4()
            lone = pair[0]
            for case, dominoes, asked in (("pair", pair, across), ("lone", [lone], lone)):
                world.set_domino_poses(dict(enumerate(dominoes)))
                views = [
                    CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC)
                    for f in world.render(CAMERAS).values()
                ]
                [answer] = check_placements([asked], views, pipeline, PlacementConfig())
                said = verdict(answer, asked, dominoes, args.tolerance * 1e-3)
                counts[case][said] += 1
                print(f"{case} yaw {np.degrees(yaw):.0f} place {place}: {said}", file=sys.stderr)
    print(json.dumps({"scenes": len(args.yaws) * len(args.places), **counts}))
    return 0


if __name__ == "__main__":
    sys.exit(main())

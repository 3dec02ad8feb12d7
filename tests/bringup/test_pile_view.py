"""The look at the pile made while the arm places (``placing.pile_in_view``,
``settings.look_while_placing``): asked at every slot of the benchmarks' S-curve, and, at
the nearest slot it is asked at, as perception's look with the arm at home (Drake renders
of the pile cameras, ``benchmarks/bench_pile_view.py``'s measure)."""

from __future__ import annotations

import math

import numpy as np
import pytest

from dombot_bringup import layouts
from dombot_bringup.task.placing import pile_in_view
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from support.benchmarks import load_benchmark
from support.scripted_cell import ScriptedCell

# a hand-laid pile: flat dominoes (x, y, yaw) at its centre and out to the edge of
# perception's pile region (0.21 m) on the build area's side, where the arm places
PILE = (
    (0.55, -0.30, 0.3),
    (0.60, -0.26, 1.2),
    (0.50, -0.24, -0.5),
    (0.55, -0.19, 0.0),
    (0.62, -0.16, 2.0),
    (0.48, -0.14, 0.8),
    (0.55, -0.12, 1.6),
)


def test_every_slot_of_the_s_curve_is_placed_with_the_pile_looked_at() -> None:
    """The S-curve of docs/SPEED.md's table starts 0.235 m from the pile's centre: at 0.32 m
    its slots 1-3 had no look while placing, and nothing planned ahead for slots 2-4."""
    start, heading, length, amplitude, count = load_benchmark("bench_pile_view").S_CURVE
    layout = layouts.s_curve(start, math.radians(heading), length, amplitude, count)
    job = Job.new(ScriptedCell(), layout, "s-curve", ArmJobSettings())
    assert [i + 1 for i in range(count) if not pile_in_view(job, i)] == []


@pytest.fixture(scope="module")
def pile_view():
    """The bench module, a world with the pile cameras and the hand-laid pile (plus the
    domino to carry), and the planner."""
    from dombot_description.grasp import flat_pose
    from dombot_planner.planner import PickPlacePlanner
    from dombot_planner.settings import PlannerSettings
    from dombot_sim.world import CellWorld, WorldConfig

    world = CellWorld(WorldConfig(cameras=True, domino_capacity=len(PILE) + 1))
    pile = {i: flat_pose(*spot).GetAsMatrix4() for i, spot in enumerate(PILE)}
    carried = len(PILE)  # lying off the pile, as a pile domino picked would be carried
    pile[carried] = flat_pose(0.45, 0.20, 0.4).GetAsMatrix4()
    planner = PickPlacePlanner(world.scenario, PlannerSettings())
    return load_benchmark("bench_pile_view"), world, pile, carried, planner


@pytest.mark.parametrize("bearing", [60.0, 90.0, 120.0])  # deg from +x: the build area
def test_the_nearest_slot_looked_at_leaves_the_pile_as_seen_from_home(
    pile_view, bearing: float
) -> None:
    """Held above the slot, down the descent, at the release and after the retreat, the
    arm hides none of the pile from camera_0 and camera_1 and brings nothing into
    perception's pile region: the same detections, no new obstacle points."""
    from dombot_description.grasp import upright_pose

    bench, world, pile, carried, planner = pile_view
    distance = ArmJobSettings().look_while_placing
    centre = np.asarray(world.scenario.pile_center)
    x, y = centre + distance * np.array(
        [math.cos(math.radians(bearing)), math.sin(math.radians(bearing))]
    )
    measured = bench.measure(world, planner, pile, [carried], upright_pose(x, y, math.pi / 2))
    assert measured is not None, "the carry to the slot was refused"
    assert measured["detected_at_home"] == len(PILE)
    for where, seen in measured["positions"].items():
        assert set(seen["pile_pixels_lost"].values()) == {0.0}, where
        assert (seen["detections_lost"], seen["detections_gained"]) == (0, 0), where
        assert seen["matched_moved_mm"] < 0.5, where
        assert seen["unexplained_points_gained"] <= 0, where

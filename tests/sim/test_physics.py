"""The physics claims of the simulated cell (issue 4): piles, standing, toppling, gripping.

The experiments live in ``dombot_sim.physics_checks`` (benchmarks/bench_sim.py prints
the same measurements for docs/SIM.md); these tests hold them to the issue's limits.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.math import SpatialVelocity

from dombot_bringup.layouts import DEFAULT_SPACING_RATIO
from dombot_description import DOMINO_SIZE, tilt_from_vertical
from dombot_planner.settings import PlannerSettings
from dombot_sim.physics_checks import (
    grip_and_swing,
    push_over,
    stand_line,
    stand_upright,
    tilt_crossings,
    topple_line,
    upright_rotation,
)
from dombot_sim.sleeping import SleepSettings
from dombot_sim.wave_model import Row, wave
from dombot_sim.world import CellWorld, WorldConfig

pytestmark = pytest.mark.slow  # seconds to minutes of Drake physics per test

CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * (
    0.5 * np.asarray(DOMINO_SIZE)
)


def world_for(count: int, sleeping: bool = True) -> CellWorld:
    return CellWorld(
        WorldConfig(cameras=False, domino_capacity=count, sleep=SleepSettings(enabled=sleeping))
    )


@pytest.fixture(scope="module")
def pile_world() -> CellWorld:
    world = world_for(30)
    world.reset(domino_count=30, seed=11)
    return world


def test_a_pile_of_30_settles_without_interpenetration(pile_world: CellWorld) -> None:
    truth = [d for d in pile_world.domino_truth() if d.in_use]
    assert len(truth) == 30
    assert all(d.asleep for d in truth)  # settled: every domino came to rest
    depth, where = pile_world.deepest_penetration()
    assert depth < 0.5e-3, f"{depth * 1e3:.3f} mm between {where}"
    for domino in truth:
        lowest = (domino.X_WD[:3, :3] @ CORNERS.T)[2].min() + domino.X_WD[2, 3]
        assert lowest > -0.5e-3, f"{domino.name} is {-lowest * 1e3:.2f} mm inside the table"
        assert domino.X_WD[2, 3] < 0.2  # nothing left hanging where it was poured from


def test_the_same_seed_gives_the_same_pile_and_another_seed_another() -> None:
    def pile(seed: int) -> np.ndarray:
        world = world_for(8)
        world.reset(domino_count=8, seed=seed)
        return np.array([d.X_WD for d in world.domino_truth()])

    first, again, other = pile(5), pile(5), pile(6)
    assert np.abs(first - again).max() < 1e-9
    assert np.abs(first[:, :3, 3] - other[:, :3, 3]).max() > 0.01


@pytest.mark.parametrize("sleeping", [True, False], ids=["sleeping", "always-awake"])
def test_an_upright_domino_stands_still_for_10_s(sleeping: bool) -> None:
    standing = stand_upright(world_for(1, sleeping), seconds=10.0)
    assert standing.drift < 0.5e-3, f"drifted {standing.drift * 1e3:.3f} mm"
    assert standing.tilt < np.radians(0.5)


@pytest.mark.parametrize("sleeping", [True, False], ids=["sleeping", "always-awake"])
def test_a_line_of_10_at_60_percent_spacing_topples_completely(sleeping: bool) -> None:
    tilts = np.degrees(topple_line(world_for(10, sleeping), count=10, spacing_ratio=0.6))
    assert tilts.size == 10
    assert tilts.min() > 60.0, f"tilts from vertical: {np.round(tilts, 1)}"


def test_a_run_of_10_at_the_default_spacing_topples_in_the_time_the_wave_model_predicts() -> None:
    """issue 27: van Leeuwen's model (dombot_sim.wave_model) with the simulator's domino
    friction (0.4) and the bring-up's strike; simulated time, ±25 %."""
    height, _, thickness = DOMINO_SIZE
    pitch = DEFAULT_SPACING_RATIO * height
    settings = PlannerSettings()
    spin = settings.push_speed / (settings.strike_height * height)  # the strike's tilt rate
    threshold = np.radians(2.0)
    world = world_for(10)
    push_over(world, stand_line(world, 10, pitch, np.array([0.65, -0.13]), np.pi / 2), spin)

    crossed = tilt_crossings(world, 10, threshold, limit=3.0)
    world.advance(0.3)

    predicted = wave(Row(height, thickness, pitch, mu=0.4), spin, 10, threshold).crossings
    assert not np.isnan(crossed).any(), f"never tipped: {np.flatnonzero(np.isnan(crossed))}"
    assert crossed[-1] == pytest.approx(predicted[-1], rel=0.25), (
        f"last domino tipped {crossed[-1]:.3f} s after the strike, model {predicted[-1]:.3f} s"
    )
    tilts = [np.degrees(tilt_from_vertical(d.X_WD)) for d in world.domino_truth()]
    assert min(tilts) > 60.0, f"tilts from vertical: {np.round(tilts, 1)}"


def test_a_gripped_domino_does_not_slip_during_a_1_m_per_s_move() -> None:
    swing = grip_and_swing(world_for(1))
    assert swing.opening == pytest.approx(DOMINO_SIZE[1], abs=0.5e-3)  # closed on the domino
    assert swing.peak_tcp_speed > 1.0, f"the move peaked at {swing.peak_tcp_speed:.2f} m/s"
    assert swing.slip < 1e-3, f"the domino slipped {swing.slip * 1e3:.2f} mm in the fingers"


def test_a_diverged_step_is_redone_and_reported_instead_of_ending_the_simulation() -> None:
    world = world_for(1)
    heard: list[str] = []
    world.trouble_listener = heard.append
    start = RigidTransform(upright_rotation(0.4), [0.55, 0.15, DOMINO_SIZE[0] / 2])
    world.set_domino_poses({0: start})
    world.advance(0.1)
    world.kick_domino(0, SpatialVelocity(np.zeros(3), [1e7, 0.0, 0.0]))  # an exploded contact

    world.advance(0.5)

    assert world.divergences == 1
    assert len(heard) == 1 and "domino_0" in heard[0]
    pose = world.domino_truth()[0].X_WD
    assert np.linalg.norm(pose[:3, 3] - start.translation()) < 1e-3  # stopped where it stood


def test_a_domino_that_leaves_the_cell_is_removed_not_left_falling_for_ever() -> None:
    """Falling for ever (no floor under the table), one ran into the divergence check and
    the simulator ended (S-curve seed 3)."""
    world = world_for(2)
    heard: list[str] = []
    world.trouble_listener = heard.append
    on_table = RigidTransform(upright_rotation(0.4), [0.55, 0.15, DOMINO_SIZE[0] / 2])
    world.set_domino_poses({0: on_table, 1: RigidTransform([0.55, 0.25, 0.05])})
    world.kick_domino(1, SpatialVelocity(np.zeros(3), [0.0, 40.0, 0.0]))  # off its edge

    world.advance(1.0)

    assert world.domino_count == 1 and world.divergences == 0
    assert len(heard) == 1 and heard[0].startswith("domino_1 left the cell")
    truth = world.domino_truth()
    assert truth[0].in_use and not truth[1].in_use
    assert np.linalg.norm(truth[0].X_WD[:3, 3] - on_table.translation()) < 1e-3


def test_a_cell_without_dominoes_steps() -> None:
    """sim_node starts with none (the watch for dominoes leaving the cell once broke it)."""
    world = world_for(0)
    world.advance(0.01)
    assert world.time == pytest.approx(0.01) and world.domino_count == 0

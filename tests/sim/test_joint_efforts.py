"""/joint_states efforts: computed by ``CellWorld`` from the controllers, not read from the
plant's net actuation port (with live output ports that re-solves a step)."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.trajectories import PiecewisePolynomial

from dombot_sim.world import CellWorld, WorldConfig


def step_actuation(world: CellWorld) -> np.ndarray:
    """The plant's net actuation over the step from now (its PD implicit), arm then fingers."""
    plant, context = world._plant, world._plant_context
    models = (world._models.arm, world._models.gripper)
    return np.concatenate([plant.get_net_actuation_output_port(m).Eval(context) for m in models])


@pytest.fixture(scope="module")
def world() -> CellWorld:
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=0, skip_still=False))
    world.advance(0.5)
    return world


def test_a_holding_arm_reports_the_torques_the_plant_applies(world: CellWorld) -> None:
    effort = world.joint_state().effort
    assert np.abs(effort[:7]).max() > 1.0  # gravity is held
    np.testing.assert_allclose(effort, step_actuation(world), atol=1e-3)


def test_a_swinging_arm_reports_them_to_within_one_step_of_the_command(world: CellWorld) -> None:
    home = world.scenario.home_position
    swing = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        [0.0, 1.0], np.column_stack([home, home + 0.5]), np.zeros(7), np.zeros(7)
    )
    world.follow_trajectory(swing)
    largest = 0.0
    for _ in range(20):
        world.advance(0.05)
        largest = max(largest, np.abs(world.joint_state().effort - step_actuation(world)).max())
    # the implicit PD acts at the step's end: stiffness x command speed x step, ~2-3 N·m
    assert 0.0 < largest < 5.0

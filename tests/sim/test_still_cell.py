"""While nothing in the cell moves, the clock advances without physics steps: the state
stays exactly as it was, and a command to move, or a domino woken, steps again."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialVelocity
from pydrake.trajectories import PiecewisePolynomial

from dombot_description import DOMINO_SIZE
from dombot_description.cell import build_shadow_plant
from dombot_sim.physics_checks import tcp_ik
from dombot_sim.world import CellWorld, WorldConfig

PILE = 5  # dominoes: a small settled pile, every one asleep


def state(world: CellWorld) -> np.ndarray:
    """Every joint position and velocity and every domino pose, as one vector."""
    joints = world.joint_state()
    poses = [truth.X_WD.ravel() for truth in world.domino_truth()]
    return np.concatenate([joints.position, joints.velocity, *poses])


@pytest.fixture(scope="module")
def world() -> CellWorld:
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=PILE))
    assert world.reset(PILE, seed=2).settled
    world.advance(1.0)  # the arm and fingers come to rest at home
    return world


def test_a_still_cell_advances_its_clock_and_nothing_else(world: CellWorld) -> None:
    assert world.still()
    before, start, skipped = state(world), world.time, world.skipped_time

    world.advance(2.0)

    assert world.time == pytest.approx(start + 2.0)
    assert world.skipped_time - skipped == pytest.approx(2.0)
    np.testing.assert_array_equal(state(world), before)  # asleep dominoes, arm, fingers
    assert all(t.asleep for t in world.domino_truth() if t.in_use)


def test_stepping_a_still_cell_moves_nothing_that_skipping_leaves_out(world: CellWorld) -> None:
    """What a skip leaves out: stepped instead, the still cell moves less than 1e-6."""
    world.skip_still = False
    try:
        before, skipped = state(world), world.skipped_time
        world.advance(0.5)
        assert world.skipped_time == skipped  # stepped
        assert np.abs(state(world) - before).max() < 1e-6
    finally:
        world.skip_still = True


def test_a_trajectory_arriving_steps_the_arm_along_it_and_then_it_is_still_again(
    world: CellWorld,
) -> None:
    home = world.joint_state().position[:7]
    goal = home + np.array([0.2, 0.0, 0.0, -0.1, 0.0, 0.1, 0.0])
    trajectory = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        [0.0, 1.0], np.column_stack([home, goal]), np.zeros(7), np.zeros(7)
    )
    end = world.follow_trajectory(trajectory)
    assert not world.still()
    skipped = world.skipped_time

    world.advance_to(end)

    assert world.skipped_time == skipped  # every step simulated
    np.testing.assert_allclose(world.joint_state().position[:7], goal, atol=1e-3)
    world.advance(1.0)  # settles at its goal
    assert world.still()


def test_a_hold_elsewhere_pulls_the_arm_there_before_it_is_still(world: CellWorld) -> None:
    """A hold starts from rest: still, but for the command (the steps show the pull)."""
    home = world.scenario.home_position
    world.hold_arm(home)
    assert not world.still()

    world.advance(1.5)

    np.testing.assert_allclose(world.joint_state().position[:7], home, atol=1e-4)
    assert world.still()


def test_a_gripper_command_steps_the_fingers_to_their_goal(world: CellWorld) -> None:
    opening = world.gripper_state().opening
    world.command_gripper(opening - 0.03, 20.0)
    assert not world.still()
    skipped = world.skipped_time

    world.advance(0.5)

    assert world.skipped_time == skipped
    assert world.gripper_state().opening == pytest.approx(opening - 0.03, abs=1e-3)
    world.command_gripper(opening, 20.0)
    world.advance(1.0)
    assert world.still()


def test_a_woken_domino_is_simulated_until_it_sleeps_again(world: CellWorld) -> None:
    world.advance(0.1)
    assert world.still()
    index = next(t.index for t in world.domino_truth() if t.in_use)
    lift = world.domino_truth()[index].X_WD[2, 3]
    world.kick_domino(index, SpatialVelocity(np.zeros(3), np.array([0.0, 0.0, 0.3])))
    assert not world.still()
    skipped = world.skipped_time

    world.advance(0.05)

    assert world.skipped_time == skipped
    assert world.domino_truth()[index].X_WD[2, 3] > lift + 1e-3  # it flew up
    assert world.settle(5.0)
    world.advance(1.0)
    assert world.still()


def test_a_domino_held_in_a_still_hand_is_still_and_carried_on_once_the_arm_moves() -> None:
    """The in-hand check's wait: the arm holds a domino above the table. Once it has
    rested in the fingers, only the clock moves (the grip's creep is not simulated);
    moved again, the arm carries it on in the same grip."""
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=1))
    scenario = world.scenario
    pick = RigidTransform(RotationMatrix.MakeZRotation(0.3), [0.55, -0.12, DOMINO_SIZE[2] / 2])
    world.set_domino_poses({0: pick})
    assert world.settle(2.0)
    shadow = build_shadow_plant(scenario, grasp_opening=DOMINO_SIZE[1])
    context = shadow.plant.CreateDefaultContext()
    grip = pick.rotation() @ RotationMatrix.MakeXRotation(np.pi)
    x, y = pick.translation()[:2]

    def to(z: float, seed: np.ndarray, duration: float = 1.0) -> np.ndarray:
        goal = tcp_ik(shadow, context, RigidTransform(grip, [x, y, z]), seed)
        start = world.joint_state().position[:7]
        trajectory = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
            [0.0, duration], np.column_stack([start, goal]), np.zeros(7), np.zeros(7)
        )
        world.advance_to(world.follow_trajectory(trajectory) + 0.1)
        return goal

    above = to(0.10, scenario.home_position, 1.5)
    down = to(0.0135, above)
    world.command_gripper(0.0, 20.0)
    world.advance(1.0)
    lifted = to(0.12, down)
    held_at = world.domino_truth()[0].X_WD[2, 3]
    assert held_at > 0.09  # in the hand

    world.advance(0.5)  # the hold settles, the domino rests in the fingers
    assert world.still()
    before, skipped = state(world), world.skipped_time
    world.advance(2.0)
    assert world.skipped_time - skipped == pytest.approx(2.0)
    np.testing.assert_array_equal(state(world), before)
    assert not world.domino_truth()[0].asleep  # awake: held, not locked

    to(0.16, lifted)
    assert world.domino_truth()[0].X_WD[2, 3] == pytest.approx(held_at + 0.04, abs=1e-3)

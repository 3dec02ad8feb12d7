"""The physics claims of the simulated cell (issue 4): piles, standing, toppling, gripping.

Each test drives the ROS-free ``CellWorld`` the way ``sim_node`` does; the figures
they check are recorded in docs/SIM.md.
"""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.math import SpatialVelocity
from pydrake.solvers import Solve
from pydrake.trajectories import PiecewisePolynomial

from dombot_description import DOMINO_SIZE
from dombot_description.cell import build_shadow_plant
from dombot_sim.sleeping import SleepSettings
from dombot_sim.world import CellWorld, WorldConfig

HEIGHT = DOMINO_SIZE[0]


def upright_rotation(heading: float) -> RotationMatrix:
    """Body x up, body z along the run (the layouts' convention)."""
    tangent = np.array([np.cos(heading), np.sin(heading), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    return RotationMatrix(np.column_stack([up, np.cross(tangent, up), tangent]))


def tilt_from_vertical(pose: np.ndarray) -> float:
    """Angle [rad] between the domino's length axis and the vertical."""
    return float(np.arccos(min(1.0, abs(pose[2, 0]))))


@pytest.fixture(scope="module")
def pile_world() -> CellWorld:
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=30))
    world.reset(domino_count=30, seed=11)
    return world


def test_a_pile_of_30_settles_without_interpenetration(pile_world: CellWorld) -> None:
    truth = [d for d in pile_world.domino_truth() if d.in_use]
    assert len(truth) == 30
    assert all(d.asleep for d in truth)  # settled: every domino came to rest
    depth, where = pile_world.deepest_penetration()
    assert depth < 0.5e-3, f"{depth * 1e3:.3f} mm between {where}"
    half_diagonal = 0.5 * np.linalg.norm(DOMINO_SIZE)
    for domino in truth:
        corners = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)]) * (
            0.5 * np.asarray(DOMINO_SIZE)
        )
        lowest = (domino.X_WD[:3, :3] @ corners.T)[2].min() + domino.X_WD[2, 3]
        assert lowest > -0.5e-3, f"{domino.name} is {-lowest * 1e3:.2f} mm inside the table"
        assert domino.X_WD[2, 3] < 0.25 + half_diagonal  # nothing left hanging in the air


def test_the_same_seed_gives_the_same_pile_and_another_seed_another() -> None:
    def pile(seed: int) -> np.ndarray:
        world = CellWorld(WorldConfig(cameras=False, domino_capacity=8))
        world.reset(domino_count=8, seed=seed)
        return np.array([d.X_WD for d in world.domino_truth()])

    first, again, other = pile(5), pile(5), pile(6)
    assert np.abs(first - again).max() < 1e-9
    assert np.abs(first[:, :3, 3] - other[:, :3, 3]).max() > 0.01


@pytest.mark.parametrize("sleeping", [True, False], ids=["sleeping", "always-awake"])
def test_an_upright_domino_stands_still_for_10_s(sleeping: bool) -> None:
    world = CellWorld(
        WorldConfig(cameras=False, domino_capacity=1, sleep=SleepSettings(enabled=sleeping))
    )
    start = RigidTransform(upright_rotation(0.4), [0.55, 0.15, HEIGHT / 2])
    world.set_domino_poses({0: start})
    world.advance(10.0)
    (domino,) = [d for d in world.domino_truth() if d.in_use]
    drift = np.linalg.norm(domino.X_WD[:3, 3] - start.translation())
    assert drift < 0.5e-3, f"drifted {drift * 1e3:.3f} mm"
    assert tilt_from_vertical(domino.X_WD) < np.radians(0.5)


@pytest.mark.parametrize("sleeping", [True, False], ids=["sleeping", "always-awake"])
def test_a_line_of_10_at_60_percent_spacing_topples_completely(sleeping: bool) -> None:
    world = CellWorld(
        WorldConfig(cameras=False, domino_capacity=10, sleep=SleepSettings(enabled=sleeping))
    )
    spacing, heading = 0.6 * HEIGHT, 0.3
    direction = np.array([np.cos(heading), np.sin(heading), 0.0])
    start = np.array([0.42, 0.05, HEIGHT / 2])
    world.set_domino_poses(
        {
            i: RigidTransform(upright_rotation(heading), start + i * spacing * direction)
            for i in range(10)
        }
    )
    world.advance(1.0)  # stands; with sleeping on, every domino is asleep by now
    assert not any(tilt_from_vertical(d.X_WD) > np.radians(1) for d in world.domino_truth())
    # Push the first one over its front edge: 6 rad/s about the edge it pivots on.
    spin = 6.0
    axis = np.cross([0.0, 0.0, 1.0], direction)
    lever = np.array([*(DOMINO_SIZE[2] / 2 * direction[:2]), HEIGHT / 2])
    world.kick_domino(0, SpatialVelocity(spin * axis, spin * np.cross(axis, lever)))
    world.advance(2.0)
    tilts = [np.degrees(tilt_from_vertical(d.X_WD)) for d in world.domino_truth()]
    assert min(tilts) > 60.0, f"tilts from vertical: {np.round(tilts, 1)}"


def _ik(shadow, context, pose: RigidTransform, seed: np.ndarray) -> np.ndarray:
    plant = shadow.plant
    ik = InverseKinematics(plant, context)
    tcp = plant.GetFrameByName("wsg_tcp")
    ik.AddPositionConstraint(
        tcp, np.zeros(3), plant.world_frame(), pose.translation() - 1e-5, pose.translation() + 1e-5
    )
    ik.AddOrientationConstraint(tcp, RotationMatrix(), plant.world_frame(), pose.rotation(), 1e-4)
    ik.prog().AddQuadraticErrorCost(np.eye(7), seed, ik.q())
    ik.prog().SetInitialGuess(ik.q(), seed)
    result = Solve(ik.prog())
    assert result.is_success(), f"no IK for {pose.translation()}"
    return result.GetSolution(ik.q())


def _move(world: CellWorld, start: np.ndarray, goal: np.ndarray, duration: float) -> None:
    trajectory = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        [0.0, duration], np.column_stack([start, goal]), np.zeros(7), np.zeros(7)
    )
    world.advance_to(world.follow_trajectory(trajectory) + 0.1)


def test_a_gripped_domino_does_not_slip_during_a_1_m_per_s_move() -> None:
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=1))
    shadow = build_shadow_plant(world.scenario, grasp_opening=0.024)
    context = shadow.plant.CreateDefaultContext()
    domino = RigidTransform(RotationMatrix.MakeZRotation(0.3), [0.55, 0.0, DOMINO_SIZE[2] / 2])
    world.set_domino_poses({0: domino})
    # Gripper pointing down, fingers across the domino's width, pad tips 4.5 mm above the table.
    grip = domino.rotation() @ RotationMatrix.MakeXRotation(np.pi)
    above = _ik(
        shadow, context, RigidTransform(grip, [0.55, 0.0, 0.10]), world.scenario.home_position
    )
    at_grasp = _ik(shadow, context, RigidTransform(grip, [0.55, 0.0, 0.0135]), above)
    _move(world, world.scenario.home_position, above, 2.0)
    _move(world, above, at_grasp, 1.5)
    world.command_gripper(0.0, max_force=20.0)
    world.advance(1.2)
    assert world.gripper_state().opening == pytest.approx(DOMINO_SIZE[1], abs=0.5e-3)
    held = world.domino_in_tcp(0)
    lifted = _ik(shadow, context, RigidTransform(grip, [0.55, 0.0, 0.15]), at_grasp)
    far = _ik(
        shadow,
        context,
        RigidTransform(grip @ RotationMatrix.MakeZRotation(0.5), [0.40, 0.35, 0.25]),
        lifted,
    )
    _move(world, at_grasp, lifted, 1.0)
    trajectory = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        [0.0, 0.6], np.column_stack([lifted, far]), np.zeros(7), np.zeros(7)
    )
    end = world.follow_trajectory(trajectory)
    fastest, slip = 0.0, 0.0
    while world.time < end + 0.2:
        world.advance(0.004)
        fastest = max(fastest, world.tcp_speed())
        slip = max(slip, np.linalg.norm(world.domino_in_tcp(0)[:3, 3] - held[:3, 3]))
    assert fastest > 1.0, f"the move peaked at {fastest:.2f} m/s"
    assert slip < 1e-3, f"the domino slipped {slip * 1e3:.2f} mm in the fingers"

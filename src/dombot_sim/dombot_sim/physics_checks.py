"""The physics experiments the simulator must pass, as functions that return measurements.

tests/sim/test_physics.py asserts the issue's thresholds on them and
benchmarks/bench_sim.py prints the numbers recorded in docs/SIM.md, so both run the
very same experiment.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.multibody.math import SpatialVelocity
from pydrake.solvers import Solve
from pydrake.trajectories import PiecewisePolynomial

from dombot_description import DOMINO_SIZE, tilt_from_vertical
from dombot_description.cell import build_shadow_plant
from dombot_sim.world import CellWorld

HEIGHT, WIDTH, THICKNESS = DOMINO_SIZE
PUSH_SPIN = 6.0  # rad/s about the front bottom edge: enough to tip the first domino over


def upright_rotation(heading: float) -> RotationMatrix:
    """Body x up, body z along the run (the layouts' convention)."""
    tangent = np.array([np.cos(heading), np.sin(heading), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    return RotationMatrix(np.column_stack([up, np.cross(tangent, up), tangent]))


@dataclass(frozen=True)
class Standing:
    drift: float  # m the centre moved
    tilt: float  # rad from vertical at the end


def stand_upright(world: CellWorld, seconds: float) -> Standing:
    """Stand one domino upright on the table and let it be for ``seconds``."""
    start = RigidTransform(upright_rotation(0.4), [0.55, 0.15, HEIGHT / 2])
    world.set_domino_poses({0: start})
    world.advance(seconds)
    pose = world.domino_truth()[0].X_WD
    return Standing(
        float(np.linalg.norm(pose[:3, 3] - start.translation())), tilt_from_vertical(pose)
    )


def stand_line(
    world: CellWorld, count: int, pitch: float, start: np.ndarray, heading: float
) -> np.ndarray:
    """Stand ``count`` dominoes ``pitch`` apart from ``start`` (x, y) along ``heading`` and
    let them settle for 1 s; returns the run's direction (unit, world)."""
    height = world.config.domino_size[0]
    direction = np.array([np.cos(heading), np.sin(heading), 0.0])
    first = np.array([start[0], start[1], height / 2])
    world.set_domino_poses(
        {
            i: RigidTransform(upright_rotation(heading), first + i * pitch * direction)
            for i in range(count)
        }
    )
    world.advance(1.0)
    if max(tilt_from_vertical(d.X_WD) for d in world.domino_truth() if d.in_use) > np.radians(1):
        raise RuntimeError("the run did not stand still before the push")
    return direction


def push_over(world: CellWorld, direction: np.ndarray, spin: float) -> None:
    """Set domino 0 turning at ``spin`` rad/s about its front bottom edge (tipping it along
    ``direction``)."""
    height, _, thickness = world.config.domino_size
    axis = np.cross([0.0, 0.0, 1.0], direction)
    lever = np.array([*(thickness / 2 * direction[:2]), height / 2])  # edge to centre
    world.kick_domino(0, SpatialVelocity(spin * axis, spin * np.cross(axis, lever)))


def topple_line(world: CellWorld, count: int, spacing_ratio: float) -> np.ndarray:
    """A straight run at ``spacing_ratio`` × height; push the first over; tilts [rad] after 2 s."""
    direction = stand_line(world, count, spacing_ratio * HEIGHT, np.array([0.42, 0.05]), 0.3)
    push_over(world, direction, PUSH_SPIN)
    world.advance(2.0)
    return np.array([tilt_from_vertical(d.X_WD) for d in world.domino_truth() if d.in_use])


def tilt_crossings(
    world: CellWorld, count: int, threshold: float, limit: float, stall: float = 1.0
) -> np.ndarray:
    """Advance until all ``count`` dominoes passed ``threshold`` tilt [rad], for at most
    ``limit`` s, or until none passed it for ``stall`` s (the wave stopped); each one's
    crossing time from now (linear between steps; NaN: never)."""
    start, crossed = world.time, np.full(count, np.nan)
    step, before, last = world.config.time_step, np.zeros(count), 0.0
    while world.time - start < min(limit, last + stall) and np.isnan(crossed).any():
        world.advance(step)
        tilts = np.array([tilt_from_vertical(d.X_WD) for d in world.domino_truth()[:count]])
        new = np.isnan(crossed) & (tilts >= threshold)
        if new.any():
            fraction = (threshold - before[new]) / np.maximum(tilts[new] - before[new], 1e-12)
            crossed[new] = world.time - start - step * (1.0 - fraction)
            last = world.time - start
        before = tilts
    return crossed


@dataclass(frozen=True)
class GripSwing:
    opening: float  # m between the pads once closed
    peak_tcp_speed: float  # m/s during the swing
    slip: float  # m the domino moved in the TCP frame from grasp to the end of the swing


def tcp_ik(shadow, context, pose: RigidTransform, seed: np.ndarray) -> np.ndarray:
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
    if not result.is_success():
        raise RuntimeError(f"no IK for the TCP at {pose.translation()}")
    return result.GetSolution(ik.q())


def start_move(world: CellWorld, start: np.ndarray, goal: np.ndarray, duration: float) -> float:
    """Start a rest-to-rest move; returns its end time."""
    trajectory = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        [0.0, duration], np.column_stack([start, goal]), np.zeros(7), np.zeros(7)
    )
    return world.follow_trajectory(trajectory)


def grip_and_swing(world: CellWorld, force: float = 20.0) -> GripSwing:
    """Pinch a flat domino across its width, lift it and swing it at over 1 m/s."""
    shadow = build_shadow_plant(world.scenario, grasp_opening=WIDTH)
    context = shadow.plant.CreateDefaultContext()
    domino = RigidTransform(RotationMatrix.MakeZRotation(0.3), [0.55, 0.0, THICKNESS / 2])
    world.set_domino_poses({0: domino})
    # Gripper pointing down, fingers across the width, pad tips 4.5 mm above the table.
    grip = domino.rotation() @ RotationMatrix.MakeXRotation(np.pi)
    home = world.scenario.home_position
    above = tcp_ik(shadow, context, RigidTransform(grip, [0.55, 0.0, 0.10]), home)
    at_grasp = tcp_ik(shadow, context, RigidTransform(grip, [0.55, 0.0, 0.0135]), above)
    lifted = tcp_ik(shadow, context, RigidTransform(grip, [0.55, 0.0, 0.15]), at_grasp)
    far_pose = RigidTransform(grip @ RotationMatrix.MakeZRotation(0.5), [0.40, 0.35, 0.25])
    far = tcp_ik(shadow, context, far_pose, lifted)
    world.advance_to(start_move(world, home, above, 2.0) + 0.1)
    world.advance_to(start_move(world, above, at_grasp, 1.5) + 0.1)
    world.command_gripper(0.0, max_force=force)
    world.advance(1.2)
    opening = world.gripper_state().opening
    held = world.domino_in_tcp(0)
    world.advance_to(start_move(world, at_grasp, lifted, 1.0) + 0.1)
    end = start_move(world, lifted, far, 0.6)
    fastest, slip = 0.0, 0.0
    while world.time < end + 0.2:
        world.advance(0.004)
        fastest = max(fastest, world.tcp_speed())
        slip = max(slip, float(np.linalg.norm(world.domino_in_tcp(0)[:3, 3] - held[:3, 3])))
    return GripSwing(opening, fastest, slip)

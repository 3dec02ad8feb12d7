"""The simulator's account of what the dominoes did during one motion (for its log)."""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialVelocity

from dombot_description import DOMINO_SIZE
from dombot_sim.motion_watch import Snapshot, describe_motion, take_snapshot
from dombot_sim.physics_checks import upright_rotation
from dombot_sim.sleeping import SleepSettings
from dombot_sim.world import CellWorld, WorldConfig

HEIGHT, _, THICKNESS = DOMINO_SIZE
MM = 1e-3


def pose(x: float, y: float, z: float = 0.0, yaw_deg: float = 0.0) -> np.ndarray:
    turn = RotationMatrix.MakeZRotation(np.radians(yaw_deg))
    return RigidTransform(turn, [x, y, z]).GetAsMatrix4()


def snapshot(tcp: np.ndarray, **dominoes: np.ndarray) -> Snapshot:
    return Snapshot(tcp, dominoes, {name: True for name in dominoes})


def test_still_and_barely_moved_dominoes_are_not_named() -> None:
    before = snapshot(pose(0.5, 0.0, 0.3), a=pose(0.5, 0.0), b=pose(0.6, 0.0))
    after = snapshot(pose(0.5, 0.2, 0.3), a=pose(0.5, 0.0004), b=pose(0.6, 0.0, yaw_deg=1.0))
    assert describe_motion(before, after, threshold=1 * MM) == []


def test_a_pushed_domino_is_named_with_how_far_it_moved_and_turned() -> None:
    before = snapshot(pose(0.5, 0.0, 0.3), a=pose(0.5, 0.0), b=pose(0.6, 0.0))
    after = snapshot(pose(0.5, 0.0, 0.3), a=pose(0.5, 0.0), b=pose(0.603, 0.004, yaw_deg=10))
    assert describe_motion(before, after, threshold=1 * MM) == ["b moved 5.0 mm / 10.0°"]


def test_a_carried_domino_is_named_only_when_it_shifted_in_the_hand() -> None:
    """Carried 0.3 m with the TCP: a 0.4 mm shift in the hand is quiet, 2 mm is named."""
    tcp_before, tcp_after = pose(0.5, 0.0, 0.10), pose(0.5, 0.3, 0.10, yaw_deg=30)
    held = pose(0.5, 0.0, 0.0)
    in_hand = np.linalg.inv(tcp_before) @ held
    for shift, expected in ((0.4 * MM, []), (2 * MM, ["a shifted 2.0 mm / 0.0° in the hand"])):
        after = tcp_after @ in_hand @ pose(shift, 0.0)
        moved = describe_motion(snapshot(tcp_before, a=held), snapshot(tcp_after, a=after), MM)
        assert moved == expected


def test_a_domino_that_left_the_cell_is_named() -> None:
    before = snapshot(pose(0.5, 0.0, 0.3), a=pose(0.5, 0.0))
    after = snapshot(pose(0.5, 0.0, 0.3))
    assert describe_motion(before, after, threshold=1 * MM) == ["a left the cell"]


def test_in_the_simulator_a_kicked_domino_is_told_to_have_fallen_and_its_neighbour_not() -> None:
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=2, sleep=SleepSettings()))
    standing = {
        i: RigidTransform(upright_rotation(0.0), [0.45, 0.1 * i, HEIGHT / 2]) for i in range(2)
    }
    world.set_domino_poses(standing)
    world.advance(0.5)
    before = take_snapshot(world)
    spin, lever = np.array([0.0, 6.0, 0.0]), np.array([THICKNESS / 2, 0.0, HEIGHT / 2])
    world.kick_domino(0, SpatialVelocity(spin, np.cross(spin, lever)))  # about its front edge
    world.advance(1.5)
    phrases = describe_motion(before, take_snapshot(world), threshold=1 * MM)
    assert len(phrases) == 1 and phrases[0].endswith(", fell"), phrases
    assert phrases[0].startswith(world.domino_truth()[0].name)

"""Inverse kinematics of the TCP pose (Drake InverseKinematics + SNOPT).

One program per target orientation is built and reused: the position bounds and the
"stay near this configuration" cost are updated per solve, which makes a solve ~1.5 ms
instead of ~5 ms. A solve is a pure function of its position, seed and target
configuration, so its answer is kept: a planning tier that asks again (the pads nudging
the pile after the tier that kept them clear) gets it without solving. The final
approach and retreat are straight lines solved this way at closely spaced waypoints,
each continuing from the previous solution.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import SnoptSolver

from dombot_planner.scene import Scene

POSITION_TOLERANCE = 1e-5  # m, checked by forward kinematics after each solve
ANGLE_TOLERANCE = 1e-4  # rad


class PoseIK:
    """IK for TCP poses with one fixed orientation; each solve sets a position."""

    def __init__(self, scene: Scene, rotation: RotationMatrix) -> None:
        self.scene = scene
        self.rotation = rotation
        plant = scene.plant
        self._ik = InverseKinematics(plant, scene.plant_context, with_joint_limits=True)
        self._position = self._ik.AddPositionConstraint(
            scene.tcp, np.zeros(3), plant.world_frame(), np.zeros(3), np.zeros(3)
        )
        self._ik.AddOrientationConstraint(
            plant.world_frame(), rotation, scene.tcp, RotationMatrix(), 0.0
        )
        self._q = self._ik.q()
        self._cost = self._ik.get_mutable_prog().AddQuadraticErrorCost(
            np.eye(len(self._q)), np.zeros(len(self._q)), self._q
        )
        self._solver = SnoptSolver()
        self._solved: dict[bytes, np.ndarray | None] = {}

    def solve(self, position: np.ndarray, seed: np.ndarray, near: np.ndarray) -> np.ndarray | None:
        """A configuration putting the TCP at ``position`` (closest to ``near``), or None."""
        key = np.concatenate([position, seed, near]).astype(float).tobytes()
        if key not in self._solved:
            self._solved[key] = self._solve(position, seed, near)
        q = self._solved[key]
        return None if q is None else q.copy()

    def _solve(self, position: np.ndarray, seed: np.ndarray, near: np.ndarray) -> np.ndarray | None:
        self._position.evaluator().set_bounds(position, position)
        self._cost.evaluator().UpdateCoefficients(2.0 * np.eye(len(near)), -2.0 * near, near @ near)
        result = self._solver.Solve(self._ik.prog(), seed)
        q = result.GetSolution(self._q)
        return q if self.reaches(q, RigidTransform(self.rotation, position)) else None

    def reaches(self, q: np.ndarray, pose: RigidTransform) -> bool:
        """Forward kinematics agrees with ``pose`` within the IK tolerances."""
        actual = self.scene.tcp_pose(q)
        angle = (actual.rotation().inverse() @ pose.rotation()).ToAngleAxis().angle()
        return (
            np.linalg.norm(actual.translation() - pose.translation()) <= POSITION_TOLERANCE
            and angle <= ANGLE_TOLERANCE
        )


def straight_line(
    ik: PoseIK,
    q_start: np.ndarray,
    start: np.ndarray,
    offset: np.ndarray,
    spacing: float,
    max_joint_step: float,
) -> np.ndarray | None:
    """Configurations moving the TCP from ``start`` by ``offset`` (fixed orientation).

    Waypoints every ``spacing`` metres, each solved from the previous one; None if a
    waypoint has no solution or the arm would jump (a joint moves more than
    ``max_joint_step`` between waypoints, e.g. a wrist flip).
    """
    count = max(2, int(np.ceil(np.linalg.norm(offset) / spacing)) + 1)
    path = [q_start]
    for fraction in np.linspace(0.0, 1.0, count)[1:]:
        q = ik.solve(start + fraction * offset, path[-1], path[-1])
        if q is None or np.max(np.abs(q - path[-1])) > max_joint_step:
            return None
        path.append(q)
    return np.array(path)

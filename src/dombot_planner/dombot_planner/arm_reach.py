"""What an arm configuration reaches, told without solving: the shell the wrist stays
in (``WristReach``), and the IK branches that swing the arm overhead (``faces_away``,
``elbow_not_up``)."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform

from dombot_description import DOMINO_SIZE
from dombot_description.cell import ShadowPlant, build_shadow_plant
from dombot_description.scenario import Scenario
from dombot_planner.scene import (
    Scene,
)

ELBOW_UP = 0.3  # the elbow's offset from the shoulder–wrist line points at least this up
STRAIGHT_ARM = 0.02  # m: an elbow this close to the shoulder–wrist line is left alone
REACH_TOLERANCE = 1e-4  # m a wrist point may lie outside WristReach's shell and still be tried


@dataclass(frozen=True)
class WristReach:
    """Where the arm can put its wrist: from ``near`` to ``far`` from its shoulder.

    The LBR iiwa's shoulder and wrist are spherical (axes 1-3 and 5-7 each meet in a
    point): the distance between the two points depends on the elbow (joint 4) alone, and
    the wrist point is fixed in the TCP frame. A TCP pose, or straight line, whose wrist
    point leaves that shell has no IK, which is told without solving: SNOPT takes longest
    to fail, ~10 times a solve (near the base, where the elbow's limit keeps the wrist
    0.41 m from the shoulder, most place candidates failed so).
    """

    shoulder: np.ndarray  # in world
    wrist_in_tcp: np.ndarray
    near: float
    far: float

    @classmethod
    def of(cls, scene: Scene, arm_joints: Sequence[str], q: np.ndarray) -> WristReach:
        """The shell of the arm in ``scene`` (joint limits from its plant), measured at
        ``q`` with the elbow bent to either limit and stretched; no shell (everything
        reaches) when its shoulder and wrist points are not where the iiwa has them."""
        plant, context = scene.plant, scene.plant_context
        joints = [plant.GetJointByName(name) for name in arm_joints]
        elbow = joints[3].position_start()
        low, high = plant.GetPositionLowerLimits()[elbow], plant.GetPositionUpperLimits()[elbow]

        def points(bend: float) -> tuple[np.ndarray, np.ndarray, float]:
            bent = np.array(q, dtype=float)
            bent[elbow] = bend
            scene.set_positions(bent)
            shoulder, wrist = (
                joints[i].child_body().EvalPoseInWorld(context).translation() for i in (1, 5)
            )
            tcp = scene.tcp.CalcPoseInWorld(context)
            return shoulder, tcp.inverse() @ wrist, float(np.linalg.norm(wrist - shoulder))

        measured = [points(bend) for bend in (low, high, float(np.clip(0.0, low, high)))]
        shoulder, wrist_in_tcp, _ = measured[0]
        if any(
            not (np.allclose(s, shoulder, atol=1e-9) and np.allclose(w, wrist_in_tcp, atol=1e-9))
            for s, w, _ in measured
        ):
            return cls(shoulder, wrist_in_tcp, 0.0, np.inf)
        return cls(shoulder, wrist_in_tcp, min(measured[0][2], measured[1][2]), measured[2][2])

    @classmethod
    def of_scenario(cls, scenario: Scenario, shadow: ShadowPlant | None = None) -> WristReach:
        """The shell of ``scenario``'s arm at its home position, measured on ``shadow``
        (default: a shadow plant built for it; any finger opening, only the arm counts)."""
        shadow = shadow or build_shadow_plant(scenario, DOMINO_SIZE[1])
        return cls.of(
            Scene(shadow, scenario.tcp_frame), scenario.arm_joints, scenario.home_position
        )

    def reaches(self, tcp: RigidTransform, offset: np.ndarray | None = None) -> bool:
        """Whether the wrist point stays in the shell (REACH_TOLERANCE outside passes) with
        the TCP at ``tcp`` and, given ``offset`` (world), all along a straight line moving
        it that far with the orientation kept."""
        start = tcp @ self.wrist_in_tcp - self.shoulder
        move = np.zeros(3) if offset is None else np.asarray(offset, dtype=float)
        along = move @ move
        closest = start + (np.clip(-(start @ move) / along, 0.0, 1.0) if along else 0.0) * move
        farthest = max(np.linalg.norm(start), np.linalg.norm(start + move))
        return bool(
            np.linalg.norm(closest) >= self.near - REACH_TOLERANCE
            and farthest <= self.far + REACH_TOLERANCE
        )


def faces_away(q: np.ndarray, position: np.ndarray) -> bool:
    """Whether the arm reaches ``position`` (world; the arm base at the origin) from
    behind: joint 1 turned away from it and the shoulder (joint 2) leaning backwards over
    the top. Moving between that branch and the usual one swings the arm overhead (the
    TCP up to 1.2-1.4 m at up to 2.7 m/s in the bring-up benchmarks, throwing held
    dominoes out of the cell); its elbow may point up or not."""
    azimuth = np.arctan2(position[1], position[0])
    return bool(q[1] < 0.0 and np.cos(q[0] - azimuth) < 0.0)


def elbow_not_up(scene: Scene, arm_joints: Sequence[str], q: np.ndarray) -> bool:
    """Whether the arm at ``q`` holds its elbow sideways or down: its offset from the line
    from shoulder (joint 2) to wrist (joint 6) points up less than ELBOW_UP (an arm
    stretched nearly straight has no elbow to speak of). Moving between such a branch
    and the usual elbow-up one swings the arm overhead: in one bring-up benchmark the
    elbow turned sideways (offset -0.01 up; the usual postures 0.54-1.0), the TCP rose
    to 0.69 m at 1.3 m/s and threw the held domino onto the run."""
    plant, context = scene.plant, scene.plant_context
    scene.set_positions(q)
    shoulder, elbow, wrist = (
        plant.GetJointByName(arm_joints[i]).child_body().EvalPoseInWorld(context).translation()
        for i in (1, 3, 5)
    )
    line = (wrist - shoulder) / np.linalg.norm(wrist - shoulder)
    offset = (elbow - shoulder) - ((elbow - shoulder) @ line) * line
    size = float(np.linalg.norm(offset))
    return size > STRAIGHT_ARM and offset[2] < ELBOW_UP * size

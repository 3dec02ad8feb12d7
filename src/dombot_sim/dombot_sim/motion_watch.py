"""What the dominoes did during one arm or gripper motion, in words for the simulator's log.

The bring-up decides from perception only; the simulator's log may say what really
happened, so a cascade during a carry, a domino pushed aside by an approaching pad (the
fingers then close on nothing) or a held domino shifting in the fingers (placed off
target) can be told from the log afterwards instead of guessed.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import TYPE_CHECKING

import numpy as np
from scipy.spatial.transform import Rotation

if TYPE_CHECKING:
    from dombot_sim.world import CellWorld

CARRIED = 0.02  # m: moved at least this far in the world, less than that in the TCP frame
TURNED = math.radians(2.0)  # a domino turned this much is named however little it moved


@dataclass(frozen=True)
class Snapshot:
    """The TCP and the dominoes in use at one instant (4x4 poses in world)."""

    tcp: np.ndarray
    dominoes: dict[str, np.ndarray]
    upright: dict[str, bool]


def take_snapshot(world: CellWorld) -> Snapshot:
    truths = [truth for truth in world.domino_truth() if truth.in_use]
    return Snapshot(
        tcp=world.tcp_pose(),
        dominoes={truth.name: truth.X_WD for truth in truths},
        upright={truth.name: truth.upright for truth in truths},
    )


def turned(before: np.ndarray, after: np.ndarray) -> float:
    """Angle [rad] of the rotation from one 4x4 pose's orientation to the other's."""
    return float(Rotation.from_matrix(before[:3, :3].T @ after[:3, :3]).magnitude())


def describe_motion(before: Snapshot, after: Snapshot, threshold: float) -> list[str]:
    """One phrase per domino that moved ``threshold`` [m] or more, or turned TURNED; one
    carried along with the TCP only when it shifted ``threshold`` or more in the hand."""
    phrases = []
    tcp_before_inv, tcp_after_inv = np.linalg.inv(before.tcp), np.linalg.inv(after.tcp)
    for name, pose in before.dominoes.items():
        if name not in after.dominoes:
            phrases.append(f"{name} left the cell")
            continue
        now = after.dominoes[name]
        moved = float(np.linalg.norm(now[:3, 3] - pose[:3, 3]))
        angle = turned(pose, now)
        in_hand_before, in_hand_after = tcp_before_inv @ pose, tcp_after_inv @ now
        shift = float(np.linalg.norm(in_hand_after[:3, 3] - in_hand_before[:3, 3]))
        if moved >= CARRIED and shift < CARRIED:
            if shift >= threshold:
                twist = math.degrees(turned(in_hand_before, in_hand_after))
                phrases.append(f"{name} shifted {shift * 1e3:.1f} mm / {twist:.1f}° in the hand")
            continue
        if moved < threshold and angle < TURNED:
            continue
        change = ""
        if before.upright[name] != after.upright[name]:
            change = ", fell" if before.upright[name] else ", stood up"
        phrases.append(f"{name} moved {moved * 1e3:.1f} mm / {math.degrees(angle):.1f}°{change}")
    return phrases

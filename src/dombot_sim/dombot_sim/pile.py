"""Seeded drop poses for a pile of dominoes poured onto the pile disc.

Dominoes are poured in waves, as a person tips them out of a box: each wave is a
set of poses in a thin slab above the current top of the pile whose bounding
spheres do not overlap, so no two dominoes start interpenetrating. The same seed
gives the same poses, hence (with a deterministic simulator) the same pile.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from scipy.spatial.transform import Rotation

from dombot_description import DOMINO_SIZE

BOUNDING_RADIUS = 0.5 * float(np.linalg.norm(DOMINO_SIZE))  # m, centre to corner
MAX_TRIES_PER_DOMINO = 400


@dataclass(frozen=True)
class PourSettings:
    """Where and how dominoes are poured (metres)."""

    center: tuple[float, float]
    radius: float  # of the disc the domino centres are drawn from
    drop_clearance: float = 0.02  # lowest centre above the current pile top
    slab_height: float = 0.12  # height of the slab each wave is drawn in
    wave_size: int = 6


def pour_wave(
    rng: np.random.Generator, count: int, settings: PourSettings, pile_top: float
) -> list[np.ndarray]:
    """``count`` non-overlapping 4x4 poses with uniformly random orientations.

    Raises ValueError when the slab is too crowded for ``count`` dominoes.
    """
    low = pile_top + settings.drop_clearance + BOUNDING_RADIUS
    centres: list[np.ndarray] = []
    for _ in range(count * MAX_TRIES_PER_DOMINO):
        if len(centres) == count:
            break
        radius = settings.radius * np.sqrt(rng.uniform())
        angle = rng.uniform(0.0, 2.0 * np.pi)
        candidate = np.array(
            [
                settings.center[0] + radius * np.cos(angle),
                settings.center[1] + radius * np.sin(angle),
                rng.uniform(low, low + settings.slab_height),
            ]
        )
        if all(np.linalg.norm(candidate - c) > 2.0 * BOUNDING_RADIUS for c in centres):
            centres.append(candidate)
    if len(centres) < count:
        raise ValueError(
            f"cannot fit {count} dominoes in one pour wave (got {len(centres)}); "
            "use smaller waves or a taller slab"
        )
    rotations = Rotation.random(count, random_state=rng).as_matrix()
    poses = []
    for centre, rotation in zip(centres, rotations, strict=True):
        pose = np.eye(4)
        pose[:3, :3] = rotation
        pose[:3, 3] = centre
        poses.append(pose)
    return poses


def wave_sizes(total: int, wave_size: int) -> list[int]:
    """Split ``total`` dominoes into waves of at most ``wave_size``."""
    if total < 0 or wave_size < 1:
        raise ValueError(f"need total >= 0 and wave_size >= 1, got {total}, {wave_size}")
    full, rest = divmod(total, wave_size)
    return [wave_size] * full + ([rest] if rest else [])


def parking_pose(index: int) -> np.ndarray:
    """Where an unused domino waits: flat on the floor beside the table, out of every view."""
    pose = np.eye(4)
    pose[:3, 3] = [-1.5 - 0.06 * (index % 20), -1.5 + 0.04 * (index // 20), -0.5]
    return pose

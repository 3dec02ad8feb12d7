"""Domino poses and rendered views for the perception tests."""

from __future__ import annotations

import numpy as np
from scipy.spatial.transform import Rotation

FLAT_HEIGHT = 0.00375  # m: centre of a domino lying flat on the table
PILE_CENTRE = (0.55, -0.30)  # m: the default scenario's pile centre


def domino_pose(position, rotation=None) -> np.ndarray:
    pose = np.eye(4)
    pose[:3, :3] = np.eye(3) if rotation is None else rotation
    pose[:3, 3] = position
    return pose


def flat(x: float, y: float, yaw: float) -> np.ndarray:
    """A domino lying flat on the table, body x turned ``yaw`` from world x."""
    return domino_pose((x, y, FLAT_HEIGHT), Rotation.from_euler("z", yaw).as_matrix())

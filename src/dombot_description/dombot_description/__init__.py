"""Robot, gripper, table, domino and camera models, and the one scenario file the
DOM-BOT simulator and planner both load.

Domino body frame (used everywhere): origin at the centre, x along the 48 mm length,
y along the 24 mm width, z along the 7.5 mm thickness.
"""

import math
from pathlib import Path

import numpy as np
from scipy.spatial.transform import Rotation

PACKAGE_DIR = Path(__file__).resolve().parent
DOMINO_SIZE = (0.048, 0.024, 0.0075)  # m: length, width, thickness
DOMINO_MASS = 0.0095  # kg


def tilt_from_vertical(pose) -> float:
    """Angle [rad] between a domino's length axis (body x) and the vertical, either way
    up: 0 standing, π/2 lying. ``pose``: its 4×4 pose or 3×3 rotation matrix in world."""
    return math.acos(min(1.0, abs(float(pose[2][0]))))


def domino_corners(pose) -> np.ndarray:
    """The eight corners (8 × 3, world) of a domino at ``pose`` (4×4 matrix)."""
    matrix = np.asarray(pose, dtype=float)
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
    return (signs * np.array(DOMINO_SIZE) / 2) @ matrix[:3, :3].T + matrix[:3, 3]


def tipped_pose(standing, lean: float, forward: float = 1.0) -> np.ndarray:
    """Where a domino standing at ``standing`` (4×4, world) lies once tipped ``lean`` rad
    over the edge of its foot ``forward`` (+1: along its thickness axis z, the way a run
    falls; -1: back): ~75° leaning on the next domino of a struck run, π/2 flat."""
    standing = np.asarray(standing, dtype=float)
    half = np.array(DOMINO_SIZE) / 2
    up = standing[:3, 0] * np.sign(standing[2, 0])
    ahead = forward * standing[:3, 2]
    edge = standing[:3, 3] + ahead * half[2] - up * half[0]
    axis = np.cross(up, ahead) * lean  # the turn (axis × angle) tipping up towards ahead
    turn = Rotation.from_rotvec(axis).as_matrix()
    pose = np.eye(4)
    pose[:3, :3] = turn @ standing[:3, :3]
    pose[:3, 3] = edge + turn @ (standing[:3, 3] - edge)
    return pose

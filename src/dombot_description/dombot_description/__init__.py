"""Robot, gripper, table, domino and camera models, and the one scenario file the
DOM-BOT simulator and planner both load.

Domino body frame (used everywhere): origin at the centre, x along the 48 mm length,
y along the 24 mm width, z along the 7.5 mm thickness.
"""

import math
from pathlib import Path

import numpy as np

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

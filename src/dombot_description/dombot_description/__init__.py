"""Robot, gripper, table, domino and camera models, and the one scenario file the
DOM-BOT simulator and planner both load.

Domino body frame (used everywhere): origin at the centre, x along the 48 mm length,
y along the 24 mm width, z along the 7.5 mm thickness.
"""

import math
from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
DOMINO_SIZE = (0.048, 0.024, 0.0075)  # m: length, width, thickness
DOMINO_MASS = 0.0095  # kg


def tilt_from_vertical(pose) -> float:
    """Angle [rad] between a domino's length axis (body x) and the vertical, either way
    up: 0 standing, π/2 lying. ``pose``: its 4×4 pose or 3×3 rotation matrix in world."""
    return math.acos(min(1.0, abs(float(pose[2][0]))))

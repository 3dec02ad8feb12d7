"""Robot, gripper, table, domino and camera models, and the one scenario file the
DOM-BOT simulator and planner both load.

Domino body frame (used everywhere): origin at the centre, x along the 48 mm length,
y along the 24 mm width, z along the 7.5 mm thickness.
"""

from pathlib import Path

PACKAGE_DIR = Path(__file__).resolve().parent
DOMINO_SIZE = (0.048, 0.024, 0.0075)  # m: length, width, thickness
DOMINO_MASS = 0.0095  # kg

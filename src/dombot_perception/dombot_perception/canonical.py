"""One canonical body frame per domino, and its posture.

A box looks the same after a half turn about any body axis, so a fit may return any
of four rotations for the same domino; the paper's Fig. 12 shows what happens when
that choice is left to chance. The rules, applied after the fit:

1. Axis names follow the sizes: x along the 48 mm length, y along the 24 mm width,
   z along the 7.5 mm thickness (the fit already names them so).
2. The *up axis* is the body axis closest to world z (z when flat, y on edge, x
   upright). It is made to point up.
3. The *reference axis* is x, or z when x is the up axis (upright). It is made to
   point away from the arm base, horizontally: its dot product with the horizontal
   direction from the base (world origin) to the domino is made non-negative.

A half turn flips exactly two axes, so rules 2 and 3 together pick exactly one of
the four rotations (the third axis follows from right-handedness). When the
reference axis is vertical or points across the radial direction (dot product
within 1e-9 of zero), the world x axis breaks the tie.
"""

from __future__ import annotations

import numpy as np

from dombot_perception.frames import (
    POSTURE_FLAT,
    POSTURE_ON_EDGE,
    POSTURE_TILTED,
    POSTURE_UPRIGHT,
)

POSTURE_OF_UP_AXIS = {0: POSTURE_UPRIGHT, 1: POSTURE_ON_EDGE, 2: POSTURE_FLAT}


def canonical_rotation(rotation: np.ndarray, position: np.ndarray) -> np.ndarray:
    """The one rotation among the box's four equivalents that follows the rules above."""
    rotation = rotation.copy()
    up_axis = int(np.argmax(np.abs(rotation[2, :])))
    reference_axis = 2 if up_axis == 0 else 0
    third_axis = 3 - up_axis - reference_axis
    if rotation[2, up_axis] < 0:
        rotation[:, [up_axis, third_axis]] *= -1.0
    radial = np.array([position[0], position[1], 0.0])
    alignment = rotation[:, reference_axis] @ radial
    if abs(alignment) < 1e-9:
        alignment = rotation[0, reference_axis]
    if alignment < 0:
        rotation[:, [reference_axis, third_axis]] *= -1.0
    return rotation


def posture(rotation: np.ndarray, tilt_limit_deg: float = 15.0) -> int:
    """POSTURE_* from the body axis closest to vertical; tilted beyond ``tilt_limit_deg``."""
    verticality = np.abs(rotation[2, :])
    up_axis = int(np.argmax(verticality))
    if verticality[up_axis] < np.cos(np.radians(tilt_limit_deg)):
        return POSTURE_TILTED
    return POSTURE_OF_UP_AXIS[up_axis]


def canonical_pose(pose_in: np.ndarray) -> np.ndarray:
    pose = pose_in.copy()
    pose[:3, :3] = canonical_rotation(pose_in[:3, :3], pose_in[:3, 3])
    return pose

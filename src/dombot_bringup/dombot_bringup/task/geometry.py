"""Where dominoes are, as the task core reasons about them: spots on the table and the
distances between them (poses are 4x4 transforms, ``cell.Pose``)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from dombot_bringup.layouts import DOMINO_LENGTH, DominoPlacement
from dombot_bringup.offers import NEIGHBOUR_RADIUS
from dombot_bringup.task.cell import Pose

SAME_SPOT = 0.01  # m: detections this close are taken for the same domino
POINTS_RADIUS = 0.12  # m: seen points farther from a pick than this cannot meet the pads


def placement_pose(placement: DominoPlacement, lead: float = 0.0) -> Pose:
    """The domino's target pose, moved ``lead`` metres ahead along the run."""
    w, x, y, z = placement.quaternion_wxyz()
    ahead = lead * np.array([math.cos(placement.heading), math.sin(placement.heading)])
    pose = np.eye(4)
    pose[:3, :3] = Rotation.from_quat([x, y, z, w]).as_matrix()
    pose[:3, 3] = [placement.x + ahead[0], placement.y + ahead[1], placement.z]
    return pose


def spot_of(pose: Pose) -> np.ndarray:
    """Where a domino lies on the table: (x, y) [m]."""
    return np.array(pose[:2, 3])


def near(spot: np.ndarray, other: np.ndarray, radius: float) -> bool:
    return bool(np.linalg.norm(spot - other) < radius)


def near_any(spot: np.ndarray, spots: Sequence[np.ndarray]) -> bool:
    """``spot`` is one of ``spots`` (within SAME_SPOT): the same domino seen again."""
    return any(near(spot, other, SAME_SPOT) for other in spots)


def foot_distance(measured: Pose, expected: Pose) -> float:
    """Horizontal distance [m] between the lower ends (feet) of two dominoes' length axes:
    where a leaning domino's foot is, it will stand once let go."""
    feet = []
    for pose in (measured, expected):
        axis = pose[:3, 0] * (1.0 if pose[2, 0] <= 0.0 else -1.0)  # pointing down
        feet.append(pose[:2, 3] + axis[:2] * DOMINO_LENGTH / 2.0)
    return float(np.linalg.norm(feet[0] - feet[1]))


def points_near(pose: Pose, points: np.ndarray) -> np.ndarray:
    """The ``points`` (N x 3) within POINTS_RADIUS of ``pose`` horizontally: all the pads
    can meet."""
    points = np.asarray(points).reshape(-1, 3)
    return points[np.hypot(*(points[:, :2] - spot_of(pose)).T) < POINTS_RADIUS]


def neighbours_of(pose: Pose, others: Iterable[Pose]) -> list[Pose]:
    """Those of ``others`` (``pose`` itself aside) close enough to it to matter for the
    fingers: a pick's pile, or the fallen beside a fallen run domino (a run that fell lies
    in a row, each on the next)."""
    centre = spot_of(pose)
    return [
        other
        for other in others
        if other is not pose and near(spot_of(other), centre, NEIGHBOUR_RADIUS)
    ]

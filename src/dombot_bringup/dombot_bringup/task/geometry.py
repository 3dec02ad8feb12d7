"""Where dominoes are, as the task core reasons about them: spots on the table and the
distances between them (poses are 4x4 transforms, ``cell.Pose``)."""

from __future__ import annotations

import math
from collections.abc import Iterable, Sequence

import numpy as np
from scipy.spatial.transform import Rotation

from dombot_bringup.footprints import footprints_meet
from dombot_bringup.layouts import DOMINO_LENGTH, DominoPlacement
from dombot_bringup.offers import NEIGHBOUR_RADIUS
from dombot_bringup.task.cell import Pose
from dombot_description import DOMINO_SIZE, domino_corners

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


def foot(pose: Pose) -> np.ndarray:
    """The lower end of a domino's length axis [m]: where a leaning domino's foot is, it
    will stand once let go."""
    axis = pose[:3, 0] * (1.0 if pose[2, 0] <= 0.0 else -1.0)  # pointing down
    return pose[:3, 3] + axis * DOMINO_LENGTH / 2.0


def lowered(pose: Pose, depth: float) -> Pose:
    """``pose`` moved ``depth`` metres straight down."""
    moved = pose.copy()
    moved[2, 3] -= depth
    return moved


def foot_distance(measured: Pose, expected: Pose) -> float:
    """Horizontal distance [m] between the feet of two dominoes."""
    return float(np.linalg.norm((foot(measured) - foot(expected))[:2]))


def in_the_way(lying: Pose, target: Pose, along: float, across: float) -> bool:
    """Whether the footprint of the domino lying at ``lying`` (its corners seen from above)
    meets the keep-out of the domino to stand at ``target``: its footprint grown ``along``
    the run (perception's error on a lying domino) and ``across`` it (the pads beside it,
    and that error); touching it is in the way."""
    frame = np.column_stack([target[:2, 2], target[:2, 1]])  # along (thickness), across
    frame /= np.linalg.norm(frame, axis=0)
    corners = (domino_corners(lying)[:, :2] - target[:2, 3]) @ frame
    half = np.array([DOMINO_SIZE[2] / 2 + along, DOMINO_SIZE[1] / 2 + across])
    keep_out = half * np.array([[1.0, 1.0], [1.0, -1.0], [-1.0, 1.0], [-1.0, -1.0]])
    return footprints_meet(keep_out, corners)


def distinct(poses: Iterable[Pose]) -> list[Pose]:
    """``poses`` less those within SAME_SPOT of one listed before: one domino measured
    twice (a struck run's check gave two slots the same lying domino, 4 mm apart)."""
    kept: list[Pose] = []
    for pose in poses:
        if not near_any(spot_of(pose), [spot_of(k) for k in kept]):
            kept.append(pose)
    return kept


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

"""``tipped_pose``: where a standing domino lies once it tipped over the edge of its foot."""

from __future__ import annotations

import math

import numpy as np

from dombot_description import DOMINO_SIZE, domino_corners, tilt_from_vertical, tipped_pose
from dombot_description.grasp import upright_pose


def test_tipped_flat_it_lies_on_the_table_ahead_of_where_it_stood() -> None:
    standing = upright_pose(0.5, 0.1, math.radians(30.0)).GetAsMatrix4()
    ahead = standing[:3, 2]
    for forward in (1.0, -1.0):
        flat = tipped_pose(standing, math.pi / 2, forward)
        assert math.isclose(tilt_from_vertical(flat), math.pi / 2, abs_tol=1e-9)
        assert np.allclose(domino_corners(flat)[:, 2].min(), 0.0, atol=1e-9)  # on the table
        along = (flat[:3, 3] - standing[:3, 3]) @ ahead * forward
        assert math.isclose(along, (DOMINO_SIZE[0] + DOMINO_SIZE[2]) / 2, abs_tol=1e-9)
        assert math.isclose(np.cross(ahead, flat[:3, 3] - standing[:3, 3])[2], 0.0, abs_tol=1e-9)


def lowest_corners(pose: np.ndarray, count: int) -> np.ndarray:
    corners = domino_corners(pose)
    return corners[np.argsort(corners[:, 2])[:count]]


def test_tipped_it_turns_about_its_front_foot_edge_which_stays_put() -> None:
    standing = upright_pose(0.5, 0.1, 0.0).GetAsMatrix4()
    leaning = tipped_pose(standing, math.radians(75.0))
    assert math.isclose(math.degrees(tilt_from_vertical(leaning)), 75.0, abs_tol=1e-9)
    foot = lowest_corners(standing, 4)
    front = foot[(foot - standing[:3, 3]) @ standing[:3, 2] > 0.0]
    edge = lowest_corners(leaning, 2)  # resting on the table on it
    assert np.allclose(np.sort(edge, axis=0), np.sort(front, axis=0), atol=1e-9)

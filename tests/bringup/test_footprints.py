"""One separating-axis test for footprints on the table, at its boundaries: touching
meets, a hair apart does not, ``gap`` apart meets (no ROS)."""

from __future__ import annotations

import numpy as np
import pytest

from dombot_bringup.footprints import footprints_meet, hull
from dombot_description import domino_corners


def square(x: float, y: float, side: float = 1.0) -> np.ndarray:
    """Corners in layouts' order (++, +-, -+, --), not round the square."""
    return np.array([[x + i * side, y + j * side] for i in (1, 0) for j in (1, 0)])


def test_the_hull_is_counter_clockwise_without_repeats_or_inner_or_collinear_points() -> None:
    points = np.vstack([square(0.0, 0.0), square(0.0, 0.0), [[0.5, 0.5], [0.5, 0.0]]])
    corners = hull(points)
    assert sorted(map(tuple, corners)) == [(0.0, 0.0), (0.0, 1.0), (1.0, 0.0), (1.0, 1.0)]
    x, y = corners.T
    assert np.sum(x * np.roll(y, -1) - np.roll(x, -1) * y) / 2 == 1.0  # area > 0: ccw


def test_points_on_a_line_are_no_footprint() -> None:
    with pytest.raises(ValueError, match="on a line"):
        hull(np.array([[0.0, 0.0], [1.0, 1.0], [2.0, 2.0]]))
    with pytest.raises(ValueError, match="3 distinct points"):
        hull(np.array([[0.0, 0.0], [0.0, 0.0], [1.0, 1.0]]))


@pytest.mark.parametrize(
    ("other", "meet"),
    [
        (square(0.5, 0.5), True),  # overlapping
        (square(0.25, 0.25, 0.5), True),  # inside
        (square(1.0, 0.0), True),  # touching along an edge
        (square(1.0, 1.0), True),  # touching at a corner
        (square(1.0 + 2**-20, 0.0), False),  # a hair apart
        (square(1.0 + 2**-20, 1.0 + 2**-20), False),  # a hair apart at a corner
    ],
)
def test_footprints_meet_when_they_touch_and_not_a_hair_apart(
    other: np.ndarray, meet: bool
) -> None:
    assert footprints_meet(square(0.0, 0.0), other) is meet
    assert footprints_meet(other, square(0.0, 0.0)) is meet


def test_footprints_gap_apart_meet_within_that_gap_and_not_within_less() -> None:
    other = square(1.25, 0.0)
    assert footprints_meet(square(0.0, 0.0), other, gap=0.25)
    assert not footprints_meet(square(0.0, 0.0), other, gap=0.25 - 2**-20)
    # near two corners the test errs towards meeting: 0.25·√2 apart, but 0.25 along the axes
    corner = square(1.25, 1.25)
    assert footprints_meet(square(0.0, 0.0), corner, gap=0.25)
    assert not footprints_meet(square(0.0, 0.0), corner, gap=0.25 - 2**-20)


def test_a_tilted_footprint_is_separated_by_its_own_edges() -> None:
    """A diamond whose edge touches a square's corner: the square's axes do not separate
    them a hair apart (their projections overlap), the diamond's edge does."""
    diamond = np.array([[0.75, 1.25], [1.25, 0.75], [1.75, 1.25], [1.25, 1.75]])  # touches
    assert footprints_meet(square(0.0, 0.0), diamond)
    assert not footprints_meet(square(0.0, 0.0), diamond + 2**-20)


def test_a_lying_dominos_eight_corners_seen_from_above_are_its_footprint() -> None:
    """Lying flat its top corners are straight above its bottom ones: repeats in 2-D."""
    flat = np.eye(4)  # length along x, width along y, thickness up
    flat[:3, 3] = [0.5, 0.0, 0.00375]
    corners = domino_corners(flat)[:, :2]
    assert len(hull(corners)) == 4
    beyond = flat.copy()
    beyond[0, 3] += 0.048 + 0.001  # end to end, 1 mm apart
    assert not footprints_meet(corners, domino_corners(beyond)[:, :2], gap=0.001 - 1e-9)
    assert footprints_meet(corners, domino_corners(beyond)[:, :2], gap=0.001 + 1e-9)

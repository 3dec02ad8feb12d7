"""The order in which pile dominoes are offered to the planner (no ROS)."""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np

from dombot_bringup.offers import follow_kept, kept_first, roomiest_first, with_pile_first


@dataclass(frozen=True)
class Seen:
    name: str
    scored: bool
    leaning: bool
    clearance: float


PILE = [  # in perception's order (best grasp first)
    Seen("scored, leaning", True, True, 0.010),
    Seen("scored, flat, tight", True, False, 0.000),
    Seen("flat, 2 mm room", False, False, 0.002),
    Seen("leaning, 20 mm room", False, True, 0.020),
    Seen("flat, 10 mm room", False, False, 0.010),
]


def test_with_the_pile_scored_ones_come_first_in_perceptions_order_flat_before_leaning() -> None:
    assert [s.name for s in with_pile_first(PILE)] == [
        "scored, flat, tight",
        "scored, leaning",
        "flat, 10 mm room",
        "flat, 2 mm room",
        "leaning, 20 mm room",
    ]


def test_the_last_resort_goes_by_room_for_the_fingers_after_posture() -> None:
    assert [s.name for s in roomiest_first(PILE)][2:] == [
        "flat, 10 mm room",
        "flat, 2 mm room",
        "leaning, 20 mm room",
    ]
    assert with_pile_first([]) == roomiest_first([]) == []


@dataclass(frozen=True)
class At:
    x: float
    y: float

    def spot(self) -> np.ndarray:
        return np.array([self.x, self.y])


def test_the_domino_kept_for_a_slot_comes_first_there_and_nowhere_else() -> None:
    """Kept within 10 mm: the same domino seen again."""
    seen = [At(0.50, -0.3), At(0.55, -0.3), At(0.60, -0.3), At(0.65, -0.3)]
    kept = {4: np.array([0.555, -0.3]), 9: np.array([0.65, -0.305])}
    assert kept_first(seen, kept, 4, 0.01) == [seen[1], seen[0], seen[2]]
    assert kept_first(seen, kept, 9, 0.01) == [seen[3], seen[0], seen[2]]
    assert kept_first(seen, kept, 0, 0.01) == [seen[0], seen[2]]
    assert kept_first(seen, {}, 4, 0.01) == seen
    assert kept_first(seen, {4: np.array([0.58, -0.3])}, 4, 0.01) == seen  # not seen now


def test_a_kept_domino_is_followed_to_the_nearest_look_within_the_radius() -> None:
    kept = {4: np.array([0.55, -0.3]), 9: np.array([0.70, -0.3])}
    follow_kept(kept, [np.array([0.50, -0.3]), np.array([0.556, -0.303])], 0.01)
    assert np.allclose(kept[4], [0.556, -0.303])
    assert np.allclose(kept[9], [0.70, -0.3])  # nothing within 10 mm: stays where it was
    follow_kept(kept, [], 0.01)
    assert np.allclose(kept[4], [0.556, -0.303])

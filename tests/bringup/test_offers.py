"""The order in which pile dominoes are offered to the planner (no ROS)."""

from __future__ import annotations

from dataclasses import dataclass

from dombot_bringup.offers import roomiest_first, with_pile_first


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

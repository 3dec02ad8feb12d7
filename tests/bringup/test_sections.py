"""A run built around empty slots, without ROS: its sections, their strike order, the
words for a slot given up and the job's exit status."""

from __future__ import annotations

import math

import pytest

from dombot_bringup import layouts
from dombot_bringup.layouts import DominoPlacement
from dombot_bringup.sections import (
    EXIT_FAILED,
    EXIT_PARTIAL,
    EXIT_SUCCESS,
    Section,
    count_refusal,
    empty_message,
    empty_reason,
    exit_status,
    sections_of,
    strike_order,
    topples_onto,
)


def test_sections_are_the_maximal_groups_of_consecutive_standing_slots() -> None:
    assert sections_of([7, 0, 1, 2, 4, 8]) == [Section(0, 2), Section(4, 4), Section(7, 8)]
    assert sections_of([]) == []
    assert [str(s) for s in sections_of([0, 1, 4])] == ["dominoes 1-2", "domino 5"]


def test_a_domino_topples_onto_the_next_but_one_across_an_empty_slot_only_if_within_reach() -> None:
    run = layouts.line((0.45, 0.0), math.pi / 2, 5)  # 28.8 mm apart along +y
    assert topples_onto(run[0], run[1])
    assert not topples_onto(run[1], run[0])  # it falls forward, away from the one behind
    assert not topples_onto(run[0], run[2])  # 57.6 mm ahead: beyond height + thickness
    beside = DominoPlacement(9, 0.45 + 0.03, 0.0288, math.pi / 2)  # 30 mm to the side
    assert not topples_onto(run[0], beside)


def test_a_straight_run_is_struck_from_its_end_backwards() -> None:
    """Each section falls onto the slots after it: struck last to first, nothing still
    standing lies ahead of a struck section."""
    run = layouts.line((0.45, 0.0), math.pi / 2, 9)
    sections = sections_of([0, 1, 3, 4, 5, 8])
    assert strike_order(sections, run) == [Section(8, 8), Section(3, 5), Section(0, 1)]


def test_a_section_whose_fall_reaches_an_earlier_one_is_struck_after_it() -> None:
    """A run that turns back on itself: the last domino faces the second, 30 mm ahead of
    it; struck first, it would knock the second over before the first section's strike."""
    run = [
        DominoPlacement(0, 0.0, 0.0, math.pi / 2),
        DominoPlacement(1, 0.0, 0.0288, math.pi / 2),
        DominoPlacement(2, 0.04, 0.05, 0.0),  # empty
        DominoPlacement(3, 0.03, 0.0288, math.pi),  # facing domino 2 (index 1)
    ]
    assert topples_onto(run[3], run[1]) and not topples_onto(run[1], run[3])
    sections = sections_of([0, 1, 3])
    assert strike_order(sections, run) == [Section(0, 1), Section(3, 3)]


def test_sections_that_would_all_fall_onto_each_other_are_struck_from_the_end() -> None:
    """Two dominoes facing each other 30 mm apart: no safe order; the last first."""
    run = [DominoPlacement(0, 0.0, 0.0, 0.0), DominoPlacement(1, 0.03, 0.0, math.pi)]
    assert strike_order([Section(0, 0), Section(1, 1)], run) == [Section(1, 1), Section(0, 0)]


def test_a_slot_given_up_is_reported_with_its_failures_and_the_planners_refusals() -> None:
    refusals: dict[str, int] = {}
    for code in (5, 4, 5, 5, 99):
        count_refusal(refusals, code)
    assert refusals == {"PLACE_UNREACHABLE": 3, "GRASP_UNREACHABLE": 1, "99": 1}
    refused, unseen = "planning: 5 offers refused", "no graspable domino seen"
    assert empty_reason([refused, unseen, unseen], [], refusals) == (
        f"{refused}, {unseen} x2; the planner refused: PLACE_UNREACHABLE x3, "
        "GRASP_UNREACHABLE x1, 99 x1"
    )
    assert empty_reason([refused], ["planning: 3 offers refused"], {}) == refused
    assert empty_reason([], ["put off", unseen], {}) == unseen
    assert empty_message(4, refused) == (
        f"domino 5 could not be placed ({refused}): left empty, building around it"
    )


@pytest.mark.parametrize(
    ("empty", "sections", "struck", "by_perception", "by_truth", "status"),
    [
        (0, 1, 1, True, True, EXIT_SUCCESS),
        (0, 1, 1, True, None, EXIT_SUCCESS),  # no truth (the report's sim died after)
        (1, 2, 2, True, True, EXIT_PARTIAL),
        (1, 1, 1, True, None, EXIT_PARTIAL),
        (1, 2, 1, True, True, EXIT_FAILED),  # a section not struck
        (1, 2, 2, False, True, EXIT_FAILED),  # perception sees one standing
        (1, 2, 2, True, False, EXIT_FAILED),  # the simulator has one standing
        (0, 1, 1, False, True, EXIT_FAILED),
        (4, 0, 0, False, None, EXIT_FAILED),  # nothing stood
    ],
)
def test_exit_status_is_0_for_a_full_run_3_for_a_partial_one_struck_down_else_1(
    empty: int, sections: int, struck: int, by_perception: bool, by_truth, status: int
) -> None:
    assert exit_status(empty, sections, struck, by_perception, by_truth) == status

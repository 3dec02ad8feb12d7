"""Planning ahead (``task.ahead``): the next slot's first request goes to the planner
before perception has checked the placement just made, and its answer serves that slot's
turn only when the turn makes the very same request with the arm where it was."""

from __future__ import annotations

import math
from collections.abc import Sequence

from dombot_bringup import layouts
from dombot_bringup.task.cell import PlacementCheck, PlaceRequest, Plan, Pose, Seen
from dombot_bringup.task.loop import run
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from support.scripted_cell import ScriptedCell, closing, flat, planned, seen

PICK_AND_PLACE = (closing(), "transfer", "place", "retreat")


def line_job(cell: ScriptedCell, count: int = 3, **settings) -> Job:
    """A line along +y from (0.45, 0.10): every slot ~0.41 m from the pile's centre, so
    the pile is looked at while the arm places (``placing.pile_in_view``)."""
    layout = layouts.line((0.45, 0.10), math.pi / 2, count)
    return Job.new(cell, layout, "line", ArmJobSettings(in_hand_tolerance=0.0, **settings))


def recording_cell() -> tuple[ScriptedCell, list[tuple[int, int]]]:
    """A cell that plans every pick, and the (slot, checks made so far) of each request."""
    asked: list[tuple[int, int]] = []
    cell = ScriptedCell(pile=[flat(0.50), flat(0.55), flat(0.60), flat(0.65)])
    cell.strike = lambda request: planned("strike")

    def place(request: PlaceRequest) -> Plan:
        asked.append((slot_of(request), len(cell.checks)))
        return planned(*PICK_AND_PLACE, held_above=request.place)

    cell.place = place
    return cell, asked


def slot_of(request: PlaceRequest) -> int:
    """The slot a request places at (slots 28.8 mm apart along +y from y = 0.10)."""
    return round((request.place[1, 3] - 0.10) / 0.0288)


def test_the_next_slots_pick_is_planned_while_the_placement_is_checked() -> None:
    cell, asked = recording_cell()
    report = run(line_job(cell))
    assert report.built
    # slot k+1's request went out before slot k's check (the k-th), and was not asked again
    assert asked == [(0, 0), (1, 0), (2, 1)]
    assert report.planned_ahead == {"used": 2, "dropped": 0}
    request = cell.place_requests[1]
    assert len(request.standing) == 1  # slot 0 taken as standing at its target meanwhile


def test_without_planning_ahead_each_pick_is_asked_for_after_the_check() -> None:
    cell, asked = recording_cell()
    assert run(line_job(cell, plan_ahead=False)).built
    assert asked == [(0, 0), (1, 1), (2, 2)]


def test_an_answer_asked_for_a_domino_that_then_fell_is_not_used() -> None:
    """The check finds slot 0's domino fallen: its slot is built again first, and slot 1
    gets a request of its own, with slot 0 standing."""
    cell, asked = recording_cell()
    first = seen([Seen.FALLEN], tilts=[math.radians(80.0)])

    def placements(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        if len(cell.checks) == 1:
            return first(expected, in_hand)
        return seen([Seen.STANDING] * len(expected))(expected, in_hand)

    cell.placements = placements
    report = run(line_job(cell))
    assert report.built and report.dominoes[0].attempts == 2
    slots = [slot for slot, _ in asked]
    assert slots[:3] == [0, 1, 0]  # asked ahead for slot 1, then slot 0's fallen domino again
    assert slots.count(1) == 2
    assert report.planned_ahead["dropped"] == 1
    last_for_slot_1 = [r for r in cell.place_requests if slot_of(r) == 1][-1]
    assert len(last_for_slot_1.standing) == 1


def test_an_answer_is_not_used_once_the_arm_has_moved() -> None:
    cell, asked = recording_cell()
    cell.joint_positions = (["a1"], [0.0])

    def placements(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        cell.joint_positions = (["a1"], [0.01 * len(cell.checks)])  # nudged meanwhile
        return seen([Seen.STANDING] * len(expected))(expected, in_hand)

    cell.placements = placements
    report = run(line_job(cell))
    assert report.built and report.planned_ahead == {"used": 0, "dropped": 2}
    assert [slot for slot, _ in asked] == [0, 1, 1, 2, 2]

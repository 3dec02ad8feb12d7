"""A slot put off before both its neighbours stand (``task.enclosure``): through the real
slot loop and a scripted cell, the planner is asked whether it can be filled between them
before the second is built; refused, its last turn comes first, and it is left empty at
once instead of a turn behind every later slot."""

from __future__ import annotations

import math
from collections.abc import Callable, Collection

import pytest

from dombot_bringup import layouts
from dombot_bringup.task.cell import PlaceRequest, Plan
from dombot_bringup.task.enclosure import enclosing
from dombot_bringup.task.loop import Turn, place_slot, run
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_planner.errors import ErrorCode
from support.scripted_cell import ScriptedCell, flat, planned, refused

PADS = "PLACE_UNREACHABLE at place: no collision-free IK and approach line for any of 2 place poses"


def line_job(count: int = 6, **settings) -> Job:
    """A line of ``count`` slots 28.8 mm apart, no safety gaps, four flat pile dominoes."""
    cell = ScriptedCell(pile=[flat(0.50), flat(0.55), flat(0.60), flat(0.65)])
    cell.strike = lambda request: planned("strike")
    layout = layouts.line((0.45, 0.0), math.pi / 2, count)
    return Job.new(cell, layout, "line", ArmJobSettings(section=0, **settings))


def slot_of(run_job: Job, request: PlaceRequest) -> int:
    return next(i for i, pose in enumerate(run_job.releases) if pose is request.place)


def standing_of(run_job: Job, request: PlaceRequest) -> set[int]:
    return {i for i, pose in enumerate(run_job.targets) if any(pose is p for p in request.standing)}


def refusing(run_job: Job, slot: int, between: bool = True) -> Callable[[PlaceRequest], Plan]:
    """The s-curve's slot 3: ``slot`` refused every place with one neighbour standing
    (the arm's reach there), and between both unless it plans there (not ``between``)."""

    def place(request: PlaceRequest) -> Plan:
        enclosed = {slot - 1, slot + 1} <= standing_of(run_job, request)
        if slot_of(run_job, request) == slot and (between or not enclosed):
            return refused(ErrorCode.PLACE_UNREACHABLE, f"{PADS} (pads–standing: 20)")
        return planned()

    return place


def open_on_one_side(run_job: Job, slot: int) -> Callable[[PlaceRequest], Plan]:
    """``slot`` with one neighbour standing: two flat dominoes' holds in their pile reach
    no place, the others' grasps none, the pile ignored (another hold) it plans; between
    both neighbours nothing plans."""

    def place(request: PlaceRequest) -> Plan:
        if slot_of(run_job, request) != slot:
            return planned()
        if {slot - 1, slot + 1} <= standing_of(run_job, request):
            return refused(ErrorCode.PLACE_UNREACHABLE, f"{PADS} (pads–standing: 20)")
        if request.pile == ():
            return planned()
        if request.domino[0, 3] < 0.575:
            return refused(ErrorCode.PLACE_UNREACHABLE, PADS)
        return refused(ErrorCode.GRASP_UNREACHABLE, "GRASP_UNREACHABLE at grasp: no IK")

    return place


def turns(run_job: Job) -> list[tuple[int, bool, Turn]]:
    """Run the job with the real turns: each (slot, may be put off, how it ended)."""
    taken: list[tuple[int, bool, Turn]] = []

    def turn(the_job: Job, index: int, may_defer: bool) -> Turn:
        taken.append((index, may_defer, place_slot(the_job, index, may_defer)))
        assert len(taken) < 30, f"put off for ever: {taken[-6:]}"
        return taken[-1][2]

    run(run_job, turn)
    return taken


DEFERRED, FAILED, PLACED = Turn.DEFERRED, Turn.FAILED, Turn.PLACED


@pytest.mark.parametrize("asked", [0, 3])
def test_a_slot_put_off_and_refused_between_its_neighbours_has_its_last_turn_before_the_second(
    asked: int,
) -> None:
    """s-curve of 10 at 22 mm: slot 3 put off, built behind the rest, then refused between
    the 2nd and 4th and left empty (asked 0: as before). Asked between its neighbours once
    put off, it is refused there: its last turn comes before the 4th, with one side open,
    where the pile ignored plans: all six stand."""
    run_job = line_job(enclosure_probe_dominoes=asked, max_spreads=0, max_isolations=0)
    cell = run_job.cell
    cell.place = open_on_one_side(run_job, 2)
    taken = turns(run_job)
    if asked == 0:
        assert taken[2:] == [
            *[(2, True, DEFERRED), (3, True, PLACED), (4, True, PLACED), (5, True, PLACED)],
            (2, False, FAILED),
        ]
        assert [e.slot for e in run_job.report.empty_slots] == [3]
    else:
        assert taken[2:] == [
            *[(2, True, DEFERRED), (2, False, PLACED)],
            *[(3, True, PLACED), (4, True, PLACED), (5, False, PLACED)],
        ]
        asked_for = [r for r in cell.place_requests if slot_of(run_job, r) == 2]
        (probe,) = [r for r in asked_for if standing_of(run_job, r) >= {1, 3}]
        assert probe.pile == ()  # only the place in question
        assert run_job.report.built


@pytest.mark.parametrize("asked", [0, 3])
def test_a_slot_put_off_that_nothing_fills_is_left_empty_before_the_second_neighbour(
    asked: int,
) -> None:
    """Refused every place, with one neighbour as with two: its last turn, before the 4th
    (asked 3), gives it up at once (``attempts.no_place``), with why; the run is built
    around it as before."""
    run_job = line_job(enclosure_probe_dominoes=asked)
    cell = run_job.cell
    cell.place = refusing(run_job, 2)
    taken = turns(run_job)
    order = [0, 1, 2, 3, 4, 5, 2] if asked == 0 else [0, 1, 2, 2, 3, 4, 5]
    assert [i for i, _, _ in taken] == order
    ((slot, reason),) = [(e.slot, e.reason) for e in run_job.report.empty_slots]
    assert slot == 3 and reason.startswith("no domino can be placed there")
    assert ("not put off again: refused between its neighbours" in reason) == (asked > 0)
    # (the scripted check sees them standing after every strike: struck again, rounds 2, 3)
    sections = [(s.first_slot, s.last_slot) for s in run_job.report.sections if s.round == 1]
    assert sections == [(1, 2), (4, 6)]
    # 4 with their pile at each turn; asked between its neighbours: once; with its pile
    # ignored before it is given up: once
    assert len([r for r in cell.place_requests if slot_of(run_job, r) == 2]) == 9 + (asked > 0)


def test_a_slot_put_off_that_plans_between_its_neighbours_is_put_off_as_before() -> None:
    """Refused with one neighbour standing, planned between both: built behind the rest."""
    run_job = line_job()
    run_job.cell.place = refusing(run_job, 2, between=False)
    assert [(i, turn) for i, _, turn in turns(run_job)][2:] == [
        *[(2, DEFERRED), (3, PLACED), (4, PLACED), (5, PLACED), (2, PLACED)],
    ]
    assert run_job.report.built


@pytest.mark.parametrize(
    ("standing", "ahead", "expected"),
    [
        ({1}, [3, 4], 0),  # the 4th encloses it
        ({1}, [4, 3], 1),  # ... built after the 5th
        (set(), [1, 3], 1),  # both still to build: the second encloses it
        ({1}, [4], None),  # its next turn comes with the 4th empty
        ({1, 3}, [4], None),  # enclosed already: nothing to put before
    ],
)
def test_the_neighbour_that_encloses_a_slot_put_off(
    standing: Collection[int], ahead: list[int], expected: int | None
) -> None:
    run_job = line_job()
    for i in standing:
        run_job.state.standing[i] = run_job.targets[i]
    assert enclosing(run_job, 2, ahead) == expected
    assert enclosing(run_job, 0, [1]) is None and enclosing(run_job, 5, [4]) is None

"""Where each stretch of the run is started (``task.order``): through the real slot loop
and a scripted cell, a stretch whose slots are refused with the one behind standing (the
s-curve of 10 at 22 mm: slots 2-4, the arm's reach there) is built from the last of them
backwards, then onwards, and every slot stands; asked only at tight spacing."""

from __future__ import annotations

import math
from collections.abc import Callable

from dombot_bringup import layouts
from dombot_bringup.run_report import StretchStart
from dombot_bringup.task.cell import PlaceRequest, Plan
from dombot_bringup.task.loop import Turn, place_slot, requeue, run
from dombot_bringup.task.order import build_order, from_start, stretches
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_planner.errors import ErrorCode
from support.scripted_cell import ScriptedCell, flat, planned, refused

REACH = (
    "PLACE_UNREACHABLE at place: no collision-free IK and approach line for any of 2 place poses"
)


def line_job(spacing: float, count: int = 8, **settings) -> Job:
    """A line of ``count`` slots ``spacing`` apart, no safety gaps, four flat pile dominoes."""
    cell = ScriptedCell(pile=[flat(0.50), flat(0.55), flat(0.60), flat(0.65)])
    cell.strike = lambda request: planned("strike")
    layout = layouts.line((0.45, 0.0), math.pi / 2, count, spacing)
    return Job.new(cell, layout, "line", ArmJobSettings(section=0, **settings))


def slot_of(job: Job, request: PlaceRequest) -> int:
    return next(i for i, pose in enumerate(job.releases) if pose is request.place)


def standing_of(job: Job, request: PlaceRequest) -> set[int]:
    return {i for i, pose in enumerate(job.targets) if any(pose is p for p in request.standing)}


def reach(job: Job, behind: set[int], ahead: set[int] = frozenset()) -> Callable:
    """The slots of ``behind`` refused with the one behind them standing (the lean ahead out
    of reach, the lean back onto it), those of ``ahead`` with the one ahead standing; every
    slot refused between two standing neighbours (at 22 mm the pads meet them)."""

    def place(request: PlaceRequest) -> Plan:
        slot, standing = slot_of(job, request), standing_of(job, request)
        if {slot - 1, slot + 1} <= standing:
            return refused(ErrorCode.PLACE_UNREACHABLE, f"{REACH} (pads–standing: 20)")
        if (slot in behind and slot - 1 in standing) or (slot in ahead and slot + 1 in standing):
            return refused(ErrorCode.PLACE_UNREACHABLE, f"{REACH} (line leaves the reach: 10)")
        return planned()

    return place


def turns(job: Job) -> tuple[list[tuple[int, Turn]], list[PlaceRequest]]:
    """Run the job with the real turns: each (slot, how it ended), and the requests asked
    before the first turn."""
    taken: list[tuple[int, Turn]] = []
    before: list[PlaceRequest] = []

    def turn(the_job: Job, index: int, may_defer: bool) -> Turn:
        if not taken:
            before.extend(job.cell.place_requests)
        taken.append((index, place_slot(the_job, index, may_defer)))
        assert len(taken) < 30, f"put off for ever: {taken[-6:]}"
        return taken[-1][1]

    run(job, turn)
    return taken, before


def test_stretches_and_their_order_from_a_start() -> None:
    assert stretches([0, 1, 2, 5, 6, 9]) == [range(0, 3), range(5, 7), range(9, 10)]
    assert from_start(range(2, 8), 4) == [4, 3, 2, 5, 6, 7]
    assert from_start(range(2, 8), 2) == [2, 3, 4, 5, 6, 7]


def test_slots_refused_behind_are_built_before_the_one_behind_and_every_slot_stands() -> None:
    job = line_job(0.022)
    job.cell.place = reach(job, behind={1, 2, 3})
    taken, probes = turns(job)
    assert taken == [(i, Turn.PLACED) for i in (3, 2, 1, 0, 4, 5, 6, 7)]
    assert job.report.built and not job.report.empty_slots
    (decision,) = job.report.build_order
    assert (decision.first, decision.last, decision.start) == (1, 8, 4)
    assert decision.behind.startswith("4: PLACE_UNREACHABLE") and decision.ahead == ""
    # asked from the last slot backwards until the 4th was refused, then 3, 2, 1 ahead
    asked = [(slot_of(job, r), standing_of(job, r)) for r in probes]
    assert asked == [(7, {6}), (6, {5}), (5, {4}), (4, {3}), (3, {2}), (2, {3}), (1, {2}), (0, {1})]
    assert all(r.pile == () for r in probes) and decision.plans == len(probes)


def test_in_run_order_slots_refused_behind_are_put_off_and_left_empty() -> None:
    """What the bring-up met before (``--run-order``): the 2nd put off, the 3rd built
    beside its empty place, then the 2nd refused between the 1st and 3rd (its last turn),
    and the 4th the same between the 3rd and 5th."""
    job = line_job(0.022, order_probe_dominoes=0)
    job.cell.place = reach(job, behind={1, 2, 3})
    taken, probes = turns(job)
    assert probes == [] and job.report.build_order == []
    assert [e.slot for e in job.report.empty_slots] == [2, 4]
    assert (1, Turn.FAILED) in taken and (3, Turn.FAILED) in taken


def test_a_slot_before_the_start_refused_ahead_keeps_run_order() -> None:
    job = line_job(0.022)
    job.cell.place = reach(job, behind={4}, ahead={2})
    assert build_order(job, range(8)) == list(range(8))
    assert job.report.build_order == [
        StretchStart(1, 8, 1, f"5: {REACH}", f"3: {REACH}", 6),
    ]


def test_not_asked_at_ordinary_spacing() -> None:
    job = line_job(0.0288)
    job.cell.place = reach(job, behind={1, 2, 3})
    assert build_order(job, range(8)) == list(range(8))
    assert job.cell.place_requests == [] and job.report.build_order == []


def test_a_domino_whose_grasp_is_refused_is_not_asked_again() -> None:
    """The first flat domino's grasp refused: the next answers, and is asked from then on."""
    job = line_job(0.022, count=4)
    place = reach(job, behind={1})

    def grasp_refused_first(request: PlaceRequest) -> Plan:
        if request.domino[0, 3] < 0.525:
            return refused(ErrorCode.GRASP_UNREACHABLE, "GRASP_UNREACHABLE at grasp: no IK")
        return place(request)

    job.cell.place = grasp_refused_first
    assert build_order(job, range(4)) == [1, 0, 2, 3]
    asked = [(slot_of(job, r), round(r.domino[0, 3], 2)) for r in job.cell.place_requests]
    assert asked == [(3, 0.5), (3, 0.55), (2, 0.55), (1, 0.55), (0, 0.55)]
    assert job.report.build_order[0].plans == 5


def test_slots_knocked_over_are_built_again_in_the_build_order() -> None:
    """The 1st to 4th knocked over once the 5th stands: built again from the 4th."""
    job = line_job(0.022)
    order = [3, 2, 1, 0, 4, 5, 6, 7]
    assert requeue(job, [6, 7], {4, 5}, order) == [3, 2, 1, 0, 6, 7]

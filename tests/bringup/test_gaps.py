"""Safety gaps the planner cannot fill between standing neighbours (``task.gaps``): asked
before the build through a scripted cell, each gap is kept, moved within its stretch or
dropped, and the build order follows."""

from __future__ import annotations

import math
from collections.abc import Callable, Collection

import pytest

from dombot_bringup import layouts
from dombot_bringup.run_report import GapDecision
from dombot_bringup.task.cell import PlaceRequest, Plan, Posture
from dombot_bringup.task.gaps import gap_slots, moves
from dombot_bringup.task.loop import Turn, run
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_planner.errors import ErrorCode
from support.scripted_cell import ScriptedCell, flat, planned, refused

PADS = "PLACE_UNREACHABLE at place: no collision-free IK and approach line for any of 2 place poses"


def line_job(cell: ScriptedCell, count: int, **settings) -> Job:
    """A line of ``count`` slots 28.8 mm apart: one-slot gaps after every 4 (slots 5, 10)."""
    layout = layouts.line((0.45, 0.0), math.pi / 2, count)
    return Job.new(cell, layout, "line", ArmJobSettings(**settings))


def slot_of(run_job: Job, request: PlaceRequest) -> int:
    return next(i for i, pose in enumerate(run_job.releases) if pose is request.place)


def standing_of(run_job: Job, request: PlaceRequest) -> set[int]:
    return {i for i, pose in enumerate(run_job.targets) if any(pose is p for p in request.standing)}


def refusing_between(run_job: Job, slots: Collection[int]) -> Callable[[PlaceRequest], Plan]:
    """The planner of a tight run: ``slots`` (layout indices) refused between their two
    standing neighbours (the pads meet them), planned with one."""

    def place(request: PlaceRequest) -> Plan:
        slot = slot_of(run_job, request)
        if slot in slots and {slot - 1, slot + 1} <= standing_of(run_job, request):
            return refused(ErrorCode.PLACE_UNREACHABLE, f"{PADS} (pads–standing: 20)")
        return planned("approach_grasp")

    return place


def build_order(run_job: Job) -> list[int]:
    """Run the job where every slot's turn places it at once; the slots in turn order."""
    turns: list[int] = []

    def turn(the_job: Job, index: int, may_defer: bool) -> Turn:
        turns.append(index)
        the_job.state.standing[index] = the_job.targets[index]
        the_job.report.dominoes[index].placed = True
        return Turn.PLACED

    run(run_job, turn)
    return turns


def test_a_gap_refused_between_its_neighbours_moves_to_where_it_plans() -> None:
    """Slot 5 refused between 4 and 6: the gap goes one slot on, to 6, which plans; the
    build leaves 6 for last, asked with everything else standing and its pile ignored."""
    cell = ScriptedCell(pile=[flat(0.55), flat(0.6)])
    run_job = line_job(cell, 10)
    cell.place = refusing_between(run_job, {4})
    assert build_order(run_job) == [0, 1, 2, 3, 4, 6, 7, 8, 9, 5]
    asked = cell.place_requests[:2]
    assert [slot_of(run_job, r) for r in asked] == [4, 5]
    assert [standing_of(run_job, r) for r in asked] == [set(range(10)) - {4}, set(range(10)) - {5}]
    assert all(r.pile == () for r in asked)
    assert run_job.report.safety_gaps == [GapDecision([5], "moved", [6], PADS, 2)]
    summary = run_job.report.summary()
    assert (summary["gaps_kept"], summary["gaps_moved"], summary["gaps_dropped"]) == (0, 1, 0)
    assert summary["gap_plans"] == 2


def test_a_gap_refused_wherever_it_may_go_is_dropped_and_its_stretch_built_in_run_order(
    capsys,
) -> None:
    """s_curve30 at 22 mm: every slot refused between its neighbours. Each gap is asked at
    its place and one slot either way, then dropped: the run is built in run order."""
    cell = ScriptedCell(pile=[flat(0.55)])
    run_job = line_job(cell, 14)
    cell.place = refusing_between(run_job, range(14))
    assert build_order(run_job) == list(range(14))
    assert [slot_of(run_job, r) for r in cell.place_requests] == [4, 5, 3, 9, 10, 8]
    assert [(g.slots, g.verdict, g.now) for g in run_job.report.safety_gaps] == [
        ([5], "dropped", []),
        ([10], "dropped", []),
    ]
    assert run_job.report.summary()["gaps_dropped"] == 2
    out = capsys.readouterr().out
    assert "safety gap at domino 10: dropped: its last slot refused between its neighbours" in out
    assert "its stretch is built in run order" in out


def test_a_gap_moves_within_its_stretch_only() -> None:
    """Slot 10's gap stays behind the one at 5 with a domino between, and leaves a domino
    after it before the run's end."""
    run_job = line_job(ScriptedCell(), 14, gap_moves=4)
    assert [gap.start for gap in moves(run_job, range(9, 10), 6, 14)] == [10, 8, 11, 7, 12, 6]


def test_a_gap_that_plans_is_kept_and_one_the_planner_said_nothing_of_too() -> None:
    """The first gap plans at once (one call); at the second every domino's grasp is
    refused, which says nothing of the slot: kept after gap_probe_dominoes dominoes, none
    of them leaning."""
    pile = [flat(0.5, posture=Posture.TILTED), *(flat(0.52 + 0.03 * k) for k in range(4))]
    cell = ScriptedCell(pile=pile)
    run_job = line_job(cell, 14)

    def place(request: PlaceRequest) -> Plan:
        if slot_of(run_job, request) == 9:
            return refused(ErrorCode.GRASP_UNREACHABLE, "GRASP_UNREACHABLE at grasp: no IK")
        return planned("approach_grasp")

    cell.place = place
    order = build_order(run_job)
    assert order[-2:] == [4, 9]
    assert [slot_of(run_job, r) for r in cell.place_requests] == [4, 9, 9, 9]
    assert not any(r.domino is pile[0].pose for r in cell.place_requests)
    assert [(g.verdict, g.now, g.plans) for g in run_job.report.safety_gaps] == [
        ("kept", [5], 1),
        ("kept", [10], 3),
    ]


@pytest.mark.parametrize("count", [4, 10])
def test_the_first_look_serves_the_first_turn_and_no_gaps_ask_nothing(count: int) -> None:
    """With gaps (10 slots) the pile is looked at once before the build and the first
    turn finds that look; without (4 slots), nothing is asked before the first turn."""
    cell = ScriptedCell(pile=[flat(0.55)], place=lambda request: planned("approach_grasp"))
    run_job = line_job(cell, count)
    gaps = gap_slots(run_job)
    assert gaps == ([4] if count == 10 else [])
    assert len(cell.looks) == (1 if count == 10 else 0)
    assert (run_job.pile_look is not None) == (count == 10)


def test_with_no_dominoes_to_ask_with_the_gaps_stay_as_laid_out() -> None:
    cell = ScriptedCell(pile=[], place=lambda request: refused(ErrorCode.PLACE_UNREACHABLE))
    run_job = line_job(cell, 10)
    assert gap_slots(run_job) == [4]
    assert cell.place_requests == [] and run_job.report.safety_gaps == []
    assert gap_slots(line_job(cell, 10, gap_probe_dominoes=0)) == [4]

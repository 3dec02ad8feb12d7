"""Planning ahead (``task.ahead``): the next slot's first request goes to the planner
as the domino just carried starts down to its slot (once the look at the pile asked for
as the carry ended has answered; else the moment it answers while the arm descends,
lets go and retreats, else after the retreat),
before perception has checked the placement, and its answer serves that slot's turn
only when the turn makes the very same request with the arm where the plan starts."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
import pytest

from dombot_bringup import layouts
from dombot_bringup.task import ahead
from dombot_bringup.task.cell import (
    Detections,
    GripperEvent,
    Later,
    Motion,
    PlacementCheck,
    PlaceRequest,
    Plan,
    Pose,
    Seen,
    Segment,
    Trajectory,
)
from dombot_bringup.task.loop import run
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from support.scripted_cell import ScriptedCell, closing, flat, path, planned, seen

ARM = ("a1", "a2")
RETREAT_END = {"a1": 0.3, "a2": -0.2}  # where every retreat leaves the arm
RETREAT = Segment(
    "retreat",
    Trajectory(ARM, np.array([0.0, 1.0]), np.array([[0.1, 0.0], [0.3, -0.2]]), np.zeros((0, 2))),
)
# the fingers open once "place" ends, as the planner's plans say
PICK_AND_PLACE = (
    closing(),
    "transfer",
    Segment("place", path("place"), GripperEvent.OPEN),
    RETREAT,
)


def line_job(cell: ScriptedCell, count: int = 3, **settings) -> Job:
    """A line along +y from (0.45, 0.10): every slot ~0.41 m from the pile's centre, so
    the pile is looked at while the arm places (``placing.pile_in_view``)."""
    layout = layouts.line((0.45, 0.10), math.pi / 2, count)
    settings = {"in_hand_tolerance": 0.0, **settings}  # no hand check unless told
    return Job.new(cell, layout, "line", ArmJobSettings(**settings))


def recording_cell() -> tuple[ScriptedCell, list[tuple[int, int, int]]]:
    """A cell that plans every pick, and for each request (slot, retreats run, checks
    made) so far."""
    asked: list[tuple[int, int, int]] = []
    cell = ScriptedCell(pile=[flat(0.50), flat(0.55), flat(0.60), flat(0.65)])
    cell.strike = lambda request: planned("strike")

    def place(request: PlaceRequest) -> Plan:
        asked.append((slot_of(request), retreats(cell), len(cell.checks)))
        return planned(*PICK_AND_PLACE, held_above=request.place)

    cell.place = place
    return cell, asked


def retreats(cell: ScriptedCell) -> int:
    return sum(t.joint_names == ARM for t in cell.executed)


def ran(cell: ScriptedCell, label: str) -> int:
    """How many of the segments labelled ``label`` (``scripted_cell.path``) ran."""
    return sum(t.joint_names == (label,) for t in cell.executed)


def slot_of(request: PlaceRequest) -> int:
    """The slot a request places at (slots 28.8 mm apart along +y from y = 0.10)."""
    return round((request.place[1, 3] - 0.10) / 0.0288)


def counts(
    descent: int = 0,
    look_answered: int = 0,
    after_retreat: int = 0,
    used: int = 0,
    dropped: int = 0,
) -> dict[str, int]:
    """The report's planned_ahead."""
    return {
        "descent": descent,
        "look_answered": look_answered,
        "after_retreat": after_retreat,
        "used": used,
        "dropped": dropped,
    }


def test_the_next_slots_pick_is_asked_for_as_the_descent_starts() -> None:
    """The look at the pile is asked for as the carry ends above the slot, before the
    hand check; answered by the time the descent starts, the next slot's first request
    goes out then, planned from where the retreat will end."""
    cell, asked = recording_cell()
    events: list[str] = []
    look, checking, planning = cell.detect, cell.check_placement, cell.place

    def detect(not_before: float):
        events.append(f"look after {ran(cell, 'transfer')} carries")
        return look(not_before)

    def check_placement(expected, in_hand=False, not_before=0.0):
        events.append("hand check" if in_hand else "placement check")
        return checking(expected, in_hand, not_before)

    def place(request: PlaceRequest) -> Plan:
        events.append(f"request after {ran(cell, 'place')} descents")
        return planning(request)

    cell.detect, cell.check_placement, cell.place = detect, check_placement, place
    report = run(line_job(cell, in_hand_tolerance=0.003))
    assert report.built
    # slot k+1's request went out before slot k's descent ran, and was not asked again
    assert asked == [(0, 0, 0), (1, 0, 1), (2, 1, 3)]
    assert events[:6] == [
        "look after 0 carries",  # the first look, before anything moved
        "request after 0 descents",
        "look after 1 carries",  # as the carry ended above slot 0
        "hand check",
        "request after 0 descents",  # slot 1's, as slot 0's descent starts
        "placement check",
    ]
    assert report.planned_ahead == counts(descent=2, used=2)
    first, early = cell.place_requests[:2]
    assert first.start is None  # the planner takes the arm where it stands
    assert early.start == RETREAT_END
    assert len(early.standing) == 1  # slot 0 taken as standing at its target meanwhile


def answering_while(cell: ScriptedCell, moving: str) -> list[tuple[int, str]]:
    """Each look at the pile answers once polled while ``moving`` moves (``waiting_on``:
    "place", the descent; "gripper"; "a1", the retreat; an approach...), not before; for
    each request: (slot, what moved as it went out: "" between motions)."""
    sent: list[tuple[int, str]] = []
    looking, planning = cell.detect_later, cell.place

    def detect_later(not_before: float) -> Later[Detections]:
        look, came = looking(not_before), []

        def answered() -> bool:
            if cell.waiting_on == moving:
                came.append(moving)
            return bool(came)

        return Later(look.wait, answered)

    def place(request: PlaceRequest) -> Plan:
        sent.append((slot_of(request), cell.waiting_on))
        return planning(request)

    cell.detect_later, cell.place = detect_later, place
    return sent


@pytest.mark.parametrize("moving", ["place", "gripper", "a1"])
def test_a_look_answered_while_the_arm_places_sends_the_request_then(moving: str) -> None:
    """The look asked for as the carry ended answers during the descent, the release or
    the retreat: the next slot's request goes out that moment, from the retreat's end."""
    cell, _ = recording_cell()
    sent = answering_while(cell, moving)
    report = run(line_job(cell))
    assert report.built
    assert sent == [(0, ""), (1, moving), (2, moving)]
    assert report.planned_ahead == counts(look_answered=2, used=2)
    assert cell.place_requests[1].start == RETREAT_END


@pytest.mark.parametrize("moving", ["approach_grasp", "transfer"])
def test_no_request_goes_out_ahead_while_the_arm_picks_or_carries(moving: str) -> None:
    """Only the descent, the release and the retreat ask: a look answered while the next
    pick's approach or carry runs was answered too late (the request after the retreat
    waited for it), and it serves no request asked before that motion."""
    cell, _ = recording_cell()
    sent = answering_while(cell, moving)
    report = run(line_job(cell))
    assert report.built
    assert sent == [(0, ""), (1, ""), (2, "")]
    assert report.planned_ahead == counts(after_retreat=2, used=2)


def test_without_planning_ahead_a_look_answered_mid_descent_sends_nothing() -> None:
    cell, asked = recording_cell()
    sent = answering_while(cell, "place")
    report = run(line_job(cell, plan_ahead=False))
    assert report.built
    assert sent == [(0, ""), (1, ""), (2, "")]
    assert asked == [(0, 0, 0), (1, 1, 1), (2, 2, 2)]
    assert report.planned_ahead == counts()


def test_a_request_sent_mid_descent_is_dropped_when_the_descent_stalls() -> None:
    """The look answers during slot 0's first descent, which then stalls: the domino is
    carried back onto the pile, and the request sent meanwhile is dropped; none goes
    out while the arm backs up and puts it back (no motion there asks)."""
    cell, _ = recording_cell()
    sent = answering_while(cell, "place")

    def motion(trajectory: Trajectory) -> Motion:
        if trajectory.joint_names == ("place",) and ran(cell, "place") == 1:
            return Motion(False, "a joint fell behind")
        return Motion(True)

    cell.motion = motion
    report = run(line_job(cell))
    assert report.built and report.dominoes[0].attempts == 2
    assert sent == [(0, ""), (1, "place"), (0, ""), (1, "place"), (2, "place")]
    assert report.planned_ahead == counts(look_answered=3, used=2, dropped=1)


def test_a_look_not_answered_yet_leaves_the_request_until_after_the_retreat() -> None:
    """The arm does not wait for the look at the pile: the request goes out as before."""
    cell, asked = recording_cell()
    cell.looks_answer_at_once = False
    report = run(line_job(cell))
    assert report.built
    assert asked == [(0, 0, 0), (1, 1, 0), (2, 2, 1)]  # after the retreat, before the check
    assert report.planned_ahead == counts(after_retreat=2, used=2)
    assert cell.place_requests[1].start is None


def test_without_planning_ahead_each_pick_is_asked_for_after_the_check() -> None:
    cell, asked = recording_cell()
    report = run(line_job(cell, plan_ahead=False))
    assert report.built
    assert asked == [(0, 0, 0), (1, 1, 1), (2, 2, 2)]
    assert report.planned_ahead == counts()


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
    slots = [slot for slot, _, _ in asked]
    assert slots[:3] == [0, 1, 0]  # asked ahead for slot 1, then slot 0's fallen domino again
    assert slots.count(1) == 2
    assert report.planned_ahead["dropped"] == 1
    last_for_slot_1 = [r for r in cell.place_requests if slot_of(r) == 1][-1]
    assert len(last_for_slot_1.standing) == 1


def nudging(cell: ScriptedCell, by: float) -> None:
    """Each placement check finds the arm's first joint ``by`` rad from where it stood."""

    def placements(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        names, positions = cell.joint_positions
        cell.joint_positions = (names, [positions[0] + by, *positions[1:]])
        return seen([Seen.STANDING] * len(expected))(expected, in_hand)

    cell.placements = placements


def test_an_answer_is_not_used_once_the_arm_has_moved() -> None:
    cell, asked = recording_cell()
    cell.joint_positions = (list(ARM), [0.0, 0.0])
    nudging(cell, 2 * ahead.START_TOLERANCE)
    report = run(line_job(cell))
    assert report.built
    assert report.planned_ahead == counts(descent=2, dropped=2)
    assert [slot for slot, _, _ in asked] == [0, 1, 1, 2, 2]


def test_an_answer_is_used_with_the_arm_within_its_tracking_error_of_the_start() -> None:
    cell, asked = recording_cell()
    cell.joint_positions = (list(ARM), [0.0, 0.0])
    nudging(cell, ahead.START_TOLERANCE / 2)
    report = run(line_job(cell))
    assert report.built and report.planned_ahead["used"] == 2
    assert [slot for slot, _, _ in asked] == [0, 1, 2]


def test_a_retreat_that_failed_drops_the_answer() -> None:
    """The first retreat stops short: the arm stands elsewhere than the plan asked for as
    the fingers let go starts, and that plan is not run (the attempt failed: slot 0 is
    built again first, then slot 1 asked for again)."""
    cell, asked = recording_cell()
    cell.joint_positions = (list(ARM), [0.0, 0.0])

    def motion(trajectory: Trajectory) -> Motion:
        if trajectory.joint_names == ARM and retreats(cell) == 1:
            cell.joint_positions = (list(ARM), [0.2, -0.1])  # where it stopped
            return Motion(False, "stopped short")
        return Motion(True)

    cell.motion = motion
    report = run(line_job(cell))
    assert report.built and report.dominoes[0].attempts == 2
    assert [slot for slot, _, _ in asked] == [0, 1, 0, 1, 2]
    assert report.planned_ahead == counts(descent=3, used=2, dropped=1)


def test_the_same_request_with_the_arm_elsewhere_is_dropped() -> None:
    """What the turn asks is what was asked ahead, but the arm does not stand where that
    plan starts (a retreat that stopped short): dropped; standing there: used."""
    cell, _ = recording_cell()
    job = line_job(cell)
    job.upcoming = 1
    request = PlaceRequest(domino=flat(0.5).pose, place=job.releases[1])
    for stands in ([0.2, -0.1], list(RETREAT_END.values())):
        cell.joint_positions = (list(ARM), stands)
        ahead.send(job, 0, lambda job, index: request, RETREAT_END, "descent")
        plan = ahead.answer(job, request)
        assert (plan is not None) == (stands == list(RETREAT_END.values()))
    assert job.report.planned_ahead == counts(descent=2, used=1, dropped=1)


def test_a_domino_put_back_on_the_pile_drops_the_look_and_the_request() -> None:
    """Slot 0's descent stalls after slot 1's request went out: the domino is carried
    back and dropped on the pile, which then lies otherwise than looked at as the carry
    ended. The answer is dropped and slot 0's next attempt looks at the pile afresh."""
    cell, _ = recording_cell()
    looked: list[tuple[int, int]] = []  # (slot, looks so far) at each request
    planning = cell.place

    def place(request: PlaceRequest) -> Plan:
        looked.append((slot_of(request), len(cell.looks)))
        return planning(request)

    def motion(trajectory: Trajectory) -> Motion:
        if trajectory.joint_names == ("place",) and ran(cell, "place") == 1:
            return Motion(False, "a joint fell behind")
        return Motion(True)

    cell.place, cell.motion = place, motion
    report = run(line_job(cell))
    assert report.built and report.dominoes[0].attempts == 2
    assert looked[:3] == [(0, 1), (1, 2), (0, 3)]  # slot 0 again after a look of its own
    assert report.planned_ahead["dropped"] == 1

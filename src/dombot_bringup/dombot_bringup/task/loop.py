"""The slot loop: every slot of the layout gets turns until it stands or is given up,
then the strike.

Each turn (``place_slot``) makes attempts (``attempts.attempt``: offer, pick, carry,
place, check) until the domino stands, the slot's attempts run out, or nothing plans
and the slot is put off for others to go first. A slot whose attempts ran out is left
empty and the run is built around it; what stands is then struck section by section
(``strike``).
"""

from __future__ import annotations

import time
from collections.abc import Callable, Collection, Sequence
from enum import Enum

import numpy as np

from dombot_bringup.run_report import EmptySlot, RunReport
from dombot_bringup.sections import empty_message, empty_reason
from dombot_bringup.task.attempts import Attempt, Outcome, attempt
from dombot_bringup.task.cell import CellError
from dombot_bringup.task.clearing import look_at_the_way, sweep_debris
from dombot_bringup.task.enclosure import enclosed
from dombot_bringup.task.gaps import gap_slots
from dombot_bringup.task.order import build_order
from dombot_bringup.task.picking import Refusal
from dombot_bringup.task.records import add_spent, record_truth, take_picture
from dombot_bringup.task.staging import set_aside
from dombot_bringup.task.state import Job, log
from dombot_bringup.task.strike import strike


class Turn(Enum):
    """How a slot's turn ended."""

    PLACED = "placed"
    FAILED = "failed"  # its attempts ran out
    DEFERRED = "deferred"  # nothing planned: put off for other slots to go first


def run(
    job: Job, turn: Callable[[Job, int, bool], Turn] | None = None, pour: bool = True
) -> RunReport:
    """Pour the pile (unless not ``pour``: a next cycle builds from what lies in the cell),
    build the layout (``turn``: one slot's turn, ``place_slot``) around the slots given
    up, knock down what stands; the report."""
    started_wall, cell, report = time.monotonic(), job.cell, job.report
    if pour:
        log(cell.reset(job.settings.pile, job.settings.seed))
    started_sim = cell.sim_time
    build(job, turn or place_slot)
    report.built = len(job.state.standing) == len(job.layout)
    if report.empty_slots:
        report.message = "; ".join(empty_message(e.slot - 1, e.reason) for e in report.empty_slots)
    record_truth(job, before_strike=True)
    take_picture(job, "before_strike", cell.sim_time)
    if job.state.standing:
        strike(job, list(job.state.standing))
    record_truth(job, before_strike=False)
    report.simulated_s = cell.sim_time - started_sim
    report.wall_s = time.monotonic() - started_wall
    return report


def build(job: Job, turn: Callable[[Job, int, bool], Turn]) -> dict[int, Turn]:
    """Give slots turns, safety gaps (``settings.section``, where the planner can fill
    them: ``gaps.gap_slots``) last, until every slot stands or was given up (FAILED:
    recorded in ``report.empty_slots``, not queued again); a slot put off goes back
    behind another, unless its next turn would then come between two standing neighbours
    and the planner refuses it there: that turn, its last, comes before the second
    (``enclosure.enclosed``). How each slot's last turn ended."""
    gaps = gap_slots(job)
    order = build_order(job, [i for i in range(len(job.layout)) if i not in gaps]) + gaps
    queue = list(order)
    if gaps:
        numbers = ", ".join(str(i + 1) for i in gaps)
        log(f"safety gaps at dominoes {numbers}: built once the rest stands")
    standing, ended = job.state.standing, {}
    deferred: set[int] = set()  # slots put off since the last placement
    # slots put off whose next turn is their last: refused between their neighbours
    # (``enclosure``), why
    last_turns: dict[int, str] = {}
    while queue:
        index = queue.pop(0)
        enclosure = last_turns.pop(index, "")
        if index in standing:
            continue  # kept standing where it was (see attempts.keep_if_standing)
        # Only slots still to build count: a standing one left behind in the queue kept two
        # slots nothing planned for putting each other off for ever (S-curve seed 2).
        settled = deferred | set(standing)  # no turn to wait for
        if_placed = {*standing, index}
        job.upcoming = next(
            (i for i in requeue(job, queue, if_placed, order) if i not in if_placed), None
        )
        ended[index] = turn(job, index, not enclosure and any(i not in settled for i in queue))
        if ended[index] is Turn.DEFERRED:
            deferred.add(index)
            # before the safety gaps (filled last), but after at least one other slot that
            # was not put off (its turn may free this one): behind only gaps it came
            # straight back (S-curve 4); behind a slot put off too, the two took turns for
            # ever while a gap behind them never had one (S-curve 3). Unless that would
            # leave it between two standing neighbours where nothing plans: its last turn
            # then comes before the second is built (it cannot be put off again).
            first_open = next((k for k, i in enumerate(queue) if i not in settled), len(queue) - 1)
            first_gap = next((k for k, i in enumerate(queue) if i in gaps), len(queue))
            at = max(first_gap, first_open + 1)
            if enclosed_there := enclosed(job, index, queue[:at]):
                at, last_turns[index] = enclosed_there.before, enclosed_there.why
            queue.insert(at, index)
            continue
        if ended[index] is Turn.FAILED:  # given up: left empty, the run is built around it
            outcome = job.report.dominoes[index]
            reason = empty_reason(outcome.failures, outcome.deferrals, outcome.refusals)
            if enclosure:
                reason += f"; not put off again: refused between its neighbours ({enclosure})"
            job.report.empty_slots.append(EmptySlot(index + 1, reason))
            log(empty_message(index, reason))
        else:
            deferred.clear()
        queue = requeue(job, queue, standing, order)
    return ended


def requeue(
    job: Job, queue: list[int], standing: Collection[int], order: Sequence[int]
) -> list[int]:
    """The slots to build, in order, after a turn: those built earlier that no longer
    stand (knocked over, or their fallen domino picked up for another slot) first, in the
    build's ``order`` (a stretch from where it was started: ``task.order``), given-up ones
    not, then ``queue``."""
    given_up = {e.slot - 1 for e in job.report.empty_slots}
    empty = [i for i in order if i not in standing]
    return [i for i in empty if i not in queue and i not in given_up] + queue


def place_slot(job: Job, index: int, may_defer: bool) -> Turn:
    """Attempts at slot ``index`` until PLACED; FAILED after max_attempts carries (since
    its domino was set aside, if it was: ``staging``) or max_missed_picks picks that
    failed; or DEFERRED: nothing planned (e.g. fallen dominoes lie where it stands) and
    other slots may be built first, which may use up those fallen dominoes; FAILED at once
    when it cannot be put off and no domino can be placed there (``attempts.no_place``).
    A deferral costs planning calls, not an attempt; so does a sweep of debris out of the
    slot, and a look again at what lies in its way when nothing moved for it (once a
    turn: ``clearing.look_at_the_way``)."""
    outcome, settings, cell = job.report.dominoes[index], job.settings, job.cell
    failed: list[np.ndarray] = []  # spots refused for this slot, or whose pick failed
    refusals: list[Refusal] = []  # the planner's, since the last plan (``attempts.no_place``)
    missed = sweeps = 0
    looked = False
    earlier = job.state.set_aside_after.get(index, 0)  # attempts before its set aside
    sim_start, wall_start, spent = cell.sim_time, time.monotonic(), dict(cell.time_spent)
    while (
        outcome.attempts - earlier - missed < settings.max_attempts
        and missed < settings.max_missed_picks
    ):
        try:
            tried = attempt(job, index, failed, ignore_pile=not may_defer, refusals=refusals)
        except CellError as error:
            tried = Attempt(Outcome.NOT_PLACED, str(error))
        outcome.simulated_s += cell.sim_time - sim_start
        outcome.wall_s += time.monotonic() - wall_start
        sim_start, wall_start = cell.sim_time, time.monotonic()
        spent = add_spent(outcome.simulated_by_activity, cell.time_spent, spent)
        if tried.outcome is Outcome.NO_PLACE:  # nothing a push, a sweep or time would cure
            outcome.attempts += 1
            outcome.failures.append(tried.why)
            return Turn.FAILED
        if not tried.moved and sweeps < settings.max_sweeps and sweep_debris(job, index, failed):
            sweeps += 1
            failed.clear()  # refused while the debris lay there (missed picks: unpickable)
            refusals.clear()
            continue
        if not tried.moved and set_aside(job, index):
            failed.clear()  # refused beside the neighbour set aside
            refusals.clear()
            continue
        if not tried.moved and not looked and look_at_the_way(job, index):
            looked = True  # once a turn: what lies there as perception sees it now
            failed.clear()
            refusals.clear()
            continue
        if not tried.moved and may_defer:
            outcome.deferrals.append(tried.why)
            log(f"{job.domino(index)} put off ({tried.why}): others first")
            return Turn.DEFERRED
        outcome.attempts += 1
        if tried.outcome is Outcome.PLACED:
            outcome.placed = True
            kept = " (off target, left standing: it still topples the next)"
            log(
                f"{job.domino(index)} placed (attempt {outcome.attempts}): {outcome.check}"
                f"{kept if outcome.off_target else ''}; "
                f"{outcome.simulated_s:.1f} s simulated, {outcome.wall_s:.1f} s wall"
            )
            return Turn.PLACED
        outcome.failures.append(tried.why)
        if tried.outcome is Outcome.MISSED:
            failed.append(tried.spot)
            missed += 1
        log(f"{job.domino(index)} attempt {outcome.attempts} failed: {tried.why}")
    return Turn.FAILED

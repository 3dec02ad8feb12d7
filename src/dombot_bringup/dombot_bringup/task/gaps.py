"""Safety gaps the planner can fill: decided once the pile is in view, before the build.

A safety gap (``layouts.safety_gaps``) is built last, so its last slot goes in between
two standing neighbours. At tight spacing the planner may refuse every place there (the
pads meet the neighbours: s_curve30 at 22 mm refused all four of its gaps' last slots,
each of which plans with one neighbour standing), and the gap would stay empty. So before
the first slot is built, the planner is asked to place a flat pile domino at each gap's
last slot with the run standing as the build will leave it then. Refused its place
(PLACE_UNREACHABLE, PLACE_IN_COLLISION: a flat domino's holds are those of any flat one),
the gap moves to the nearest position in its stretch whose last slot plans, at most
``gap_moves`` slots either way; when none does it is dropped, and its stretch is built in
run order. A grasp refusal says nothing of the slot: the next flat domino is asked (at
most ``gap_probe_dominoes``); when none answers about the slot, the gap is kept as it is.
"""

from __future__ import annotations

from collections.abc import Collection
from dataclasses import dataclass, replace
from enum import Enum

from dombot_bringup.layouts import gap_at, safety_gaps
from dombot_bringup.offers import PILE_IGNORED
from dombot_bringup.run_report import GapDecision
from dombot_bringup.task.cell import CellError, Detections, Later, Posture
from dombot_bringup.task.picking import Candidate, look_at_pile, pile_candidate, place_request
from dombot_bringup.task.state import Job, log
from dombot_planner.errors import ErrorCode

PLACE_REFUSALS = (ErrorCode.PLACE_UNREACHABLE, ErrorCode.PLACE_IN_COLLISION)


class Fill(Enum):
    """What the planner said of a gap's last slot between its standing neighbours."""

    PLANS = "plans"
    REFUSED = "refused"  # the place itself: no flat domino goes there
    UNKNOWN = "unknown"  # grasps refused, a timeout, no answer: nothing said of the slot


@dataclass(frozen=True)
class Probe:
    fill: Fill
    why: str  # the planner's refusal, or why nothing was learnt
    plans: int  # planning calls made


def gap_slots(job: Job) -> list[int]:
    """The slots to build last: the safety gaps of ``settings.section``, each kept, moved
    or dropped as the planner can fill its last slot (``decide``). Asks for the first
    look at the pile, which the first turn then uses."""
    gaps = safety_gaps(job.layout, job.settings.section)
    asked = job.settings.gap_probe_dominoes
    dominoes = flat_pile_dominoes(job)[:asked] if gaps and asked else []
    if gaps and dominoes:
        gaps = decide(job, gaps, dominoes)
    elif gaps and asked:
        log("safety gaps: no flat pile domino seen to ask the planner with; kept as laid out")
    return [i for gap in gaps for i in gap]


def flat_pile_dominoes(job: Job) -> list[Candidate]:
    """The flat pile dominoes of a look at the pile, perception's best first; the look
    is kept for the first turn (``job.pile_look``)."""
    try:
        detections, unexplained = look_at_pile(job)
    except CellError as error:
        log(f"safety gaps: {error}")
        return []
    if detections:
        seen = Detections(True, "", tuple(detections), unexplained)
        job.pile_look = Later(lambda: seen)
    return [
        pile_candidate(d, detections, unexplained) for d in detections if d.posture == Posture.FLAT
    ]


def decide(job: Job, gaps: list[range], dominoes: list[Candidate]) -> list[range]:
    """Each of ``gaps`` kept, moved within its stretch (between the gap before it, as
    decided, and the one after it) or dropped; every decision in the log and the report."""
    decided: list[range] = []
    for number, gap in enumerate(gaps):
        later = {i for other in gaps[number + 1 :] for i in other}
        low = decided[-1].stop + 1 if decided else 1
        high = gaps[number + 1].start if number + 1 < len(gaps) else len(job.layout)
        asked = probe(job, gap[-1], others_standing(job, gap, later), dominoes)
        plans, now = asked.plans, gap
        if asked.fill is Fill.REFUSED:
            now = None
            for other in moves(job, gap, low, high):
                tried = probe(job, other[-1], others_standing(job, other, later), dominoes)
                plans += tried.plans
                if tried.fill is Fill.PLANS:
                    now = other
                    break
        verdict = "dropped" if now is None else "kept" if now == gap else "moved"
        job.report.safety_gaps.append(
            GapDecision([i + 1 for i in gap], verdict, [i + 1 for i in now or ()], asked.why, plans)
        )
        log(f"safety gap at {names(gap)}: {verdict}{verdict_words(asked, now)}")
        if now is not None:
            decided.append(now)
    return decided


def moves(job: Job, gap: range, low: int, high: int) -> list[range]:
    """Where else ``gap`` may go, nearest first, at most ``gap_moves`` slots either way:
    its first slot at ``low`` or after, the first domino after it (that of the next
    section) before ``high``."""
    others = []
    for shift in range(1, job.settings.gap_moves + 1):
        for first in (gap.start + shift, gap.start - shift):
            other = gap_at(job.layout, first) if first >= low else None
            if other is not None and other.stop < high:
                others.append(other)
    return others


def others_standing(job: Job, gap: range, later: Collection[int]) -> list[int]:
    """The slots standing when ``gap``'s last slot comes: every other but those of
    ``later`` gaps."""
    return [i for i in range(len(job.layout)) if i != gap[-1] and i not in later]


def probe(
    job: Job,
    slot: int,
    standing: Collection[int],
    dominoes: list[Candidate],
    where: str = "between its neighbours",
) -> Probe:
    """Whether the planner places a flat pile domino (the first of ``dominoes``) at
    ``slot`` with the slots ``standing`` standing (as the build leaves the run then),
    ignoring the domino's pile and any debris (only the place is in question); the next
    domino when its grasp is refused. ``where``: the log's words for ``standing``."""
    targets = tuple(job.targets[i] for i in sorted(standing))
    plans, why = 0, ""
    for candidate in dominoes:
        request = replace(place_request(job, slot, candidate, PILE_IGNORED), standing=targets)
        try:
            plan = job.cell.plan_place(request)
        except CellError as error:
            return Probe(Fill.UNKNOWN, str(error), plans)
        plans += 1
        if plan.success:
            return Probe(Fill.PLANS, "", plans)
        why = plan.message.split(" (")[0]
        log(f"{job.domino(slot)} {where} refused: {why}")
        if plan.error in PLACE_REFUSALS:
            return Probe(Fill.REFUSED, why, plans)
        if plan.error != ErrorCode.GRASP_UNREACHABLE:
            break
    return Probe(Fill.UNKNOWN, why or "no flat pile domino", plans)


def names(slots: range) -> str:
    numbers = ", ".join(str(i + 1) for i in slots)
    return f"domino {numbers}" if len(slots) == 1 else f"dominoes {numbers}"


def verdict_words(asked: Probe, now: range | None) -> str:
    """The log's words after a gap's verdict: where it went and why."""
    if asked.fill is not Fill.REFUSED:
        return f" (nothing said of its last slot: {asked.why})" if asked.why else ""
    refused = f"its last slot refused between its neighbours ({asked.why})"
    if now is None:
        return f": {refused}, and every position tried; its stretch is built in run order"
    return f" to {names(now)}: {refused}"

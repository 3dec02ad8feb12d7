"""A slot put off before both its neighbours stand: may its next turn come between them?

A slot put off (nothing planned for it: ``loop.Turn.DEFERRED``) goes back in the queue
behind a slot that was not put off (``loop.build``), in run order its next neighbour: its
next turn then comes between two standing dominoes, where at tight spacing the planner
may refuse every place (the pads meet them). s_curve30's first 10 at 22 mm put slot 3 off
(nothing planned with slot 2 standing), built the 4th, and had slot 3 refused between the
two at a turn behind each later slot, then left it empty. The gap check (``task.gaps``)
asks only of the safety gaps, before the build. So when a slot put off would next come
between two standing neighbours, the planner is asked the gap check's question
(``gaps.probe``: a flat pile domino at the slot, its pile ignored, both neighbours
standing). Refused its place, the slot's next turn comes before the neighbour that would
enclose it, and is its last (it is not put off again): placed, or left empty, at once
when no flat domino's place plans (``attempts.no_place``) — a section break, not more
turns.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from dombot_bringup.task.gaps import Fill, flat_pile_dominoes, probe
from dombot_bringup.task.state import Job, log


@dataclass(frozen=True)
class Enclosed:
    """A slot put off that the planner refused between its neighbours."""

    before: int  # where in the queue its last turn goes: before the neighbour enclosing it
    why: str  # the planner's refusal


def enclosing(job: Job, index: int, ahead: Sequence[int]) -> int | None:
    """Where in ``ahead`` (the slots whose turns come before slot ``index``'s next one)
    is the neighbour whose placement leaves it between two standing ones; None when it
    has not two neighbours, or one of them stands empty then (given up, or built later)."""
    neighbours = [i for i in (index - 1, index + 1) if 0 <= i < len(job.layout)]
    empty = [i for i in neighbours if i not in job.state.standing]
    if len(neighbours) < 2 or not empty or any(i not in ahead for i in empty):
        return None
    return max(ahead.index(i) for i in empty)


def enclosed(job: Job, index: int, ahead: Sequence[int]) -> Enclosed | None:
    """Slot ``index``, just put off, with ``ahead`` to be built before its next turn:
    where its last turn goes instead, when that turn would come between two standing
    neighbours and the planner refuses a flat domino's place there (with the slots
    standing as the build leaves them then); None: put off as any other (not enclosed
    then, the place plans, or the planner said nothing of it)."""
    asked = job.settings.enclosure_probe_dominoes
    before = enclosing(job, index, ahead) if asked else None
    if before is None:
        return None
    dominoes = flat_pile_dominoes(job)[:asked]
    if not dominoes:
        log(f"{job.domino(index)}: no flat pile domino to ask between its neighbours with")
        return None
    standing = {*job.state.standing, *ahead[: before + 1]} - {index}
    answer = probe(job, index, standing, dominoes)
    if answer.fill is not Fill.REFUSED:
        said = "it plans" if answer.fill is Fill.PLANS else f"nothing said of it ({answer.why})"
        log(f"{job.domino(index)} between its neighbours: {said}; put off as any other")
        return None
    log(f"{job.domino(index)}: its last turn now, before domino {ahead[before] + 1} encloses it")
    return Enclosed(before, answer.why)

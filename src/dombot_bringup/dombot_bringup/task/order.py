"""Where each stretch of the run is started: decided before the build, asked of the planner.

Built in run order, each slot is placed with the one behind it standing. At tight spacing
only a hold leaning over the free side (ahead) plans there: the pads of one leaning over
a standing neighbour come within fine_obstacle_clearance of it (docs/PLANNER.md, Limits).
Where the run heads towards the arm near its inner reach, the lean ahead is out of reach
(the wrist beyond the elbow's reach): the s-curve of 10 at 22 mm refused slots 2-4 with
the one behind standing and planned each with the one ahead standing. Such a slot must be
built before the one behind it, and that one before its own, so its stretch is built from
there (its start) backwards to its first slot, then forwards from the start: no slot
of the stretch has both neighbours standing at its turn, where nothing plans at 22 mm.

Before the build, in a stretch (consecutive slots between the safety gaps) whose
neighbours stand closer than ``order_probe_spacing``, the planner is asked as the gap
check asks (``gaps.probe``: a flat pile domino, its pile ignored) whether each slot
plans with the one behind standing, from the stretch's last slot backwards until one is
refused. That one starts the stretch when every slot before it plans with the one ahead
standing (asked too); else the stretch is built in run order (a slot refused then is put
off: ``enclosure``). A grasp refusal says nothing of a slot: the next flat domino is
asked, and the refused one not again in that stretch; when none answers
(``Fill.UNKNOWN``), the slot is taken as planned.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import pairwise

from dombot_bringup.run_report import StretchStart
from dombot_bringup.task.gaps import Fill, Probe, flat_pile_dominoes, probe
from dombot_bringup.task.picking import Candidate
from dombot_bringup.task.state import Job, log

BEHIND, AHEAD = "with the one behind standing", "with the one ahead standing"


def stretches(slots: Sequence[int]) -> list[range]:
    """``slots`` (ascending) as runs of consecutive ones."""
    runs: list[range] = []
    for index in slots:
        if runs and runs[-1].stop == index:
            runs[-1] = range(runs[-1].start, index + 1)
        else:
            runs.append(range(index, index + 1))
    return runs


def from_start(stretch: range, start: int) -> list[int]:
    """``stretch`` built from ``start`` backwards to its first slot, then onwards."""
    return [*range(start, stretch.start - 1, -1), *range(start + 1, stretch.stop)]


def tight(job: Job, stretch: range) -> bool:
    """Whether two neighbours of ``stretch`` stand closer than order_probe_spacing."""
    spots = [(job.layout[i].x, job.layout[i].y) for i in stretch]
    spacing = job.settings.order_probe_spacing
    return any(math.dist(a, b) < spacing for a, b in pairwise(spots))


def build_order(job: Job, slots: Sequence[int]) -> list[int]:
    """``slots`` (every slot but the safety gaps, ascending) in the order to build them:
    each stretch of consecutive ones from its start (``start_of``) backwards, then
    onwards; every stretch asked about is in the log and the report."""
    asked = job.settings.order_probe_dominoes
    runs = stretches(slots)
    probed = [stretch for stretch in runs if len(stretch) > 1 and tight(job, stretch)]
    dominoes = flat_pile_dominoes(job)[:asked] if asked and probed else []
    if probed and asked and not dominoes:
        log("build order: no flat pile domino seen to ask the planner with; run order")
    order: list[int] = []
    for stretch in runs:
        start = stretch.start
        if dominoes and stretch in probed:
            decision = start_of(job, stretch, dominoes)
            job.report.build_order.append(decision)
            log(
                f"build order: dominoes {stretch.start + 1}-{stretch.stop} started at "
                f"{decision.start}{decision.words()}"
            )
            start = decision.start - 1
        order += from_start(stretch, start)
    return order


def start_of(job: Job, stretch: range, dominoes: list[Candidate]) -> StretchStart:
    """Where ``stretch`` is started: its last slot refused with the one behind standing,
    when every slot before it plans with the one ahead standing; else its first slot."""
    first, last = stretch.start + 1, stretch.stop
    dominoes = list(dominoes)
    plans, refused = 0, None

    def asked(index: int, neighbour: int, where: str) -> Probe:
        nonlocal plans
        answer = probe(job, index, [neighbour], dominoes, where)
        plans += answer.plans
        if answer.fill is not Fill.UNKNOWN:  # those asked before it: their grasps refused
            del dominoes[: answer.plans - 1]
        return answer

    for index in reversed(stretch[1:]):
        behind = asked(index, index - 1, BEHIND)
        if behind.fill is Fill.REFUSED:
            refused = (index, behind.why)
            break
    if refused is None:
        return StretchStart(first, last, first, "", "", plans)
    start, why = refused
    for index in range(start - 1, stretch.start - 1, -1):
        ahead = asked(index, index + 1, AHEAD)
        if ahead.fill is Fill.REFUSED:
            return StretchStart(
                first, last, first, f"{start + 1}: {why}", f"{index + 1}: {ahead.why}", plans
            )
    return StretchStart(first, last, start + 1, f"{start + 1}: {why}", "", plans)

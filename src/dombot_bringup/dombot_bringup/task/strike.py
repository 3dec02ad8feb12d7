"""Knocking down what stands: each section (consecutive standing slots) struck from its
own first domino, from the run's end backwards (``sections``); perception's word on what
fell, and where it lies."""

from __future__ import annotations

from collections.abc import Sequence

from dombot_bringup.run_report import SectionOutcome
from dombot_bringup.sections import Section, sections_of, strike_order
from dombot_bringup.task.cell import Seen, StrikeRequest
from dombot_bringup.task.checks import remember_fallen, settle
from dombot_bringup.task.placing import execute
from dombot_bringup.task.records import take_picture
from dombot_bringup.task.state import Job, log
from dombot_description import tipped_pose


def strike(job: Job, standing: Sequence[int]) -> None:
    """Knock over the dominoes at layout indices ``standing`` as sections, in
    ``sections.strike_order`` so that no strike reaches a section still standing; then one
    look by perception counts what fell, section by section. A full run is one section."""
    built = sorted(standing)
    sections = sections_of(built)
    report = job.report
    report.sections = [SectionOutcome(s.first + 1, s.last + 1) for s in sections]
    outcomes = dict(zip(sections, report.sections, strict=True))
    for section in strike_order(sections, job.layout):
        outcome = outcomes[section]
        outcome.message = strike_section(job, section, built)
        outcome.struck = not outcome.message
        if outcome.message:
            words = f"{section}: {outcome.message}"
            report.message = "; ".join(m for m in (report.message, words) if m)
            log(words)
    if not any(s.struck for s in report.sections):
        return
    report.struck = all(s.struck for s in report.sections)
    fresh = settle(job, job.settings.topple_wait)
    take_picture(job, "after_strike", fresh)
    answer = job.cell.check_placement([job.targets[i] for i in built], not_before=fresh)
    down = [s != Seen.STANDING for s in answer.status] if answer.success else [False] * len(built)
    fallen = dict(zip(built, down, strict=True))
    for section, outcome in outcomes.items():
        outcome.toppled_by_perception = sum(fallen[i] for i in section.slots)
    report.toppled_by_perception = answer.success and all(fallen.values())
    log(f"after the strike perception sees {sum(fallen.values())}/{len(built)} dominoes down")
    unfitted = []  # one line for them all: after a strike most lie in a heap
    for position, i in enumerate(built):  # where they lie, for a next cycle to pick up
        if fallen[i]:
            job.state.standing.pop(i, None)
            status, tilt = answer.status[position], answer.tilt[position]
            if remember_fallen(job, i, status, answer.measured[position], tilt):
                unfitted.append(str(i + 1))
                lean = job.settings.unfitted_lean
                job.state.unfitted.append(tipped_pose(job.targets[i], lean))
    if unfitted:
        log(
            f"{len(unfitted)} toppled dominoes lie where perception cannot fit them "
            f"({', '.join(unfitted)}): taken to lie tipped over their slots' front edge, "
            "obstacles to sweep out of a slot's way"
        )


def strike_section(job: Job, section: Section, built: Sequence[int]) -> str:
    """Strike ``section``'s first domino, every other of the ``built`` slots an obstacle;
    "" once the arm pushed it, or why not."""
    whole = len(built) == len(job.layout)
    log("the run stands: knocking it down" if whole else f"knocking down {section}")
    plan = job.cell.plan_strike(
        StrikeRequest(
            domino=job.targets[section.first],
            standing=tuple(job.targets[i] for i in built if i != section.first),
            time_budget=job.settings.plan_budget,
        )
    )
    if not plan.success:
        return f"strike planning failed: {plan.message}"
    execution = execute(job, plan.segments, holds_domino=False)
    return "" if execution.done else f"strike failed: {execution.why}"

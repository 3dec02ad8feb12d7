"""Knocking down what stands: each section (consecutive standing slots) struck from its
own first domino, from the run's end backwards (``sections``); perception's word on what
fell, and where it lies."""

from __future__ import annotations

from collections.abc import Mapping, Sequence

from dombot_bringup.run_report import SectionOutcome
from dombot_bringup.sections import Section, sections_of, strike_order
from dombot_bringup.task.cell import PlacementCheck, Pose, Seen, StrikeRequest
from dombot_bringup.task.checks import remember_fallen, settle
from dombot_bringup.task.placing import execute
from dombot_bringup.task.records import take_picture
from dombot_bringup.task.state import Job, log
from dombot_description import tipped_pose

LOOK_TRIES = 3  # looks after the strike before it counts as not seen


def strike(job: Job, standing: Sequence[int]) -> None:
    """Knock over the dominoes at layout indices ``standing`` as sections, in
    ``sections.strike_order`` so that no strike reaches a section still standing; then one
    look by perception counts what fell, section by section. What it sees still standing
    (a chain broken by a domino kept off its target, arc10_cycles5 seed 3) is struck again
    the same way from where it stands, up to ``settings.strike_again`` times, so the run
    still ends down. A full run is one section."""
    built = sorted(standing)
    report = job.report
    report.sections = []
    poses = {i: job.targets[i] for i in built}  # where each stands, as far as known
    upright, answer = built, None
    for again in range(job.settings.strike_again + 1):
        if again:
            names = ", ".join(str(i + 1) for i in upright)
            log(f"still standing after the strike: {names}; striking again where they stand")
        if not strike_sections(job, upright, poses, again + 1):
            break
        answer = look_after_strike(job, built)
        if not answer.success:
            break
        seen = zip(built, answer.status, answer.measured, strict=True)
        still = {i: measured for i, status, measured in seen if status == Seen.STANDING}
        if not still:
            break
        upright = list(still)  # in run order, as ``built``
        poses.update(still)
    if answer is None:
        return
    report.struck = all(s.struck for s in report.sections)
    down = [s != Seen.STANDING for s in answer.status] if answer.success else [False] * len(built)
    fallen = dict(zip(built, down, strict=True))
    for outcome in report.sections:
        slots = range(outcome.first_slot - 1, outcome.last_slot)
        outcome.toppled_by_perception = sum(fallen[i] for i in slots)
    report.toppled_by_perception = answer.success and all(fallen.values())
    if answer.success:
        log(f"after the strike perception sees {sum(fallen.values())}/{len(built)} dominoes down")
    else:
        log(f"after the strike perception could not look: {answer.message}")
    unfitted = []  # one line for them all: after a strike most lie in a heap
    for position, i in enumerate(built):  # where they lie, for a next cycle to pick up
        if fallen[i]:
            job.state.knocked_down(i)
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


def strike_sections(
    job: Job, upright: Sequence[int], poses: Mapping[int, Pose], strike_round: int
) -> bool:
    """Strike the sections of the ``upright`` slots (at ``poses``) in ``strike_order``,
    each outcome added to the report; whether any was struck."""
    sections = sections_of(upright)
    report = job.report
    outcomes = {s: SectionOutcome(s.first + 1, s.last + 1, round=strike_round) for s in sections}
    report.sections.extend(outcomes.values())
    for section in strike_order(sections, job.layout):
        outcome = outcomes[section]
        outcome.message = strike_section(job, section, upright, poses)
        outcome.struck = not outcome.message
        if outcome.message:
            words = f"{section}: {outcome.message}"
            report.message = "; ".join(m for m in (report.message, words) if m)
            log(words)
    return any(outcome.struck for outcome in outcomes.values())


def look_after_strike(job: Job, built: Sequence[int]) -> PlacementCheck:
    """Perception's look at every slot struck, once what fell has settled; a look that
    failed is asked again a camera period on, LOOK_TRIES times in all (circle30 seed 6: one
    check that raised made a toppled run of 30 "0/30 seen down" and the job fail)."""
    fresh = settle(job, job.settings.topple_wait)
    take_picture(job, "after_strike", fresh)
    expected = [job.targets[i] for i in built]
    for attempt in range(LOOK_TRIES):
        if attempt:
            fresh = settle(job, 1.0 / job.settings.camera_rate)
        answer = job.cell.check_placement(expected, not_before=fresh)
        if answer.success:
            break
        log(f"perception's look after the strike failed: {answer.message}")
    return answer


def strike_section(
    job: Job, section: Section, upright: Sequence[int], poses: Mapping[int, Pose]
) -> str:
    """Strike ``section``'s first domino, every other of the ``upright`` slots an
    obstacle, each at ``poses``; "" once the arm pushed it, or why not."""
    whole = len(upright) == len(job.layout)
    log("the run stands: knocking it down" if whole else f"knocking down {section}")
    plan = job.cell.plan_strike(
        StrikeRequest(
            domino=poses[section.first],
            standing=tuple(poses[i] for i in upright if i != section.first),
            time_budget=job.settings.plan_budget,
        )
    )
    if not plan.success:
        return f"strike planning failed: {plan.message}"
    execution = execute(job, plan.segments, holds_domino=False)
    return "" if execution.done else f"strike failed: {execution.why}"

"""Knocking the run down: the first domino struck, perception's word on what fell."""

from __future__ import annotations

from collections.abc import Sequence

from dombot_bringup.task.cell import Seen, StrikeRequest
from dombot_bringup.task.checks import settle
from dombot_bringup.task.placing import execute
from dombot_bringup.task.records import take_picture
from dombot_bringup.task.state import Job, log


def strike(job: Job, run: Sequence[int]) -> None:
    """Knock over the dominoes at layout indices ``run`` (in run order, all standing) by
    striking the first, the rest kept clear of on the way; perception then checks that
    every one fell."""
    targets = [job.targets[i] for i in run]
    report = job.report
    plan = job.cell.plan_strike(
        StrikeRequest(
            domino=targets[0], standing=tuple(targets[1:]), time_budget=job.settings.plan_budget
        )
    )
    if not plan.success:
        report.message = f"strike planning failed: {plan.message}"
        log(report.message)
        return
    execution = execute(job, plan.segments, holds_domino=False)
    if not execution.done:
        report.message = f"strike failed: {execution.why}"
        log(report.message)
        return
    report.struck = True
    fresh = settle(job, job.settings.topple_wait)
    take_picture(job, "after_strike", fresh)
    answer = job.cell.check_placement(targets, not_before=fresh)
    fallen = [s != Seen.STANDING for s in answer.status]
    report.toppled_by_perception = answer.success and all(fallen)
    log(f"after the strike perception sees {sum(fallen)}/{len(fallen)} dominoes down")

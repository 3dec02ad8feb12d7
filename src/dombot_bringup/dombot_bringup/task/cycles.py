"""The perpetual cycle (``--cycles``): build a layout, knock it down, build the next one
from the dominoes the strike left lying in the build area and what is left of the pile,
and so on.

The pile is poured once. After each strike perception says where the run's dominoes lie
(``strike``: its look at what fell); the next cycle takes them as ``BuildState.toppled``
(one measured twice, once): offered for each slot before the pile's, one in the slot's
way first (it is cleared by becoming its domino; nothing else is placed there while one
lies in its way, ``attempts.clear_the_way``), then the nearest the slot, and obstacles
for every carry and placement until picked up; looked at again where something moved
near them (``checks.look_again``). Those seen down but not fitted are taken to lie
tipped over their slot's front edge (``BuildState.unfitted``): obstacles, swept out of a
slot's way, never picked unless a look again fits them (one at each cycle's start). A
cycle that failed (a strike refused, or dominoes left standing) ends the cycles: what
stands where the next layout goes is nothing the next cycle knows.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence

from dombot_bringup.layouts import DominoPlacement
from dombot_bringup.run_report import CycleOutcome, RunReport
from dombot_bringup.sections import EXIT_FAILED, VERDICTS
from dombot_bringup.task.cell import Cell, Pose
from dombot_bringup.task.geometry import spot_of
from dombot_bringup.task.loop import run
from dombot_bringup.task.picking import is_among
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import BuildState, Job, log

Layout = tuple[str, Sequence[DominoPlacement]]  # a layout's name and its dominoes


def run_cycles(
    cell: Cell,
    layouts: Sequence[Layout],
    settings: ArmJobSettings,
    memory: Callable[[], Mapping[str, float]] = dict,
    started: Callable[[Job], None] = lambda job: None,
) -> list[Job]:
    """One cycle per layout of ``layouts`` (the first pours the pile), until they are done
    or one failed; the cycles' jobs, each report's ``cycles`` listing every cycle up to
    its own. ``memory``: resident MB of each process, read at each cycle's end;
    ``started``: told each cycle's job as it starts (for a report if a node dies)."""
    jobs: list[Job] = []
    outcomes: list[CycleOutcome] = []
    for number, (name, layout) in enumerate(layouts, 1):
        job = Job.new(cell, layout, name, settings)
        if jobs:
            # numbered on from the last cycle's: each cycle's from 0 wrote over the earlier
            # cycles' records in the one --record-picks folder
            job.picks_recorded = jobs[-1].picks_recorded
            earlier = jobs[-1].state
            job.state.toppled, job.state.unfitted = left_lying(earlier)
            # those the strike's look did not measure, looked at again before the first
            # pick (``checks.look_again``), nothing near them having moved since:
            # perception refits a lying one turned about the vertical too, so one turned by
            # a pick or push is picked, not carried along as an obstacle (seed 2: 1, 3 and
            # 7 carried into cycles 3, 4 and 5); and one the strike or a pick moved is not
            # sought where it lay before (arc cycles seed 3: one remembered 19 mm from
            # where it lay kept slot 1 empty in cycles 1-4, every grasp and sweep of the
            # remembered pose refused)
            stale = [*earlier.toppled, *earlier.unfitted]
            job.state.disturbed = [spot_of(pose) for pose in stale]
            unfitted = len(job.state.unfitted)
            again = f", {unfitted} more seen down but not fitted" if unfitted else ""
            if stale:
                again += f": {len(stale)} seen before the strike or not fitted"
                again += " looked at again first"
            log(
                f"cycle {number}/{len(layouts)}: building '{name}' ({len(layout)} dominoes) "
                f"from {len(job.state.toppled)} toppled dominoes seen lying and the pile{again}"
            )
        found = len(job.state.toppled) + len(job.state.unfitted)
        job.report.cycles = list(outcomes)  # the report of a cycle cut short has the others
        started(job)
        report = run(job, pour=not jobs)
        picked = job.state.toppled_picked
        outcomes.append(cycle_outcome(number, report, found, picked, memory()))
        report.cycles = list(outcomes)
        jobs.append(job)
        if len(layouts) > 1:
            log(cycle_line(outcomes[-1], len(layouts)))
        if outcomes[-1].exit_status == EXIT_FAILED and number < len(layouts):
            log(f"cycle {number} failed: no more cycles ({report.message})")
            break
    return jobs


def left_lying(state: BuildState) -> tuple[list[Pose], list[Pose]]:
    """What a cycle leaves lying for the next: the dominoes located (to pick up) and
    those seen down but not fitted (obstacles where they presumably lie), each once."""
    lying = state.lying()
    unfitted = [pose for pose in lying if is_among(pose, state.unfitted)]
    return [pose for pose in lying if not is_among(pose, unfitted)], unfitted


def cycle_outcome(
    number: int, report: RunReport, found: int, picked: int, rss: Mapping[str, float]
) -> CycleOutcome:
    """What cycle ``number`` did: ``found`` toppled dominoes at its start (unfitted ones
    too), ``picked`` of them picked up."""
    summary = report.summary()
    return CycleOutcome(
        cycle=number,
        layout=report.layout,
        dominoes=summary["dominoes"],
        placed=summary["placed"],
        placed_first_attempt=summary["placed_first_attempt"],
        toppled_found=found,
        toppled_picked=picked,
        empty_slots=summary["empty_slots"],
        toppled_by_perception=sum(s.toppled_by_perception for s in report.sections),
        toppled_by_truth=report.toppled_by_truth,
        exit_status=report.own_exit_status,  # the job's is the worst cycle's so far
        simulated_s=report.simulated_s,
        wall_s=report.wall_s,
        rss_mb={name: round(mb, 1) for name, mb in rss.items()},
    )


def cycle_line(outcome: CycleOutcome, cycles: int) -> str:
    """The log's one line for a cycle."""
    memory = ", ".join(f"{name} {mb:.0f}" for name, mb in outcome.rss_mb.items())
    empty = ", ".join(map(str, outcome.empty_slots)) or "none"
    return (
        f"cycle {outcome.cycle}/{cycles} '{outcome.layout}': {VERDICTS[outcome.exit_status]}, "
        f"{outcome.placed}/{outcome.dominoes} placed ({outcome.placed_first_attempt} at the "
        f"first attempt), {outcome.toppled_picked} of {outcome.toppled_found} toppled "
        f"picked up, empty slots: {empty}, {outcome.toppled_by_perception} seen down; "
        f"{outcome.simulated_s:.0f} s simulated, {outcome.wall_s:.0f} s wall; "
        f"RSS MB: {memory or 'not measured'}"
    )

"""Clearing the way with pushes (/plan_strike's sweep): fallen debris out of a slot it
blocks, a crowded pile spread, a jammed one stirred, a pile domino no grasp takes as it
lies pushed over or slid into reach."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np

from dombot_bringup.debris import carried_along, pushed_whole_way, sweep_pushes
from dombot_bringup.layouts import DOMINO_LENGTH
from dombot_bringup.offers import roomiest_first
from dombot_bringup.spread import TIP_DISTANCE, lay_flat_pushes, spread_pushes, stir_pushes
from dombot_bringup.task.cell import Plan, Pose, StrikeRequest, planner_strike_request
from dombot_bringup.task.checks import check, look_again
from dombot_bringup.task.geometry import near, near_any, spot_of
from dombot_bringup.task.picking import PLANNER_SETTINGS, Candidate, in_its_way, is_among
from dombot_bringup.task.placing import execute
from dombot_bringup.task.state import Job, log
from dombot_planner.strike_foresight import foreseen_strike_refusal

SPREAD_TRIES = 2  # pushes of one pile domino offered to the planner (the shortest first)


def sweep_debris(job: Job, index: int, failed: list[np.ndarray]) -> bool:
    """Push aside a fallen or toppled domino within a domino length of slot ``index``
    that no grasp reached (refused, or its pick failed; an unfitted one, never offered),
    or one of two or more in its way (``picking.in_its_way``): those no grasp reached
    first, nearest the slot first, out of the slot's way, the lying dominoes on its way
    pushed along (``debris.carried_along``: a shingled row as one blob; the standing run
    and the other lying dominoes kept clear of; every lying one kept clear of where one
    of those lies within carry_clearance of the standing run); True once one was pushed
    (or the push failed after the arm moved)."""
    state, settings = job.state, job.settings
    place, avoid = spot_of(job.releases[index]), failed + state.unpickable
    way = in_its_way(job, index)
    known = state.lying()  # a domino remembered twice is swept once
    earlier = [(None, pose) for pose in [*state.toppled, *state.unfitted]]
    lying = [(k, pose) for k, pose in [*state.fallen.items(), *earlier] if is_among(pose, known)]
    refused = [
        near_any(spot_of(pose), avoid) or is_among(pose, state.unfitted) for _, pose in lying
    ]
    debris = sorted(
        (not refused[n], float(np.linalg.norm(spot_of(pose) - place)), n)
        for n, (_, pose) in enumerate(lying)
        if (is_among(pose, way) and (refused[n] or len(way) > 1))
        or (refused[n] and near(spot_of(pose), place, DOMINO_LENGTH))
    )
    margin = sweep_margin(job)
    standing = list(state.standing.values())
    clearance = PLANNER_SETTINGS.coarse_clearance
    for _, _, n in debris:
        k, pose = lying[n]
        others = [p for p in known if p is not pose]
        for direction, distance in sweep_pushes(pose, job.layout[index], margin):
            name = "toppled domino" if k is None else f"domino {k + 1}"
            what = f"{name} lying at {spot_of(pose).round(3).tolist()}"
            push = distance * np.asarray(direction)[:2]
            if state.sweep_refused(spot_of(pose), push):
                continue  # refused as it is now: not asked again (logged then)
            along = carried_along(
                pose, others, standing, direction, distance, clearance, settings.carry_clearance
            )
            along = along or []  # None: one would near the standing run; all kept clear of
            where = "across the run" + (f", {len(along)} lying on its way with it" if along else "")
            kept = [p for m, p in enumerate(others) if m not in along]
            swept = sweep(job, pose, kept, direction, distance, what, where)
            if swept is None:
                state.unswept.append((spot_of(pose), push, frozenset(state.standing)))
                continue
            job.report.dominoes[index].sweeps.append(swept)
            log(f"{job.domino(index)}: {swept}")
            # Those pushed the whole way lie where the push left them too, until looked at
            # again there: remembered where they lay, one behind a domino swept out of a
            # slot would be pushed into the slot and looked for where it had been.
            for m in along:
                if pushed_whole_way(pose, others[m], direction):
                    state.pushed_along(others[m], push)
                else:  # brushed: looked at again where it lay
                    state.forget_refusals_near(spot_of(others[m]))
            if k is None:  # not a slot perception checks: taken to lie where it was pushed
                state.pushed_along(pose, push)
            else:
                state.fallen.pop(k)
                check(job, k, just_placed=False)  # still there (fallen again) or gone
            return True
    return False


def look_at_the_way(job: Job, index: int) -> bool:
    """The lying dominoes in slot ``index``'s way looked at again (``checks.look_again``)
    before an attempt is spent on them or the slot put off: one remembered where it no
    longer lies (a strike, pick or sweep moved it unseen) has every grasp and sweep
    refused there (arc cycles seed 3: slot 1 left empty in cycles 1-4 for one remembered
    19 mm from where it lay). True when there were any."""
    way = in_its_way(job, index)
    if not way:
        return False
    log(f"{job.domino(index)}: looking again at the {len(way)} lying in its way")
    job.state.disturbed.extend(spot_of(pose) for pose in way)
    look_again(job)
    return True


def sweep_margin(job: Job) -> float:
    """How far beyond the run's side a sweep leaves debris: sweep_margin, and out of the
    slot's way (``picking.in_its_way``) by a millimetre more."""
    settings = job.settings
    return max(settings.sweep_margin, settings.clear_margin + settings.clear_pads + 1e-3)


def spread(job: Job, index: int, candidates: Sequence[Candidate]) -> bool:
    """Push one of the pile ``candidates`` (none of which planned; roomiest first) out of
    its crowd (``spread.spread_pushes``, the planner keeping it clear of its neighbours),
    or when no such push plans, through them (``spread.stir_pushes``: the pile is
    jammed), asking the planner at most spread_plans times for each; True once the arm
    moved."""
    settings, asked = job.settings, [0, 0]
    pile = roomiest_first([c for c in candidates if c.from_pile])
    for jammed in (False, True):
        for candidate in pile:
            if asked[jammed] == settings.spread_plans:
                break
            limit = settings.spread_plans - asked[jammed]
            spread, tried = push_out_of_crowd(job, candidate, jammed, limit)
            asked[jammed] += tried
            if spread is not None:
                job.report.dominoes[index].spreads.append(spread)
                log(f"{job.domino(index)}: spreading the pile: {spread}")
                return True
    if not any(asked):
        log(f"{job.domino(index)}: no push would spread the pile")
    return False


def isolate(job: Job, index: int, candidate: Candidate) -> bool:
    """Before pile ``candidate`` is picked ignoring its pile (a grasp reaches it, the pads
    only through a neighbour): push it out of its crowd (``spread.spread_pushes``, the
    planner keeping it clear of its neighbours), or when no such push plans, through them
    (``spread.stir_pushes``), at most max_isolations times a slot; True once the arm
    moved (the pile is to be looked at again). Not for a run domino: its neighbours are
    fallen dominoes, obstacles of the carry."""
    outcome = job.report.dominoes[index]
    if not candidate.from_pile or len(outcome.isolations) >= job.settings.max_isolations:
        return False
    for jammed in (False, True):
        isolated, _ = push_out_of_crowd(job, candidate, jammed)
        if isolated is not None:
            outcome.isolations.append(isolated)
            log(f"{job.domino(index)}: isolated before a pick ignoring its pile: {isolated}")
            return True
    return False


def push_out_of_crowd(
    job: Job, candidate: Candidate, jammed: bool, limit: int | None = None
) -> tuple[str | None, int]:
    """Push pile ``candidate`` out of its crowd (``jammed``: through it), its SPREAD_TRIES
    shortest pushes asked of the planner in turn, ``limit`` at most: what was done (None
    if every one was refused) and how many were asked."""
    choices, obstacles, how = pushes(job, candidate, jammed)
    what = f"pile domino at {candidate.spot().round(3).tolist()}"
    asked = 0
    for direction, distance in choices[:SPREAD_TRIES]:
        if asked == limit:
            break
        asked += 1
        pushed = sweep(job, candidate.pose, obstacles, direction, distance, what, how)
        if pushed is not None:
            return pushed, asked
    return None, asked


def lay_leaning_flat(job: Job, index: int, candidate: Candidate) -> bool:
    """Before leaning pile ``candidate`` is picked: push it over so that it lies flat
    (``lay_flat``: not where one was pushed already until something near it moves, at
    most max_lay_flat a slot); True once the arm moved (the pile is to be looked at
    again)."""
    if not to_lay_flat(job, candidate):
        return False
    laid = job.report.dominoes[index].laid_flat
    return len(laid) < job.settings.max_lay_flat and lay_flat(job, index, [candidate])


def to_lay_flat(job: Job, candidate: Candidate) -> bool:
    """A leaning pile domino, pushed over flat before it is picked (``lay_leaning_flat``)."""
    return job.settings.lay_leaning_flat and candidate.from_pile and candidate.leaning


def stays_leaning(job: Job, index: int, candidate: Candidate) -> bool:
    """Whether leaning pile ``candidate``, planned for slot ``index``, is told now that no
    push will lay it flat (``lay_leaning_flat`` would push nothing): the slot's pushes used
    up, pushed where it lies already, or every push's refusal foreseen (``foreseen_strike``).
    Only with foresee_refusals."""
    if not (job.settings.foresee_refusals and to_lay_flat(job, candidate)):
        return False
    state, spot = job.state, candidate.spot()
    if len(job.report.dominoes[index].laid_flat) >= job.settings.max_lay_flat:
        return True
    if near_any(spot, state.pushed):
        return True
    others = [*candidate.neighbours, *state.fallen.values()]
    centre = np.asarray(job.settings.pile_center)
    return all(
        foreseen_strike(job, sweep_request(job, candidate.pose, others, direction, distance))
        for direction, distance in lay_flat_pushes(candidate.pose, centre)
    )


def lay_flat(job: Job, index: int, stuck: Sequence[Candidate]) -> bool:
    """Push one of the pile dominoes no grasp takes as they lie (``stuck``: on their edge,
    or refused even ignoring their pile) so that it lies flat within reach
    (``spread.lay_flat_pushes``), the planner keeping it clear of its neighbours; True
    once the arm moved. One pushed where it lies already, or whose pushes were all
    refused, is not pushed again until something near it moves (``BuildState.pushed``);
    the planner's refusal is remembered as why it is out of reach."""
    state, centre = job.state, np.asarray(job.settings.pile_center)
    fallen = list(state.fallen.values())
    for candidate in stuck:
        spot = candidate.spot()
        if near_any(spot, state.pushed):
            continue
        what = f"pile domino {candidate.posture_name} at {spot.round(3).tolist()}"
        refusals: list[str] = []
        for direction, distance in lay_flat_pushes(candidate.pose, centre):
            how = "to push it over" if distance == TIP_DISTANCE else "towards the pile's centre"
            others = [*candidate.neighbours, *fallen]
            pushed = sweep(job, candidate.pose, others, direction, distance, what, how, refusals)
            if pushed is not None:
                job.report.dominoes[index].laid_flat.append(pushed)
                log(f"{job.domino(index)}: laying the pile flat: {pushed}")
                state.pushed.append(spot)
                return True
        state.pushed.append(spot)
        if refusals:
            state.remember_why(spot, f"no push lays it flat ({refusals[-1]})")
    return False


def pushes(
    job: Job, candidate: Candidate, jammed: bool
) -> tuple[list[tuple[np.ndarray, float]], list[Pose], str]:
    """The pushes of pile ``candidate`` to ask for (out of its crowd, or ``jammed``:
    through it), what the planner keeps it clear of, and how the log says it went."""
    settings, state = job.settings, job.state
    seen = [*candidate.neighbours, *state.standing.values()]
    centre = np.asarray(settings.pile_center)
    fallen = state.lying()
    if jammed:  # the neighbours are pushed along: only the run is an obstacle
        found = stir_pushes(candidate.pose, seen, candidate.points, centre, settings.spread_radius)
        return found, fallen, "through its neighbours"
    found = spread_pushes(
        candidate.pose,
        seen,
        candidate.points,
        centre,
        settings.spread_radius,
        settings.spread_clearance,
    )
    return found, [*candidate.neighbours, *fallen], ""


def sweep(
    job: Job,
    pose: Pose,
    others: Sequence[Pose],
    direction: np.ndarray,
    distance: float,
    what: str,
    where: str = "",
    refusals: list[str] | None = None,
) -> str | None:
    """Push the domino at ``pose`` ``distance`` along ``direction`` (/plan_strike's
    sweep), keeping clear of ``others`` and the standing run: what was done, or None if
    the planner refused (the arm has not moved; its reason goes to ``refusals``)."""
    request = sweep_request(job, pose, others, direction, distance)
    plan = foreseen_strike(job, request) or job.cell.plan_strike(request)
    if not plan.success:
        reason = plan.message.split(" (")[0]
        log(f"sweeping {what} refused: {reason}")
        if refusals is not None:
            refusals.append(reason)
        return None
    execution = execute(job, plan.segments, holds_domino=False)
    job.state.forget_refusals_near(spot_of(pose))
    job.state.forget_refusals_near(spot_of(pose) + distance * np.asarray(direction)[:2])
    swept = f"{what}: swept {distance * 1e3:.0f} mm {where}".rstrip()
    return swept + ("" if execution.done else f", stopped ({execution.why})")


def sweep_request(
    job: Job, pose: Pose, others: Sequence[Pose], direction: np.ndarray, distance: float
) -> StrikeRequest:
    """The sweep of the domino at ``pose`` ``distance`` along ``direction``, clear of
    ``others`` and the standing run."""
    return StrikeRequest(
        domino=pose,
        standing=(*job.state.standing.values(), *others),
        sweep=np.asarray(direction)[:2],
        push_distance=distance,
        time_budget=job.settings.plan_budget,
    )


def foreseen_strike(job: Job, request: StrikeRequest) -> Plan | None:
    """The planner's refusal of ``request`` when it is told without asking the planner
    (``strike_foresight.foreseen_strike_refusal``: the request's own checks, or the pusher
    inside a standing domino at every strike pose, before any IK), else None (settings
    foresee_refusals). Pushing a leaning pile domino over flat, the default job (seed 0)
    asked 8 such sweeps, each refused so (0.6-1.1 s of wall time at strike, under load)."""
    if not job.settings.foresee_refusals:
        return None
    refusal = foreseen_strike_refusal(
        planner_strike_request(request, np.zeros(0), None), PLANNER_SETTINGS
    )
    if refusal is None:
        return None
    why = f"foreseen: {refusal.code.name} at {refusal.stage}: {refusal.message}"
    return Plan(False, refusal.code, why, foreseen=True)

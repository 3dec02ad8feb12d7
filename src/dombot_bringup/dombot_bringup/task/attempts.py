"""One attempt at a slot: offer candidates until one plans, pick it, carry it, place it,
check the placement."""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from enum import Enum
from functools import partial

import numpy as np

from dombot_bringup.layouts import DOMINO_LENGTH
from dombot_bringup.offers import (
    PILE_BOXES,
    PILE_CORES,
    PILE_IGNORED,
    roomiest_first,
    with_pile_first,
)
from dombot_bringup.run_report import PileDomino
from dombot_bringup.task import ahead
from dombot_bringup.task.cell import CellError, Detections, Later, PlaceRequest, Pose, Posture
from dombot_bringup.task.checks import check
from dombot_bringup.task.clearing import (
    isolate,
    lay_flat,
    lay_leaning_flat,
    spread,
    stays_leaning,
    to_lay_flat,
)
from dombot_bringup.task.geometry import SAME_SPOT, near, near_any, spot_of
from dombot_bringup.task.picking import (
    PICKABLE_POSTURES,
    PILE_WORDS,
    Candidate,
    Offer,
    Refusal,
    candidates,
    first_plan,
    foreseen,
    in_its_way,
    is_among,
    place_request,
)
from dombot_bringup.task.placing import DESCENT, REGRASP_PREFIX, Hold, Ran, execute
from dombot_bringup.task.records import (
    Truth,
    at_slot,
    nearest_truth,
    pick_record,
    truth,
    write_pick_record,
)
from dombot_bringup.task.state import Job, log
from dombot_planner.errors import ErrorCode


class Outcome(Enum):
    """How an attempt ended."""

    PLACED = "placed"  # the slot's domino stands
    NOT_PLACED = "not placed"  # carried (or put back, or a call failed): the arm moved
    MISSED = "missed"  # the pick failed (blocked or missed): the run is as it was
    NO_PLAN = "no plan"  # nothing planned: the arm has not moved
    NO_PLACE = "no place"  # nothing planned, and no domino can be placed at the slot


@dataclass(frozen=True)
class Attempt:
    outcome: Outcome
    why: str  # the check's words when placed, else what failed
    spot: np.ndarray | None = None  # MISSED: where the domino lay that was not picked

    @property
    def moved(self) -> bool:
        return self.outcome not in (Outcome.NO_PLAN, Outcome.NO_PLACE)


def attempt(
    job: Job,
    index: int,
    failed: list[np.ndarray],
    ignore_pile: bool = False,
    turned: bool = False,
    refusals: list[Refusal] | None = None,
) -> Attempt:
    """Offer the planner candidates until one plans; execute and check it.

    First with their pile neighbours as obstacles (the planner keeps the pads clear of
    them, or lets them nudge one a few millimetres), in ``offers.with_pile_first``'s
    order; when every one is refused, the roomiest with their pile's cores (the pads may
    push a neighbour up to pile_core_shrink, the gripper body keeps clear); then, unless a
    refusal was about the slot and not ``ignore_pile`` (other slots may be built first;
    refusals about the dominoes would recur at every slot), a pile domino is pushed out of
    its crowd (``clearing.spread``) and the attempt starts again from a fresh look (up to
    max_spreads a slot); only then the roomiest ignoring the pile: the first that plans so
    is pushed out of its crowd first and the attempt starts again from a fresh look
    (``clearing.isolate``, up to max_isolations a slot), and after that picked (a miss is
    caught by the grasp check and backed out of, and stirs the pile). A refusal costs a
    planning call, not an attempt: the arm has not moved (NO_PLAN). When the slot cannot be put off
    (``ignore_pile``) and the refusals of its turn (``refusals``, kept over the turn's
    attempts, spreads and pushes until something plans) show no domino can be placed there
    (``no_place``), nothing more is pushed for it: NO_PLACE, and the slot is given up.
    Refusals and failed picks are remembered for the run (refused with the pile: not
    offered with it again; refused ignoring it, or the pick blocked or missed: not offered
    at all), until a pick within DISTURBED_RADIUS moves it.

    A leaning pile domino that planned with its pile is pushed over flat first
    (``clearing.lay_leaning_flat``) and the attempt starts again from a fresh look; when
    no push plans, a flat one offered after it is picked if it plans (``flat_instead``).

    A pile domino the planner turns in place first (no grasp reached it as it lay) is
    turned, then looked at again and the attempt goes on from there (once: ``turned``):
    picked blind where the plan expected it to settle, 3 of 7 such picks missed.
    """
    found, stuck = candidates(job, failed, index)
    if way := in_its_way(job, index):
        return clear_the_way(job, index, way, found, failed, ignore_pile, refusals)
    settings = job.settings
    roomiest = last_resort(job, found)
    refusals = [] if refusals is None else refusals
    earlier = len(refusals)  # this attempt's refusals follow
    with_pile = offers_with_pile(job, index, found)
    offer, refused = first_plan(job, index, with_pile, failed, refusals)
    if offer is not None and lay_leaning_flat(job, index, offer.candidate):
        return attempt(job, index, failed, ignore_pile, turned, refusals)
    if offer is not None:
        offer, more = flat_instead(job, index, offer, with_pile, failed, refusals)
        refused += more
    about_the_pile = ignore_pile or not any(r.about_the_slot for r in refusals[earlier:])
    if offer is None and ignore_pile and (why := no_place(job, index, refusals)):
        return Attempt(Outcome.NO_PLACE, why)
    if offer is None and about_the_pile:
        outcome = job.report.dominoes[index]
        if len(outcome.laid_flat) < settings.max_lay_flat and lay_flat(job, index, stuck):
            return attempt(job, index, failed, ignore_pile, turned, refusals)
        if len(outcome.spreads) < settings.max_spreads and spread(job, index, found):
            return attempt(job, index, failed, ignore_pile, turned, refusals)
        ignoring = [(c, PILE_IGNORED) for c in roomiest]
        offer, more = first_plan(job, index, ignoring, failed, refusals)
        refused += more
        if offer is not None and isolate(job, index, offer.candidate):
            return attempt(job, index, failed, ignore_pile, turned, refusals)
    if offer is None:
        if about_the_pile:
            name_out_of_reach(job, index, [c for c in found if c.from_pile] + stuck)
        why = f"planning: {refused} offers refused" if refused else "no graspable domino seen"
        return Attempt(Outcome.NO_PLAN, why)
    job.report.pile_out_of_reach.clear()
    refusals.clear()  # something plans for the slot: what was refused tells nothing of it
    return pick(job, index, offer, failed, ignore_pile, turned)


def clear_the_way(
    job: Job,
    index: int,
    way: Sequence[Pose],
    found: Sequence[Candidate],
    failed: list[np.ndarray],
    ignore_pile: bool,
    refusals: list[Refusal] | None,
) -> Attempt:
    """The attempt at slot ``index`` while dominoes lie in its way (``way``,
    ``picking.in_its_way``): one alone is offered as the slot's domino, nothing else (a
    pile domino placed beside a toppled one fell onto the run, arc cycle 3); when it is
    refused (then in ``failed``), or more lie there, nothing plans (NO_PLAN) and
    ``clearing.sweep_debris`` pushes them aside."""
    lying = [c for c in found if is_among(c.pose, way)]
    offer = None
    if len(way) == 1 and lying:
        offer, _ = first_plan(job, index, offers_with_pile(job, index, lying), failed, [])
        if offer is None and not near_any(lying[0].spot(), failed):
            failed.append(lying[0].spot())  # refused about the domino: no other goes there
    if offer is None:
        spots = ", ".join(str(spot_of(pose).round(3).tolist()) for pose in way)
        return Attempt(Outcome.NO_PLAN, f"{len(way)} lying in its way (at {spots})")
    if refusals is not None:
        refusals.clear()
    return pick(job, index, offer, failed, ignore_pile, turned=False)


def offers_with_pile(
    job: Job, index: int, found: Sequence[Candidate]
) -> list[tuple[Candidate, str]]:
    """The offers planned with their pile for slot ``index``, in order: the best ranked
    with their pile's boxes, then the roomiest with their pile's cores; none refused so
    already, until a pick or push nearby (the default job, seed 0, asked for one domino
    with its pile's cores at three slots, five times with no pick or push within 5 cm of
    it between, and five times it was refused); leaning ones no push will lay flat behind
    the flat ones after them (``leaning_behind_flat``)."""
    state = job.state
    ranked = [c for c in with_pile_first(found) if not near_any(c.spot(), state.crowded)]
    cored = [c for c in last_resort(job, found) if not near_any(c.spot(), state.cored)]
    offers = [
        *((c, PILE_BOXES) for c in ranked[: job.settings.max_candidates]),
        *((c, PILE_CORES) for c in cored),
    ]
    return leaning_behind_flat(job, index, offers)


def leaning_behind_flat(
    job: Job, index: int, offers: list[tuple[Candidate, str]]
) -> list[tuple[Candidate, str]]:
    """``offers`` with each leaning pile domino that no push will lay flat
    (``clearing.stays_leaning``) moved behind the flat offers after it. Planned where it
    stood, it would be picked only when none of those plans (``flat_instead``), so asking
    them first picks the same domino without planning it and its pushes (the default job,
    seed 0: at four slots a leaning domino planned, then its two pushes refused, 1.5-6 s
    of wall time before the flat one after it)."""
    ordered, staying = list(offers), {}
    for offer in offers:
        candidate = offer[0]
        at = next(k for k, other in enumerate(ordered) if other is offer)
        after = ordered[at + 1 :]
        flat = [o for o in after if not o[0].leaning]
        if not (candidate.leaning and flat):
            continue  # nothing to ask before it
        if id(candidate) not in staying:  # a candidate comes in both tiers: told once
            staying[id(candidate)] = stays_leaning(job, index, candidate)
        if not staying[id(candidate)]:
            continue
        ordered = [*ordered[:at], *flat, offer, *(o for o in after if o[0].leaning)]
    return ordered


def last_resort(job: Job, found: Sequence[Candidate]) -> list[Candidate]:
    """The roomiest candidates: offered with their pile's cores, then ignoring it."""
    return roomiest_first(found)[: job.settings.last_resort_candidates]


def first_request(job: Job, index: int) -> PlaceRequest | None:
    """The request a new turn at slot ``index`` makes first, from the look at the pile
    made while the arm placed (``job.pile_look``, kept for that turn): its first offer
    whose refusal is not foreseen (``picking.foreseen``); None without one."""
    early = job.pile_look
    if early is None:
        return None
    try:
        seen = early()
    except CellError:
        seen = Detections(False)
    job.pile_look = Later(lambda: seen)
    if not (seen.success and seen.dominoes):
        return None
    found, _ = candidates(job, [], index)
    job.pile_look = Later(lambda: seen)
    requests = (place_request(job, index, *offer) for offer in offers_with_pile(job, index, found))
    return next((r for r in requests if foreseen(job, r) is None), None)


def flat_instead(
    job: Job,
    index: int,
    offer: Offer,
    offers: Sequence[tuple[Candidate, str]],
    failed: list[np.ndarray],
    refusals: list[Refusal],
) -> tuple[Offer, int]:
    """``offer``, unless it is a leaning pile domino (no push laid it flat) and a flat one
    after it in ``offers`` plans: that one then, and how many were refused before it. A
    leaning domino kept its failed picks (an edge, or nothing between the fingers) when a
    flat one planned at the next attempt."""
    candidate = offer.candidate
    if not to_lay_flat(job, candidate):
        return offer, 0
    after = next(k for k, (c, pile) in enumerate(offers) if c is candidate and pile == offer.pile)
    flat = [(c, pile) for c, pile in offers[after + 1 :] if not c.leaning]
    other, refused = first_plan(job, index, flat, failed, refusals)
    return other or offer, refused


def no_place(job: Job, index: int, refusals: list[Refusal]) -> str:
    """Why no domino can be placed at slot ``index``, or "" while one may: the planner
    refused the place of at least ``give_up_unplaceable`` flat pile dominoes
    (PLACE_UNREACHABLE; a flat domino's holds are those of any flat one, so any other,
    after a spread or a push, gets the same refusal), no refusal was one a sweep or a
    deferral may cure (PLACE_IN_COLLISION, TIMEOUT, ...; GRASP_UNREACHABLE says nothing of
    the slot, nor does a leaning domino's hold, which laying it flat may change), and no
    fallen domino lies within a domino length of the slot (a sweep may make room)."""
    if any(
        r.code not in (ErrorCode.PLACE_UNREACHABLE, ErrorCode.GRASP_UNREACHABLE) for r in refusals
    ):
        return ""
    unplaceable = [  # each a different domino: one refused for the slot is not offered again
        r
        for r in refusals
        if r.code == ErrorCode.PLACE_UNREACHABLE
        and r.candidate.from_pile
        and r.candidate.posture == Posture.FLAT
    ]
    place = spot_of(job.releases[index])
    debris = [pose for pose in job.state.lying() if near(spot_of(pose), place, DOMINO_LENGTH)]
    needed = job.settings.give_up_unplaceable
    if needed == 0 or len(unplaceable) < needed or debris:
        return ""
    return (
        f"no domino can be placed there: the planner refused {len(unplaceable)} flat "
        f"dominoes' place ({unplaceable[-1].message})"
    )


def name_out_of_reach(job: Job, index: int, pile: list[Candidate]) -> None:
    """Say which pile dominoes no grasp or push reached for slot ``index``, where they lie,
    how and why (the simulator's name for each, for the report only), in the log and in
    the report (``pile_out_of_reach``)."""
    dominoes = truth(job)
    left = []
    for candidate in pile:
        spot = candidate.spot()
        why = job.state.why(spot) or default_why(job, candidate)
        name, _ = nearest_truth(dominoes, candidate.pose)
        left.append(PileDomino(*spot.round(4).tolist(), candidate.posture_name, why, name))
    job.report.pile_out_of_reach = left
    if not left:
        log(f"{job.domino(index)}: the pile is empty")
        return
    log(f"{job.domino(index)}: {len(left)} pile dominoes out of reach for now:")
    for domino in left:
        named = f" ({domino.truth})" if domino.truth else ""
        log(f"  {domino.posture} at [{domino.x:.3f}, {domino.y:.3f}]{named}: {domino.why}")


def default_why(job: Job, candidate: Candidate) -> str:
    """Why a pile domino with no refusal remembered was not picked or pushed."""
    if candidate.posture not in PICKABLE_POSTURES:
        return f"no grasp holds a domino {candidate.posture_name}; " + (
            "pushed where it lies already"
            if near_any(candidate.spot(), job.state.pushed)
            else "this slot's pushes are used up"
        )
    if near_any(candidate.spot(), job.state.crowded):
        return "refused with its pile (crowded); not among the roomiest offered without it"
    return "not offered: others were tried first"


def pick(
    job: Job, index: int, offer: Offer, failed: list[np.ndarray], ignore_pile: bool, turned: bool
) -> Attempt:
    """Execute ``offer``'s plan and check the placement."""
    candidate, plan, state = offer.candidate, offer.plan, job.state
    spot = candidate.spot()
    log(
        f"{job.domino(index)}: picking {candidate.source} ({candidate.posture_name}) at "
        f"{spot.round(3).tolist()}, {plan.message}{PILE_WORDS[offer.pile]}"
    )
    state.forget_refusals_near(spot)  # the pick disturbs its neighbours
    # the pile as it lay when looked at: a report-only wait would cost the robot time
    dominoes = truth(job, since=job.pile_seen_at)
    truth_name, seen_off = nearest_truth(dominoes, candidate.pose)
    job.report.dominoes[index].pick_seen_off_mm.append(seen_off)
    record = pick_record(job, index, candidate, offer.pile, plan, dominoes)
    turn = [s for s in plan.segments if s.label.startswith(REGRASP_PREFIX)]
    look_again = bool(turn) and candidate.run_index is None and not turned
    segments = turn if look_again else plan.segments
    held, asking = plan.held_above_place, partial(ask_ahead, job, index, candidate)
    hold = None if held is None else Hold(index, held, candidate.pose, asking)
    execution = execute(job, segments, hold)
    write_pick_record(job, record, execution.why or ("turned in place only" if look_again else ""))
    if execution.ran is not Ran.FAILED:
        carried_away(job, candidate)
        if candidate.toppled:
            state.toppled_picked += 1
    if execution.ran is Ran.PUT_BACK:  # an attempt (the arm moved), not a pick that failed
        if execution.stalled:  # picked again, it hung the same way (s-curve seed 3: 3 times)
            say_what_lay_there(job, index, dominoes, truth_name)
            job.report.dominoes[index].put_back.append(execution.why)
            state.unpickable.append(spot)
            state.remember_why(spot, execution.why)
        return Attempt(Outcome.NOT_PLACED, execution.why)
    if execution.ran is Ran.FAILED:  # blocked or missed: unless it moved, it would recur
        if seen_off is not None:  # the name finds it in sim_node's "during the" lines
            log(f"(truth, report only: {truth_name} lay {seen_off:.1f} mm from where seen)")
        # A run domino stays where it was: an obstacle for every later carry (a new
        # domino was once built into one that still stood there).
        state.unpickable.append(spot)
        state.remember_why(spot, f"its pick failed: {execution.why}")
        if candidate.run_index is not None:
            return keep_if_standing(job, index, candidate.run_index, execution.why, spot)
        return Attempt(Outcome.MISSED, execution.why, spot)
    if look_again:
        log(f"{job.domino(index)}: turned it in place; looking again")
        return attempt(job, index, failed, ignore_pile, turned=True)
    ahead.ask(job, index, first_request)  # unless asked as the descent started or at let-go
    if check(job, index):
        return Attempt(Outcome.PLACED, job.report.dominoes[index].check)
    say_what_lay_there(job, index, dominoes, truth_name)
    return Attempt(Outcome.NOT_PLACED, job.report.dominoes[index].check)


def say_what_lay_there(job: Job, index: int, dominoes: Truth, held: str) -> None:
    """After a placement at slot ``index`` fell or its descent stalled: the simulator's
    dominoes but the ``held`` one that lay against the slot's footprint before the pick
    (``records.at_slot``; report only: "(truth, ...)" lines are for people)."""
    if dominoes:
        there = at_slot(dominoes, job.targets[index], held)
        log(f"(truth, report only: before the pick, at slot {index + 1}: {there})")


def ask_ahead(
    job: Job, index: int, candidate: Candidate, when: str, start: Mapping[str, float]
) -> None:
    """As ``candidate`` starts down to slot ``index``, or while it is placed there
    (``when``): the next slot's first pick asked for ahead, from ``start``, the arm's
    joints where the plan ends. Polled while the arm places: cheap but at the descent."""
    if when == DESCENT:
        carried_away(job, candidate)  # no longer where it lay, for that request
    ahead.ask_early(job, index, first_request, when, start)


def carried_away(job: Job, candidate: Candidate) -> None:
    """``candidate`` no longer lies where it was seen: no run domino fallen there, no
    domino toppled there, nor any remembered within SAME_SPOT of it (the same domino
    measured twice: left behind, it blocked its slot for good)."""
    state, spot = job.state, candidate.spot()
    if candidate.run_index is not None:
        state.fallen.pop(candidate.run_index, None)

    def there(pose: Pose) -> bool:
        return pose is candidate.pose or near(spot_of(pose), spot, SAME_SPOT)

    state.fallen = {k: pose for k, pose in state.fallen.items() if not there(pose)}
    state.toppled = [pose for pose in state.toppled if not there(pose)]
    state.unfitted = [pose for pose in state.unfitted if not there(pose)]


def keep_if_standing(job: Job, index: int, run_index: int, why: str, spot: np.ndarray) -> Attempt:
    """After a failed pick of run domino ``run_index``: if it still stands upright within
    keep_when_stuck of its target, it stays as that slot's domino (when that is the slot
    being built, the attempt succeeded); otherwise the pick failed with ``why``."""
    job.state.stuck.add(run_index)
    if not check(job, run_index):
        return Attempt(Outcome.MISSED, why, spot)
    job.state.fallen.pop(run_index, None)
    outcome = job.report.dominoes[run_index]
    outcome.placed = True
    if run_index == index:
        return Attempt(Outcome.PLACED, outcome.check)
    log(f"domino {run_index + 1} kept standing where it is ({outcome.check})")
    return Attempt(Outcome.MISSED, why, spot)

"""Planning ahead: the next slot's first pick is asked for before the placement just made
is checked, and its answer is used when the next attempt makes that very request with
the arm where the plan starts.

The request goes out as the descent to the slot starts or, failing that, the moment the
look at the pile answers while the arm descends, lets go of the domino and retreats
(``ask_early``, polled on the job's own thread while each of those motions runs, as
the cell waits for its end: ``placing.execute``, ``Cell.execute``'s meanwhile), starting
where the retreat ends (PlanPlace's start_state): the planner works on it while the arm
places and retreats and perception checks the placement. That needs the look asked for
as the carry ended above the slot (before the hand check, ``placing.look_while_placing``)
to have answered; it is never waited for (the arm would stand still meanwhile): when it
answers only after the retreat, the request goes out then (``ask``), from where the arm
stands (the planner reads /joint_states).

Why an answer asked for so early is right when it is used:
* the request is the one the next slot's turn makes first if the placement stands: the
  pile has been still since the lift and was looked at with the arm above the slot, and
  a domino that stands where it should is kept at its target pose for the planner
  (``checks.check``). When the check says otherwise (the domino fell, stands off target,
  another slot comes next) the turn's request differs and the answer is dropped; a
  domino put back on the pile drops it at once (``placing.put_back``);
* the plan starts where the arm stands: any motion after the request but the descent,
  release and retreat it was asked during drops the answer (``drop``, as
  ``placing.execute`` starts, or in a put back), and when the turn starts the arm must
  stand within START_TOLERANCE of the plan's start (a retreat that stopped short left it
  elsewhere: dropped).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace

import numpy as np

from dombot_bringup.task.cell import CellError, Later, PlaceRequest, Plan
from dombot_bringup.task.state import Job, log

# rad per joint the arm may stand from a plan's start. A retreat ends within the
# controller's goal tolerance of its last point or fails (0.01 rad in sim_node); the
# simulator takes a trajectory whose first point lies within 0.05 rad of the arm. Measured
# on the default job: retreats ended 0.16-0.22 mrad off their last point (sim_node's
# "when it ended"), and the arm stood within 0.12 mrad of it when the next turn began.
START_TOLERANCE = 0.01

RequestFor = Callable[[Job, int], PlaceRequest | None]
AFTER_RETREAT = "after_retreat"  # ``ask``'s count in the report's planned_ahead


@dataclass(frozen=True, eq=False)
class PlanAhead:
    """A request sent before the attempt that makes it, and its answer to come."""

    request: PlaceRequest
    start: Mapping[str, float]  # the joints the plan starts from (name → rad)
    answer: Later[Plan]


def ask_early(
    job: Job, index: int, request_for: RequestFor, when: str, start: Mapping[str, float]
) -> None:
    """As slot ``index``'s domino starts down to it, or while it is placed there and the
    arm retreats (``when``, counted by that name): the next slot's first request
    (``request_for``), planned from ``start`` (where the retreat ends), unless it went out
    already, if the look at the pile made while placing has answered. Cheap until then:
    it is polled while the arm moves."""
    look = job.pile_look
    if job.ahead is None and look is not None and look.answered():
        send(job, index, request_for, start, when)


def ask(job: Job, index: int, request_for: RequestFor) -> None:
    """After the retreat, unless it went out while the arm placed: the next slot's first
    request, planned from where the arm stands."""
    if job.ahead is None:
        send(job, index, request_for, None, AFTER_RETREAT)


def send(
    job: Job,
    index: int,
    request_for: RequestFor,
    start: Mapping[str, float] | None,
    when: str,
) -> None:
    """Send the next slot's first request (``request_for``, with slot ``index`` taken as
    standing at its target), planned from ``start`` (None: where the arm stands); counted
    as ``when`` in the report's planned_ahead."""
    upcoming = job.upcoming
    if not job.settings.plan_ahead or upcoming is None or upcoming == index:
        return
    state = job.state
    kept = state.standing.get(index)
    state.standing[index] = job.targets[index]
    try:
        request = request_for(job, upcoming)
    finally:
        if kept is None:
            state.standing.pop(index)
        else:
            state.standing[index] = kept
    if request is None:
        return
    request = replace(request, start=start)
    try:
        answer = job.cell.plan_place_later(request)
    except CellError as error:
        log(f"planning ahead: {error}")
        return
    job.report.planned_ahead[when] += 1
    job.ahead = PlanAhead(request, joints_now(job) if start is None else start, answer)


def answer(job: Job, request: PlaceRequest) -> Plan | None:
    """The answer asked for ahead, if it was for ``request`` and the arm stands at its
    start; None otherwise (the answer is dropped)."""
    ahead = job.ahead
    if ahead is None:
        return None
    if not same_request(ahead.request, request):
        drop(job, "the turn asks for another pick")
        return None
    off = off_start(job, ahead.start)
    if off > START_TOLERANCE:
        drop(job, f"the arm stands {off:.3f} rad from where it starts")
        return None
    job.ahead = None
    try:
        plan = ahead.answer()
    except CellError as error:
        log(f"planning ahead: {error}")
        return None
    job.report.planned_ahead["used"] += 1
    log(f"planned ahead, used: the arm {off * 1e6:.1f} µrad from where it starts")
    return plan


def drop(job: Job, why: str) -> None:
    """Forget the answer asked for ahead, if any (the planner works on it first anyway)."""
    if job.ahead is None:
        return
    job.ahead = None
    job.report.planned_ahead["dropped"] += 1
    log(f"planned ahead, not used: {why}")


def joints_now(job: Job) -> dict[str, float]:
    names, positions = job.cell.joints()
    return dict(zip(names, positions, strict=True))


def off_start(job: Job, start: Mapping[str, float]) -> float:
    """How far [rad, the largest joint's] the arm stands from ``start``; inf when it lacks
    one of its joints."""
    now = joints_now(job)
    return max(
        (abs(now[name] - q) if name in now else math.inf for name, q in start.items()),
        default=0.0,
    )


def same_request(a: PlaceRequest, b: PlaceRequest) -> bool:
    """Whether two requests ask the planner the same pick (field by field, poses exactly;
    where the plan starts is for ``answer`` to judge)."""
    return (
        same(a.domino, b.domino)
        and same(a.place, b.place)
        and same_poses(a.standing, b.standing)
        and same(a.grasp, b.grasp)
        and same_poses(a.pile, b.pile)
        and same(a.pile_points, b.pile_points)
        and (a.pads_into_pile, a.holding, a.time_budget)
        == (b.pads_into_pile, b.holding, b.time_budget)
    )


def same(a: np.ndarray | None, b: np.ndarray | None) -> bool:
    if a is None or b is None:
        return a is b
    return a.shape == b.shape and bool(np.array_equal(a, b))


def same_poses(a: tuple[np.ndarray, ...], b: tuple[np.ndarray, ...]) -> bool:
    return len(a) == len(b) and all(same(p, q) for p, q in zip(a, b, strict=True))

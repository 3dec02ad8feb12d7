"""Planning ahead: the next slot's first pick is asked for before the placement just made
is checked, and its answer is used when the next attempt makes that very request (within
perception's repeatability: ``serves``) with the arm where the plan starts.

The request goes out as the carry to the slot starts, made from the look the carried
domino was picked from less that domino (``ask_at_carry``, settings
plan_ahead_at_carry): the planner then works on it while the arm carries, the hand is
checked and the domino placed. The pick moved that domino and may have moved its
neighbours or bared one below it, so once the look asked for as the carry ended answers,
the request made from it must be one the answer serves (``confirm``); otherwise the
answer is dropped and that request goes out instead. Without a request from the carry, it
goes out as the descent to the slot starts or, failing that, the moment the
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
from scipy.spatial import cKDTree

from dombot_bringup.task.cell import CellError, Detections, Later, PlaceRequest, Plan, Pose
from dombot_bringup.task.checks import to_look_again
from dombot_bringup.task.geometry import SAME_SPOT, near, spot_of
from dombot_bringup.task.state import Job, log

# rad per joint the arm may stand from a plan's start. A retreat ends within the
# controller's goal tolerance of its last point or fails (0.01 rad in sim_node); the
# simulator takes a trajectory whose first point lies within 0.05 rad of the arm. Measured
# on the default job: retreats ended 0.16-0.22 mrad off their last point (sim_node's
# "when it ended"), and the arm stood within 0.12 mrad of it when the next turn began.
START_TOLERANCE = 0.01

# How far [m, rad] two readings of one still domino (or seen point) may lie apart and be
# taken for the same: a request made from a newer look within it asks the planner the same
# pick. Perception's fits of a domino lying still are seeded (deterministic on the same
# frames); 1 mm is within its error against the truth (~1.2 mm, picks that held), which
# the grasp's width tolerance and the hand check already take.
SAME_READING = (0.001, math.radians(1.0))

RequestFor = Callable[[Job, int], PlaceRequest | None]
CARRY = "carry"  # ``ask_at_carry``'s count in the report's planned_ahead
AFTER_RETREAT = "after_retreat"  # ``ask``'s count in the report's planned_ahead


@dataclass(frozen=True, eq=False)
class PlanAhead:
    """A request sent before the attempt that makes it, and its answer to come."""

    request: PlaceRequest
    start: Mapping[str, float]  # the joints the plan starts from (name → rad)
    answer: Later[Plan]
    # made from the look before the pick (``ask_at_carry``): not yet compared with the
    # request the look made since makes (``confirm``)
    unconfirmed: bool = False


def ask_at_carry(
    job: Job, index: int, picked: Pose, request_for: RequestFor, start: Mapping[str, float]
) -> None:
    """As slot ``index``'s domino (``picked``, where it lay) starts its carry: the next
    slot's first request (``request_for``), planned from ``start`` (where the retreat
    ends), made from the look it was picked from (``job.last_look``) less it (within
    SAME_SPOT), to be confirmed by the look asked as the carry ends (``confirm``). Not
    while lying dominoes near where something moved wait to be looked at again
    (``checks.look_again``): the arm above the pile would hide them."""
    last = job.last_look
    if not job.settings.plan_ahead_at_carry or last is None or job.ahead is not None:
        return
    if any(to_look_again(job)):
        return
    here = spot_of(picked)
    left = tuple(d for d in last.dominoes if not near(spot_of(d.pose), here, SAME_SPOT))
    before = Detections(True, last.message, left, last.unexplained)
    kept, job.pile_look = job.pile_look, Later(lambda: before)
    try:
        send(job, index, request_for, start, CARRY)
    finally:
        job.pile_look = kept
    if job.ahead is not None:
        job.ahead = replace(job.ahead, unconfirmed=True)


def confirm(
    job: Job,
    index: int,
    request_for: RequestFor,
    start: Mapping[str, float] | None,
    when: str,
) -> None:
    """The request asked at the carry against the one the look asked above the slot
    (``request_for``) makes: kept when its answer serves it, else dropped and that one sent
    (from ``start``, counted as ``when``). Without that look (a slot too near the pile) the
    turn's own look decides (``answer``)."""
    ahead = job.ahead
    if ahead is None or not ahead.unconfirmed or job.pile_look is None:
        return
    request = next_request(job, index, request_for)
    why = "no request" if request is None else difference(ahead.request, request)
    if not why:
        job.ahead = replace(ahead, unconfirmed=False)
        log("planned ahead at the carry: the pile looked at since asks the same")
        return
    drop(job, f"the pile looked at since asks another pick ({why})")
    if request is not None:
        send_request(job, replace(request, start=start), start, when)


def ask_early(
    job: Job, index: int, request_for: RequestFor, when: str, start: Mapping[str, float]
) -> None:
    """As slot ``index``'s domino starts down to it, or while it is placed there and the
    arm retreats (``when``, counted by that name): the next slot's first request
    (``request_for``), planned from ``start`` (where the retreat ends), unless it went out
    already, if the look at the pile made while placing has answered. Cheap until then:
    it is polled while the arm moves."""
    look = job.pile_look
    if look is None or not look.answered():
        return
    if job.ahead is None:
        send(job, index, request_for, start, when)
    else:
        confirm(job, index, request_for, start, when)


def ask(job: Job, index: int, request_for: RequestFor) -> None:
    """After the retreat, unless it went out while the arm placed: the next slot's first
    request, planned from where the arm stands; one asked at the carry and not confirmed
    yet is now (``confirm``)."""
    if job.ahead is None:
        send(job, index, request_for, None, AFTER_RETREAT)
    else:
        confirm(job, index, request_for, None, AFTER_RETREAT)


def send(
    job: Job,
    index: int,
    request_for: RequestFor,
    start: Mapping[str, float] | None,
    when: str,
) -> None:
    """Send the next slot's first request (``next_request``), planned from ``start``
    (None: where the arm stands); counted as ``when`` in the report's planned_ahead."""
    request = next_request(job, index, request_for)
    if request is not None:
        send_request(job, replace(request, start=start), start, when)


def next_request(job: Job, index: int, request_for: RequestFor) -> PlaceRequest | None:
    """The next slot's first request (``request_for``, with slot ``index`` taken as
    standing at its target); None when nothing is to be asked ahead."""
    upcoming = job.upcoming
    if not job.settings.plan_ahead or upcoming is None or upcoming == index:
        return None
    state = job.state
    kept = state.standing.get(index)
    state.standing[index] = job.targets[index]
    try:
        return request_for(job, upcoming)
    finally:
        if kept is None:
            state.standing.pop(index)
        else:
            state.standing[index] = kept


def send_request(
    job: Job, request: PlaceRequest, start: Mapping[str, float] | None, when: str
) -> None:
    try:
        answer = job.cell.plan_place_later(request)
    except CellError as error:
        log(f"planning ahead: {error}")
        return
    job.report.planned_ahead[when] += 1
    job.ahead = PlanAhead(request, joints_now(job) if start is None else start, answer)


def answer(job: Job, request: PlaceRequest) -> Plan | None:
    """The answer asked for ahead, if it serves ``request`` (``serves``; a refusal only
    when the two ask the same both ways: one obstacle fewer may plan) and the arm stands at
    its start; None otherwise (the answer is dropped)."""
    ahead = job.ahead
    if ahead is None:
        return None
    if why := difference(ahead.request, request):
        drop(job, f"the turn asks for another pick ({why})")
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
    if not plan.success and not serves(request, ahead.request):
        job.report.planned_ahead["dropped"] += 1
        log("planned ahead, not used: refused with an obstacle the turn does not see")
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


def serves(asked: PlaceRequest, wanted: PlaceRequest) -> bool:
    """Whether the planner's answer to ``asked`` is one to ``wanted`` (where the plan
    starts is for ``answer`` to judge): the same domino and place, the same standing
    dominoes, each within SAME_READING; and every obstacle of ``wanted`` (its pile
    dominoes, its seen points) one of ``asked``'s: a plan clear of those is clear of
    these. ``asked`` may keep more (a neighbour the pick moved away, seen where it lay).
    Perception's grasp, the planner's first try, may differ: chosen clear of every point
    seen then, it is clear of those seen since (a neighbour gone gives room for others)."""
    return not difference(asked, wanted)


def difference(asked: PlaceRequest, wanted: PlaceRequest) -> str:
    """What keeps the answer to ``asked`` from serving ``wanted`` (``serves``), or ""."""
    for name in ("domino", "place"):
        if not same_pose(getattr(asked, name), getattr(wanted, name)):
            return f"its {name} {apart(getattr(asked, name), getattr(wanted, name))}"
    if len(asked.standing) != len(wanted.standing) or not all(
        same_pose(a, w) for a, w in zip(asked.standing, wanted.standing, strict=True)
    ):
        return "the standing dominoes differ"
    new = [w for w in wanted.pile if not any(same_pose(a, w) for a in asked.pile)]
    if new:
        nearest = min(
            (float(np.linalg.norm(w[:3, 3] - a[:3, 3])) for w in new for a in asked.pile),
            default=math.inf,
        )
        return (
            f"{len(new)} of {len(wanted.pile)} pile dominoes not among those asked with, "
            f"the nearest {nearest * 1e3:.1f} mm from one"
        )
    if not among(wanted.pile_points, asked.pile_points):
        return "seen points not among those asked with"
    if (asked.pads_into_pile, asked.holding, asked.time_budget) != (
        wanted.pads_into_pile,
        wanted.holding,
        wanted.time_budget,
    ):
        return "another tier"
    return ""


def apart(a: Pose | None, b: Pose | None) -> str:
    """How far two poses lie apart, for the log."""
    if a is None or b is None:
        return "given once only"
    cos = (np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0
    turned = math.degrees(math.acos(float(np.clip(cos, -1.0, 1.0))))
    return f"{np.linalg.norm(a[:3, 3] - b[:3, 3]) * 1e3:.1f} mm, {turned:.1f}° apart"


def same_pose(a: Pose | None, b: Pose | None) -> bool:
    """Two readings of one pose, within SAME_READING (both None: the same)."""
    if a is None or b is None:
        return a is b
    apart, turned = SAME_READING
    cos = (np.trace(a[:3, :3].T @ b[:3, :3]) - 1.0) / 2.0
    return bool(
        np.linalg.norm(a[:3, 3] - b[:3, 3]) <= apart
        and math.acos(float(np.clip(cos, -1.0, 1.0))) <= turned
    )


def among(points: np.ndarray, others: np.ndarray) -> bool:
    """Whether each of ``points`` (N x 3) lies within SAME_READING of one of ``others``."""
    points, others = np.reshape(points, (-1, 3)), np.reshape(others, (-1, 3))
    if not len(points):
        return True
    if not len(others):
        return False
    distances, _ = cKDTree(others).query(points, distance_upper_bound=SAME_READING[0])
    return bool(np.isfinite(distances).all())

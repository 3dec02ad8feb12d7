"""Planning ahead: the next slot's first pick is asked for while perception checks the
placement just made, and its answer is used when the next attempt makes that very
request from where the arm stands.

The arm stands still from the retreat to the next pick, the pile has been looked at
while the arm placed, and a domino that stands where it should is kept at its target
pose for the planner (``checks.check``): the next slot's first request is then known
before the check has answered, and the planner works on it on the other core meanwhile.
When the check says otherwise (the domino fell, stands off target, the next slot is
another) the request differs and the answer is not used.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np

from dombot_bringup.task.cell import CellError, PlaceRequest, Plan
from dombot_bringup.task.state import Job, log

# rad: the arm must stand where it stood when the plan was asked for (the planner took
# its start from /joint_states then); a plan's start is as far from the arm after any
# motion (the controller's tracking error)
SAME_START = 1e-3


@dataclass(frozen=True, eq=False)
class PlanAhead:
    """A request sent before the attempt that makes it, and its answer to come."""

    request: PlaceRequest
    joints: np.ndarray  # the arm and fingers when it was sent
    answer: Callable[[], Plan]


def ask(job: Job, index: int, request_for: Callable[[Job, int], PlaceRequest | None]) -> None:
    """Send the next slot's first request (``request_for``, with slot ``index`` taken as
    standing at its target) before the placement at ``index`` is checked."""
    job.ahead = None
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
    try:
        answer = job.cell.plan_place_later(request)
    except CellError as error:
        log(f"planning ahead: {error}")
        return
    job.ahead = PlanAhead(request, np.asarray(job.cell.joints()[1]), answer)


def answer(job: Job, request: PlaceRequest) -> Plan | None:
    """The answer asked for ahead, if it was for ``request`` from where the arm stands;
    None otherwise (the answer, which the planner works on first anyway, is dropped)."""
    ahead, job.ahead = job.ahead, None
    if ahead is None:
        return None
    try:
        plan = ahead.answer()
    except CellError as error:
        log(f"planning ahead: {error}")
        return None
    joints = np.asarray(job.cell.joints()[1])
    moved = joints.shape != ahead.joints.shape or (
        np.abs(joints - ahead.joints).max(initial=0.0) > SAME_START
    )
    used = not moved and same_request(ahead.request, request)
    job.report.planned_ahead["used" if used else "dropped"] += 1
    if not used:
        why = "the arm moved since" if moved else "the turn asks for another pick"
        log(f"planned ahead, not used: {why}")
    return plan if used else None


def same_request(a: PlaceRequest, b: PlaceRequest) -> bool:
    """Whether two requests ask the planner the same (field by field, poses exactly)."""
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

"""Perception's word on the build: which run dominoes stand, which fell and where."""

from __future__ import annotations

import math

import numpy as np

from dombot_bringup.task.cell import Pose, Seen
from dombot_bringup.task.geometry import SAME_SPOT, near, spot_of
from dombot_bringup.task.state import DISTURBED_RADIUS, Job, log


def settle(job: Job, seconds: float = 0.0) -> float:
    """The simulated time from which on camera frames show the scene as it is ``seconds``
    from now (waited for here), for perception's ``not_before``: perception waits for the
    first frame stamped then or later (on a loaded CPU the images arrive after the joint
    states: a frame from before a placement once had perception call the domino standing
    there MISSING, and the next carry swept through it). Waiting here a camera period more
    cost ~0.3 s simulated a look."""
    fresh = job.cell.sim_time + seconds
    if seconds > 0.0:
        job.cell.wait_for_sim_time(seconds)
    return fresh


def settle_left(job: Job) -> float:
    """Simulated seconds still to wait before a placement is looked at: settle_after_place
    from when the fingers let go (the retreat takes its share), else from now."""
    settle = job.settings.settle_after_place
    if job.let_go_at is None:
        return settle
    return max(0.0, settle - (job.cell.sim_time - job.let_go_at))


def check(job: Job, index: int, just_placed: bool = True) -> bool:
    """Perception looks at every domino placed so far and at slot ``index``; fallen ones
    are queued again. True: slot ``index`` stands.

    One hidden from the camera (NOT_SEEN: most of it behind something, e.g. the arm above
    the domino just placed) is taken as standing until the next check: rebuilt on
    perception's word alone, a domino that still stood there was hit by the next (a whole
    run fell so). One upright but off target by up to keep_off_target is left standing
    where perception measured it, not picked up from within the run; so is one that stays
    within the tolerance of where it was left, and one whose pick-up again failed, up to
    keep_when_stuck. A hidden ``index`` not ``just_placed`` (e.g. the slot a fallen
    domino was swept out of) is not taken as standing."""
    settings, state = job.settings, job.state
    fresh = settle(job, settle_left(job))
    job.still_since = fresh
    indices = sorted(set(state.standing) | {index})
    answer = job.cell.check_placement([job.targets[i] for i in indices], not_before=fresh)
    if not answer.success:
        job.report.dominoes[index].check = f"placement check failed: {answer.message}"
        return False
    placed = False
    tolerance, tilt_tolerance = settings.place_tolerance, settings.place_tilt_tolerance
    for position, i in enumerate(indices):
        status = answer.status[position]
        error, tilt = answer.position_error[position], answer.tilt[position]
        hidden = status == Seen.NOT_SEEN and (just_placed or i != index)
        measured, last = answer.measured[position], state.standing.get(i)
        # within the tolerance of where it was last taken to stand: not moved (one left
        # 6.0 mm off read 6.6 mm at the next check and was to be picked again)
        stayed = last is not None and near(spot_of(measured), spot_of(last), tolerance)
        erect = status == Seen.STANDING and tilt <= tilt_tolerance
        keep = settings.keep_when_stuck if i in state.stuck else settings.keep_off_target
        off_target = erect and error > tolerance and (error <= keep or stayed)
        upright = hidden or off_target or (erect and error <= tolerance)
        if i == index:
            outcome = job.report.dominoes[index]
            outcome.check = check_words(status, error, tilt)
            outcome.measured_error_mm, outcome.measured_tilt_deg = (
                (None, None) if hidden else (error * 1e3, math.degrees(tilt))
            )
            outcome.off_target = off_target
            placed = upright
        if upright:
            moved = off_target and last is job.targets[i]
            if i != index and (hidden or moved):
                words = check_words(status, error, tilt)
                log(f"domino {i + 1} moved ({words}); left standing" if moved else words)
            where = (last if stayed else measured) if off_target else job.targets[i]
            state.standing[i] = where  # for the planner to keep clear of
        else:
            state.standing.pop(i, None)
            state.disturbed.append(spot_of(job.targets[i]))  # it fell there, or went
            if remember_fallen(job, i, status, measured, tilt):
                log(f"domino {i + 1} fell where perception cannot fit it; left where it lies")
            if i != index:
                job.report.dominoes[i].placed = False  # until it is built again
                log(f"domino {i + 1} is no longer standing ({check_words(status, error, tilt)})")
    return placed


def remember_fallen(job: Job, index: int, status: Seen, measured: Pose, tilt: float) -> bool:
    """A run domino out of place is picked up again from where perception fitted it; one
    that fell where no box fits (perception answers the standing target, tilt 0) is left
    where it lies, and a domino from the pile takes its place. True: left where it lies."""
    if status == Seen.STANDING or (
        status == Seen.FALLEN and tilt > job.settings.place_tilt_tolerance
    ):
        job.state.fallen[index] = measured
        return False
    if status == Seen.FALLEN:
        job.state.fallen.pop(index, None)
        return True
    return False


def look_again(job: Job) -> None:
    """The toppled and unfitted dominoes within DISTURBED_RADIUS of where something moved
    since they were seen (``BuildState.disturbed``) looked at again where they were seen
    (perception refits a lying expected pose; the standing run asked too, to keep its
    points): one found there lies where perception measured it now, one seen down but not
    fitted is unfitted (an obstacle, not picked), one gone (MISSING) is forgotten. A
    toppled pose gone stale (up to 44 mm off after the build's falls, arc cycle 3) made
    picks close on nothing."""
    state = job.state
    disturbed, state.disturbed = state.disturbed, []
    again = [
        pose
        for pose in [*state.toppled, *state.unfitted]
        if any(near(spot_of(pose), spot, DISTURBED_RADIUS) for spot in disturbed)
    ]
    if not again:
        return
    standing = list(state.standing.values())
    fresh = settle(job) if job.still_since is None else job.still_since
    answer = job.cell.check_placement([*standing, *again], not_before=fresh)
    if not answer.success:
        log(f"looking again at {len(again)} toppled dominoes failed: {answer.message}")
        return
    first = len(standing)
    seen = zip(answer.status[first:], answer.measured[first:], answer.tilt[first:], strict=True)
    toppled, unfitted = list(state.toppled), list(state.unfitted)
    for pose, (status, measured, tilt) in zip(again, seen, strict=True):
        if status in (Seen.STANDING, Seen.NOT_SEEN):
            continue  # no word on it: as it was
        toppled = [p for p in toppled if p is not pose]
        unfitted = [p for p in unfitted if p is not pose]
        where = f"toppled domino at {spot_of(pose).round(3).tolist()}"
        if status == Seen.MISSING:
            log(f"{where}: no longer there; forgotten")
        elif tilt <= job.settings.place_tilt_tolerance:  # down, no box fits it (tilt 0)
            log(f"{where}: something lies there that perception cannot fit; not picked")
            unfitted.append(pose)
        else:
            moved = float(np.linalg.norm(spot_of(measured) - spot_of(pose)))
            if moved >= SAME_SPOT:
                log(f"{where} moved {moved * 1e3:.0f} mm since it was seen")
            toppled.append(measured)
    state.toppled, state.unfitted = toppled, unfitted


def check_words(status: Seen, error: float, tilt: float) -> str:
    if status == Seen.NOT_SEEN:
        return "not seen (hidden from the camera): taken as standing until the next check"
    name = {Seen.STANDING: "standing", Seen.FALLEN: "fallen", Seen.MISSING: "missing"}[status]
    return f"{name}, {error * 1e3:.1f} mm and {math.degrees(tilt):.1f}° from the target"

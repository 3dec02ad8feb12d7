"""Perception's word on the build: which run dominoes stand, which fell and where."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

from dombot_bringup.footprints import footprints_meet
from dombot_bringup.task.cell import PlacementCheck, Pose, Seen
from dombot_bringup.task.chain import at_risk, chain_breaks
from dombot_bringup.task.geometry import SAME_SPOT, near, spot_of
from dombot_bringup.task.state import DISTURBED_RADIUS, Job, log
from dombot_description import domino_corners, tilt_from_vertical

# m: a pick or push moves dominoes whose centres lie within DISTURBED_RADIUS of it up to a
# length on (arc cycles seed 3: 30 mm), their far ends a half-length beyond: the unbuilt
# slots this close to it are looked at (``look_again``)
SLOT_LOOK_RADIUS = 0.10


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


@dataclass(frozen=True)
class Reading:
    """Perception's word on one expected domino."""

    status: Seen
    measured: Pose
    error: float  # m from the target, horizontally
    tilt: float  # rad from vertical

    @classmethod
    def of(cls, answer: PlacementCheck, position: int) -> Reading:
        return cls(
            answer.status[position],
            answer.measured[position],
            answer.position_error[position],
            answer.tilt[position],
        )

    @property
    def words(self) -> str:
        return check_words(self.status, self.error, self.tilt)


def check(job: Job, index: int, just_placed: bool = True) -> bool:
    """Perception looks at every domino placed so far and at slot ``index``; fallen ones
    are queued again. True: slot ``index`` stands.

    One hidden from the camera (NOT_SEEN: most of it behind something, e.g. the arm above
    the domino just placed) is taken as standing until the next check: rebuilt on
    perception's word alone, a domino that still stood there was hit by the next (a whole
    run fell so). One upright but off target by up to keep_off_target is left standing
    where perception measured it, not picked up from within the run; so is one that stays
    within the tolerance of where it was left, and one whose pick-up again failed, up to
    keep_when_stuck. A run domino other than ``index`` seen standing beyond those bounds
    is looked at again before anything is done about it (``second_look``); so is
    ``index`` when more than replace_risk standing dominoes have no empty slot between it
    and them (``chain.at_risk``): s_curve30 seed 6, its safety gaps dropped, had its 22nd
    picked up again from the end of the 21 standing for 5.2° of lean, knocked it over and
    felled them all. A hidden ``index`` not ``just_placed`` (e.g. the slot a fallen domino
    was swept out of) is not taken as standing."""
    state = job.state
    fresh = settle(job, settle_left(job))
    job.still_since = fresh
    indices = sorted(set(state.standing) | {index})
    answer = job.cell.check_placement([job.targets[i] for i in indices], not_before=fresh)
    if not answer.success:
        job.report.dominoes[index].check = f"placement check failed: {answer.message}"
        return False
    again = []  # run dominoes seen standing off target: looked at again
    for position, i in enumerate(indices):
        reading = Reading.of(answer, position)
        hidden = reading.status == Seen.NOT_SEEN and (just_placed or i != index)
        off_target = is_off_target(job, i, reading)
        upright = hidden or off_target or on_target(job, reading)
        if i == index:
            outcome = job.report.dominoes[index]
            outcome.check = reading.words
            outcome.measured_error_mm, outcome.measured_tilt_deg = (
                (None, None) if hidden else (reading.error * 1e3, math.degrees(reading.tilt))
            )
            outcome.off_target = off_target
        if upright:
            stands(job, i, reading, off_target, i != index)
        elif reading.status == Seen.STANDING and (i != index or risky_to_lift(job, i)):
            again.append(i)
        else:
            fell(job, i, index, reading)
    if again and not second_look(job, again, index) and index in again:
        # not looked at again: judged on the first word
        fell(job, index, index, Reading.of(answer, indices.index(index)))
    return index in state.standing  # ``stands`` puts it there, ``fell`` takes it out


def risky_to_lift(job: Job, index: int) -> bool:
    """More than replace_risk standing dominoes with no empty slot between them and
    domino ``index``: a failed pick of it could fell them all."""
    return len(at_risk(index, job.state.standing)) > job.settings.replace_risk


def is_erect(job: Job, reading: Reading) -> bool:
    return reading.status == Seen.STANDING and reading.tilt <= job.settings.place_tilt_tolerance


def is_off(job: Job, reading: Reading) -> bool:
    return reading.error > job.settings.place_tolerance


def on_target(job: Job, reading: Reading) -> bool:
    return is_erect(job, reading) and not is_off(job, reading)


def stayed(job: Job, index: int, reading: Reading) -> bool:
    """Within the tolerance of where domino ``index`` was last taken to stand: not moved
    (one left 6.0 mm off read 6.6 mm at the next check and was to be picked again)."""
    last = job.state.standing.get(index)
    tolerance = job.settings.place_tolerance
    return last is not None and near(spot_of(reading.measured), spot_of(last), tolerance)


def is_off_target(job: Job, index: int, reading: Reading) -> bool:
    """Domino ``index`` stands off target where it may stay: upright, up to
    keep_off_target off (keep_when_stuck once its pick-up again failed) or where it was
    left; or, left off target after a second look (``BuildState.left_off``), standing
    where it was left."""
    settings, state = job.settings, job.state
    if index in state.left_off and reading.status == Seen.STANDING and stayed(job, index, reading):
        return True
    keep = settings.keep_when_stuck if index in state.stuck else settings.keep_off_target
    return (
        is_erect(job, reading)
        and is_off(job, reading)
        and (reading.error <= keep or stayed(job, index, reading))
    )


def stands(job: Job, index: int, reading: Reading, off_target: bool, tell: bool) -> None:
    """Domino ``index`` is taken to stand: at its target, or off target where perception
    measured it (where it was left, if it stayed there), for the planner to keep clear of;
    ``tell``: hidden, or moved off its target, it is said so."""
    state = job.state
    last = state.standing.get(index)
    moved = off_target and last is job.targets[index]
    if tell and (reading.status == Seen.NOT_SEEN or moved):
        words = reading.words
        log(f"domino {index + 1} moved ({words}); left standing" if moved else words)
    if not off_target:
        state.standing[index] = job.targets[index]
    elif last is not None and stayed(job, index, reading):
        state.standing[index] = last
    else:
        state.standing[index] = reading.measured


def fell(job: Job, index: int, placing: int, reading: Reading) -> None:
    """Domino ``index`` no longer stands (``placing``: the slot being built): built again
    from where it lies, or, where perception cannot fit it, left there."""
    state = job.state
    state.knocked_down(index)
    state.left_off.discard(index)
    state.disturbed.append(spot_of(job.targets[index]))  # it fell there, or went
    if remember_fallen(job, index, reading.status, reading.measured, reading.tilt):
        log(f"domino {index + 1} fell where perception cannot fit it; left where it lies")
    if index != placing:
        job.report.dominoes[index].placed = False  # until it is built again
        log(f"domino {index + 1} is no longer standing ({reading.words})")


def second_look(job: Job, again: Sequence[int], placing: int = -1) -> bool:
    """Run dominoes ``again``, seen standing but off target beyond what ``check`` keeps,
    looked at again from frames a camera period on (circle30 seed 1: one read 7.8 mm and
    7.3° off while the arm stood over the run, 6 others hidden, was picked from between
    its standing neighbours and the 18 before it fell). Upright within the bounds now, or
    hidden: standing as before. Still off: left where it stands while the run topples
    through it (``chain.chain_breaks``); else picked up again, unless more than
    replace_risk standing dominoes stand with no empty slot between them and it
    (``chain.at_risk``): left then too, the risk told. Down or gone: it fell. False: the
    look failed, and each is as it was."""
    fresh = settle(job, 1.0 / job.settings.camera_rate)
    job.still_since = fresh
    answer = job.cell.check_placement([job.targets[i] for i in again], not_before=fresh)
    if not answer.success:
        log(f"looking again at dominoes {span(again)} failed ({answer.message}): as they were")
        return False
    for position, i in enumerate(again):
        reading = Reading.of(answer, position)
        if i == placing:
            job.report.dominoes[i].check = reading.words
        off_target = is_off_target(job, i, reading)
        if reading.status == Seen.NOT_SEEN or off_target or on_target(job, reading):
            stands(job, i, reading, off_target, True)
        elif reading.status != Seen.STANDING:
            fell(job, i, placing, reading)
        else:
            standing_off(job, i, reading, placing)
    return True


def standing_off(job: Job, index: int, reading: Reading, placing: int = -1) -> None:
    """Domino ``index``, seen twice standing off target (``placing``: the slot being
    built): see ``second_look``."""
    settings, state = job.settings, job.state
    neighbours = {
        k: state.standing.get(k, job.targets[k])  # an empty slot: where its domino will stand
        for k in (index - 1, index + 1)
        if 0 <= k < len(job.targets)
    }
    why = chain_breaks(index, reading.measured, reading.tilt, neighbours, settings)
    risk = at_risk(index, state.standing)
    said = f"domino {index + 1} standing off target ({reading.words})"
    if why and len(risk) <= settings.replace_risk:
        log(f"{said}: {why}; picked up again ({len(risk)} standing within its reach)")
        fell(job, index, placing, reading)
        return
    if why:
        log(
            f"{said}: {why}; left standing all the same: lifting it out could fell the "
            f"{len(risk)} standing with no empty slot between (dominoes {span(risk)})"
        )
    else:
        log(f"{said}, the chain still runs; left standing")
    state.standing[index] = reading.measured
    state.left_off.add(index)
    job.report.dominoes[index].off_target = True


def span(indices: Sequence[int]) -> str:
    """Layout indices as the log numbers them, runs joined: "1-18, 20-24"."""
    runs: list[list[int]] = []
    for i in indices:
        if runs and runs[-1][-1] == i - 1:
            runs[-1].append(i)
        else:
            runs.append([i])
    return ", ".join(f"{r[0] + 1}" if len(r) == 1 else f"{r[0] + 1}-{r[-1] + 1}" for r in runs)


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
    """The toppled, unfitted and fallen run dominoes within DISTURBED_RADIUS of where
    something moved since they were seen (``BuildState.disturbed``) looked at again where
    they were seen (perception refits a lying expected pose; the standing run asked too,
    to keep its points): each found there lies where perception measured it now
    (``refit``), one seen down but not fitted is unfitted (an obstacle, not picked), one
    gone (MISSING) is forgotten. A toppled pose gone stale (up to 44 mm off after the
    build's falls, arc cycle 3) made picks close on nothing; so, presumably, did the
    fallen run of circle30 seed 1 (1-18 lying shingled, picked one by one from poses
    measured when they fell: many picks closed to 0.4 mm). The places of the unbuilt
    slots within SLOT_LOOK_RADIUS of what moved are looked at after that, in a call of
    their own (``new_at_slot``): asked beside the lying ones, an upright place took the
    points and the detection of a domino lying across it from that domino's own refit
    (arc cycles seed 3, cycle 3: a debris domino fitted as the slot's fallen one was then
    "no longer there", and four placements fell off it)."""
    state = job.state
    disturbed, state.disturbed = state.disturbed, []

    def moved_near(pose: Pose, radius: float = DISTURBED_RADIUS) -> bool:
        return any(near(spot_of(pose), spot, radius) for spot in disturbed)

    again = [pose for pose in [*state.toppled, *state.unfitted] if moved_near(pose)]
    run = [k for k, pose in state.fallen.items() if moved_near(pose)]
    slots = [
        k
        for k, target in enumerate(job.targets)
        if k not in state.standing and moved_near(target, SLOT_LOOK_RADIUS)
    ]
    if not again and not run and not slots:
        return
    fresh = settle(job) if job.still_since is None else job.still_since
    if again or run:
        seen = look(job, [*again, *(state.fallen[k] for k in run)], fresh)
        if seen is not None:
            refit_toppled(job, again, seen[: len(again)])
            refit_fallen(job, run, seen[len(again) :])
    if slots and (seen := look(job, [job.targets[k] for k in slots], fresh)) is not None:
        for k, (status, measured, _) in zip(slots, seen, strict=True):
            new_at_slot(job, k, status, measured)


Seeing = tuple[Seen, Pose, float]  # perception's status, measured pose and tilt of a place


def look(job: Job, places: Sequence[Pose], fresh: float) -> list[Seeing] | None:
    """Perception's word on ``places`` in frames from ``fresh`` on (the standing run asked
    too, to keep its points), or None when the check failed (logged)."""
    standing = list(job.state.standing.values())
    answer = job.cell.check_placement([*standing, *places], not_before=fresh)
    if not answer.success:
        log(f"looking again at {len(places)} places failed: {answer.message}")
        return None
    return list(zip(answer.status, answer.measured, answer.tilt, strict=True))[len(standing) :]


def refit_toppled(job: Job, again: Sequence[Pose], seen: Sequence[Seeing]) -> None:
    """The toppled and unfitted dominoes ``again`` as perception saw them now (``refit``)."""
    state = job.state
    toppled, unfitted = list(state.toppled), list(state.unfitted)
    for pose, (status, measured, tilt) in zip(again, seen, strict=True):
        where = f"toppled domino at {spot_of(pose).round(3).tolist()}"
        found = refit(job, where, pose, status, measured, tilt)
        if found is Found.AS_IT_WAS:
            continue
        toppled = [p for p in toppled if p is not pose]
        unfitted = [p for p in unfitted if p is not pose]
        if found is Found.UNFITTED:
            unfitted.append(pose)
        elif found is Found.THERE:
            toppled.append(measured)
    state.toppled, state.unfitted = toppled, unfitted


def refit_fallen(job: Job, run: Sequence[int], seen: Sequence[Seeing]) -> None:
    """The fallen run dominoes of slots ``run`` as perception saw them now (``refit``)."""
    state = job.state
    for k, (status, measured, tilt) in zip(run, seen, strict=True):
        found = refit(job, f"fallen domino {k + 1}", state.fallen[k], status, measured, tilt)
        if found is Found.THERE:
            state.fallen[k] = measured
        elif found is Found.UNFITTED:
            state.unfitted.append(state.fallen.pop(k))
        elif found is Found.GONE:
            state.fallen.pop(k)


def new_at_slot(job: Job, index: int, status: Seen, measured: Pose) -> None:
    """A domino perception fits lying at unbuilt slot ``index``'s place is taken as
    toppled (in the slot's way it becomes the slot's domino or is swept aside:
    ``attempts.clear_the_way``, where a domino placed on it would fall) unless its
    footprint meets a lying domino the task knows and has in the slot's way too (or it is
    out of the slot's way and meets one: that one fitted again). Arc cycles seed 3,
    cycle 3: a pick 45 mm away knocked one onto slot 6, unknown; cycle 4: one lay over
    slot 5 that the task knew 20 mm off, out of the slot's way, unfitted there; in both,
    placements fell off it and the slot was left empty. Two poses of one domino cost a
    look: the next one near a pick or push forgets or refits the stale one."""
    if status != Seen.FALLEN or tilt_from_vertical(measured) <= job.settings.place_tilt_tolerance:
        return  # nothing there, or nothing perception can fit (the upright place: no pose)
    footprint = domino_corners(measured)[:, :2]
    met = [p for p in job.state.lying() if footprints_meet(footprint, domino_corners(p)[:, :2])]
    if met and (not job.in_the_way(index, measured) or any(job.in_the_way(index, p) for p in met)):
        return  # one the task knows of, where it matters as much
    spot = spot_of(measured).round(3).tolist()
    known = ", ".join(str(spot_of(p).round(3).tolist()) for p in met)
    how = f"known at {known}, out of its way" if met else "unknown so far"
    log(f"a domino lies at slot {index + 1}'s place, at {spot}, {how}: taken as toppled")
    job.state.toppled.append(measured)


class Found(Enum):
    """A lying domino looked at again (``refit``)."""

    AS_IT_WAS = "as it was"  # STANDING or NOT_SEEN: no word on it
    GONE = "gone"  # MISSING: forgotten
    UNFITTED = "unfitted"  # down, no box fits it (tilt 0): an obstacle, not picked
    THERE = "there"  # fitted: it lies where perception measured it now


def refit(job: Job, where: str, pose: Pose, status: Seen, measured: Pose, tilt: float) -> Found:
    """What perception's answer says of a lying domino expected at ``pose``; said in
    the log (named ``where``) unless as it was."""
    if status in (Seen.STANDING, Seen.NOT_SEEN):
        return Found.AS_IT_WAS
    if status == Seen.MISSING:
        log(f"{where}: no longer there; forgotten")
        return Found.GONE
    if tilt <= job.settings.place_tilt_tolerance:
        log(f"{where}: something lies there that perception cannot fit; not picked")
        return Found.UNFITTED
    moved = float(np.linalg.norm(spot_of(measured) - spot_of(pose)))
    if moved >= SAME_SPOT:
        log(f"{where} moved {moved * 1e3:.0f} mm since it was seen")
    return Found.THERE


def check_words(status: Seen, error: float, tilt: float) -> str:
    if status == Seen.NOT_SEEN:
        return "not seen (hidden from the camera): taken as standing until the next check"
    name = {Seen.STANDING: "standing", Seen.FALLEN: "fallen", Seen.MISSING: "missing"}[status]
    return f"{name}, {error * 1e3:.1f} mm and {math.degrees(tilt):.1f}° from the target"

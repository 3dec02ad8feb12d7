"""Running a plan in the cell: each grasp checked by the finger opening (a failed one
backed out of), the hold looked at above the slot (carried again from where it is held,
or put back on the pile)."""

from __future__ import annotations

import math
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, replace
from enum import Enum
from functools import partial

import numpy as np

from dombot_bringup.task import ahead
from dombot_bringup.task.cell import (
    CellError,
    GripperEvent,
    Later,
    Meanwhile,
    PlacementCheck,
    PlaceRequest,
    Pose,
    Seen,
    Segment,
    Trajectory,
)
from dombot_bringup.task.chain import at_risk
from dombot_bringup.task.checks import settle
from dombot_bringup.task.geometry import foot, foot_distance, lowered
from dombot_bringup.task.state import Job, log
from dombot_description import DOMINO_SIZE

BACK_OUT_LEAD = 0.5  # s to get from where a failed approach stopped back onto its path
LET_GO_OPENING = 0.04  # m the fingers open to, around a 24 mm domino, to let go of it
# ends straight above the slot, where the hold is looked at (a regrasp's own is prefixed)
HOLD_CHECK_SEGMENT = "transfer"
OPEN_SEGMENT = "open_gripper"  # the fingers open for the approach that follows
PLACE_SEGMENT = "place"  # the fingers let go of the domino on its slot once it ends
REGRASP_PREFIX = "regrasp_"  # the planner's turn in place before the pick proper
# when ``Hold.ask_ahead`` is called: as the descent to the slot starts; then while the arm
# descends, lets go and retreats (each motion's ``meanwhile``), for the look to answer
DESCENT, LOOK_ANSWERED = "descent", "look_answered"
# What the in-hand check says when it cannot measure the held domino.
IN_HAND_WORDS = {
    Seen.FALLEN: "no upright domino fitted below the pads",
    Seen.MISSING: "nothing seen below the pads (dropped?)",
    Seen.NOT_SEEN: "not seen well enough (hidden, or seen edge-on)",
}


class Ran(Enum):
    """How a plan's execution ended."""

    DONE = "done"
    FAILED = "failed"  # a motion or a grasp failed (a failed grasp was backed out of)
    PUT_BACK = "put back"  # the hold could not be placed: dropped back onto the pile


@dataclass(frozen=True)
class Execution:
    ran: Ran
    why: str = ""  # what failed, or how the hold was found
    stalled: bool = False  # put back because its descent to the place stalled

    @property
    def done(self) -> bool:
        return self.ran is Ran.DONE


@dataclass(frozen=True)
class Hold:
    """A domino being carried to slot ``index``: where the plan holds it above the slot,
    where it was picked (a fallen run domino is no obstacle there any more), and what to
    do as its descent starts and, from then on, while the arm waits for the descent, the
    release and the retreat to end (the next pick asked ahead), given when (DESCENT,
    LOOK_ANSWERED) and where the arm's joints end (name → rad)."""

    index: int
    held_above: Pose
    picked: Pose
    ask_ahead: Callable[[str, Mapping[str, float]], None] | None = None


@dataclass(frozen=True)
class InHand:
    """What the look at the hold above its slot decided."""

    again: tuple[Segment, ...] = ()  # a plan from where it is held; none: place as planned
    put_back: str = ""  # why it is not to be placed but dropped back onto the pile


def execute(
    job: Job,
    segments: Sequence[Segment],
    hold: Hold | None = None,
    holds_domino: bool = True,
    carried: tuple[Segment, ...] = (),
) -> Execution:
    """Run the segments and their gripper events.

    The fingers open for a grasp while the approach moves, when they are nearly open
    (``opens_while_moving``). A close that should hold a domino is checked by where the
    fingers stopped (the strike closes them on nothing). When a grasp fails, the arm
    backs out the way it came before anything else is tried. With a ``hold``, the domino
    is looked at in the hand where "transfer" ends above its slot (``in_hand``); at a slot
    the pile cameras see past, the next look at the pile is asked for just before it
    (``look_while_placing``; perception answers the hand check beside it, not after it),
    and ``hold.ask_ahead`` is told where the plan ends as the descent starts and again and
    again while the descent, the release and the retreat run (their ``meanwhile``: on this
    thread, between polls for their end), so the next pick goes out the moment that look
    answers.
    The descent to the place stops as soon as a joint falls ``place_path_tolerance``
    behind it (the held domino or a pad pressing on something): the arm backs up the
    line, still holding the domino, and puts it back on the pile along the transfers it
    came (``carried``: those of the plans run before this one) rather than press on.
    Any motion drops what was planned ahead (``ahead.drop``) and the look at the pile
    made while placing.
    """
    ahead.drop(job, "the arm moves before the turn")
    job.still_since = job.let_go_at = job.pile_look = None
    cell = job.cell
    opening: Later[float] | None = None  # the fingers opening while the approach moves
    asking: Meanwhile | None = None  # from the descent on: the next pick, once looked
    for index, segment in enumerate(segments):
        approach = is_approach(segment)
        if hold is not None and segment.label == PLACE_SEGMENT:
            if job.pile_look is None and pile_in_view(job, hold.index):
                look_while_placing(job)  # no transfer before it
            if hold.ask_ahead is not None:
                hold.ask_ahead(DESCENT, end_of(segments))
                asking = partial(hold.ask_ahead, LOOK_ANSWERED, end_of(segments))
        if moves(segment):
            tolerance = job.settings.approach_goal_tolerance if approach else 0.0
            placing = segment.label == PLACE_SEGMENT
            path = job.settings.place_path_tolerance if placing else 0.0
            motion = cell.execute(segment.trajectory, tolerance, path, meanwhile=asking)
            if opening is not None:
                job.fingers, opening = opening(), None
            if not motion.ok:
                why = f"{segment.label}: {motion.error}"
                if approach:
                    back_out(job, segment)
                elif placing and holds_domino and (way := (*carried, *transfers(segments))):
                    log(f"{why}; backing up the line, still holding it")
                    move(job, segment.trajectory.reversed(BACK_OUT_LEAD), "backing up")
                    put_back(job, way)
                    why = f"put back on the pile: its descent stopped ({why})"
                    return Execution(Ran.PUT_BACK, why, stalled=True)
                return Execution(Ran.FAILED, why)
        if segment.gripper_after == GripperEvent.CLOSE:
            stopped = grip(job, segment.gripper_position, segment.gripper_max_effort)
            problem = grasp_problem(job, stopped)
            if holds_domino and problem:
                back_out(job, segment)
                return Execution(
                    Ran.FAILED,
                    f"{segment.label}: grasp {problem} (fingers stopped at "
                    f"{stopped * 1e3:.1f} mm, domino {DOMINO_SIZE[1] * 1e3:.0f} mm)",
                )
        elif segment.gripper_after == GripperEvent.OPEN:
            if opens_while_moving(job, segment, segments[index + 1 : index + 2]):
                opening = cell.gripper_later(segment.gripper_position, 0.0)
            else:
                grip(job, segment.gripper_position, 0.0, meanwhile=asking)
            if segment.label == PLACE_SEGMENT:
                job.let_go_at = cell.sim_time
        if hold is not None and segment.label == HOLD_CHECK_SEGMENT:
            if pile_in_view(job, hold.index):
                look_while_placing(job)
            verdict = in_hand(job, hold, segment)
            if verdict.put_back:
                put_back(job, (*carried, *transfers(segments[: index + 1])))
                return Execution(Ran.PUT_BACK, verdict.put_back)
            if verdict.again:
                return execute(job, verdict.again, carried=(*carried, segment))
    return Execution(Ran.DONE)


def opens_while_moving(job: Job, segment: Segment, following: Sequence[Segment]) -> bool:
    """Whether ``segment``'s open, the fingers' for a grasp before ``following``'s approach
    (the planner's ``open_gripper``, where the arm stands), runs while that approach moves:
    when the fingers stand within ``open_while_moving`` of the opening. The approach was
    planned with them open all the way: a pad that far inside where the plan has it
    stays clear on its coarse move, and they open within ~0.07 s (7 mm at 0.1 m/s),
    the coarse move lasting ~1 s before its line down to the grasp."""
    goal, fingers = segment.gripper_position, job.fingers
    return (
        segment.label.endswith(OPEN_SEGMENT)
        and segment.trajectory.duration == 0.0  # where the arm stands (one point, or none)
        and bool(following)
        and is_approach(following[0])
        and following[0].trajectory.duration > 0.0
        and fingers is not None
        and abs(fingers - goal) <= job.settings.open_while_moving
    )


def in_hand(job: Job, hold: Hold, transfer: Segment) -> InHand:
    """The held domino straight above its slot (where ``transfer`` ended), seen by
    perception: when it turned or slid in the hand on the way (``in_hand_tolerance``), or
    hangs lower than planned (``in_hand_low_tolerance``), a plan from where it is held to
    its release pose (down onto it from above, the fingers open there, then the retreat).
    Not seen there, and a fall of it could take down more than ``in_hand_look_risk``
    standing dominoes: looked at again from the base turned (``look_turned``).
    No plan: placed as planned (within the tolerance, read beyond ``in_hand_max_off``, not
    seen well, or no plan for a hold that may still stand). Put back: no plan, and leaning
    over ``put_back_lean`` it would fall."""
    settings, name = job.settings, job.domino(hold.index)
    if settings.in_hand_tolerance <= 0.0:
        return InHand()
    fresh = settle(job)
    answer = job.cell.check_placement([hold.held_above], in_hand=True, not_before=fresh)
    risk = len(at_risk(hold.index, job.state.standing))
    if (
        answer.success
        and answer.status[0] == Seen.NOT_SEEN
        and settings.in_hand_look_turn != 0.0
        and risk > settings.in_hand_look_risk
    ):
        log(f"{name} in the hand: {IN_HAND_WORDS[Seen.NOT_SEEN]}, {risk} standing at risk")
        answer = look_turned(job, hold.held_above, end_of([transfer]))
    if not (answer.success and answer.status[0] == Seen.STANDING):
        status = IN_HAND_WORDS.get(answer.status[0], "?") if answer.success else answer.message
        log(f"{name} in the hand: {status}; placing it")
        return InHand()
    measured, tilt = answer.measured[0], answer.tilt[0]
    off = foot_distance(measured, hold.held_above)
    seen = f"foot {off * 1e3:.1f} mm off, leaning {math.degrees(tilt):.1f}°"
    # how much lower than planned it hangs: the place line ends release_height above the
    # table for the hold as planned, so a lower one would press the table (issue 23)
    low = foot(hold.held_above)[2] - foot(measured)[2]
    hangs = f"{low * 1e3:.1f} mm lower than planned"
    aside = off > settings.in_hand_tolerance or tilt > settings.in_hand_tilt_tolerance
    if not aside and low <= settings.in_hand_low_tolerance:
        log(f"{name} in the hand: {seen} ({hangs}); placing it")
        return InHand()
    if off > settings.in_hand_max_off:
        log(f"{name} in the hand: {seen}; too far off: a misreading, placing it")
        return InHand()
    outcome = job.report.dominoes[hold.index]
    outcome.corrected_in_hand.append(f"{seen} ({hangs})")
    plan = job.cell.plan_place(
        PlaceRequest(
            # only low: the hold as planned, that much lower (its foot's horizontal
            # reading, within in_hand_tolerance, is as much perception's ~1 mm as the hold's)
            domino=measured if aside else lowered(hold.held_above, low),
            place=job.releases[hold.index],
            # a fallen run domino being carried is no obstacle where it lay (an S-curve
            # run: its own pose "overlapped" its slot, every correction was
            # refused, and the build stopped at that slot)
            standing=(
                *job.state.standing.values(),
                *(pose for pose in job.state.lying() if pose is not hold.picked),
            ),
            holding=True,
            time_budget=settings.plan_budget,
        )
    )
    if plan.success:
        log(f"{name} in the hand: {seen} ({hangs}); carrying it again from where it is held")
        return InHand(again=plan.segments)
    refused = f"carrying it again refused ({plan.message.split(' (')[0]})"
    if tilt > settings.put_back_lean:
        outcome.put_back.append(seen)
        log(f"{name} in the hand: {seen}; {refused}; it would fall")
        return InHand(put_back=f"put back on the pile: held {seen}, {refused}")
    log(f"{name} in the hand: {seen}; {refused}; placing it as it is")
    return InHand()


def look_turned(job: Job, held_above: Pose, above: Mapping[str, float]) -> PlacementCheck:
    """The in-hand check again with the arm's base joint turned ``in_hand_look_turn`` from
    ``above`` and back, its reading turned back to above the slot. The planner's joints
    run from the base out: the first turns the arm, and the hold with it, rigidly about the
    world's z axis (the scenario's origin is the arm's base), so the hold expected there is
    the planned one turned so, and nothing moves lower than it was (the held domino's
    foot clears the run's tops above its slot)."""
    turn = job.settings.in_hand_look_turn
    out = base_turn(above, turn, job.settings.in_hand_look_speed)
    log(f"looking again with the arm's base turned {math.degrees(turn):+.0f}°")
    # the look at the pile asked for above the slot may be answered from frames the turned
    # arm is in: dropped, it is asked again as the descent starts (``execute``)
    job.pile_look = None
    motion = job.cell.execute(out)
    if motion.ok:
        turned = about_base(turn)
        fresh = settle(job)
        answer = job.cell.check_placement([turned @ held_above], in_hand=True, not_before=fresh)
        measured = tuple(about_base(-turn) @ pose for pose in answer.measured)
        answer = replace(answer, measured=measured)
    else:
        answer = PlacementCheck(False, f"turning the base failed: {motion.error}")
    # from where a failed turn stopped, eased onto the way back as a failed approach is
    move(job, out.reversed(0.0 if motion.ok else BACK_OUT_LEAD), "turning the base back")
    return answer


def base_turn(at: Mapping[str, float], turn: float, speed: float) -> Trajectory:
    """From the joints ``at``, the first (the base) turned by ``turn`` rad, the others
    held: a half-cosine in time, at most ``speed`` rad/s, still at both ends."""
    names = tuple(at)
    start = np.array([at[name] for name in names])
    duration = math.pi * abs(turn) / (2.0 * speed)
    phase = np.linspace(0.0, math.pi, 11)
    positions = np.repeat(start[None, :], len(phase), axis=0)
    velocities = np.zeros_like(positions)
    positions[:, 0] += turn * (1.0 - np.cos(phase)) / 2.0
    velocities[:, 0] = turn * math.pi / (2.0 * duration) * np.sin(phase)
    return Trajectory(names, phase / math.pi * duration, positions, velocities)


def about_base(turn: float) -> Pose:
    """The rigid turn of ``turn`` rad about the world's z axis, the arm base's."""
    pose = np.eye(4)
    pose[:2, :2] = [[math.cos(turn), -math.sin(turn)], [math.sin(turn), math.cos(turn)]]
    return pose


def pile_in_view(job: Job, index: int) -> bool:
    """Whether perception sees the pile as with the arm away while the arm holds a domino
    above slot ``index`` or places it there: the slot at least look_while_placing from the
    pile's centre (the hand then out of perception's pile region). The pile has been still
    since the lift, so a look from then on serves the next pick."""
    slot = job.releases[index][:2, 3]
    return bool(np.hypot(*(slot - job.settings.pile_center)) >= job.settings.look_while_placing)


def look_while_placing(job: Job) -> None:
    """Ask for the next pick's look at the pile now (``job.pile_look``); perception not
    answering the request leaves it to the next look, it does not fail the placement."""
    job.pile_seen_at = job.cell.sim_time
    try:
        job.pile_look = job.cell.detect_later(job.pile_seen_at)
    except CellError as error:
        log(f"perception while placing: {error}")


def grip(
    job: Job, position: float, max_effort: float, *, meanwhile: Meanwhile | None = None
) -> float:
    """``cell.gripper``, remembering where the fingers stopped (``job.fingers``)."""
    job.fingers = job.cell.gripper(position, max_effort, meanwhile=meanwhile)
    return job.fingers


def transfers(segments: Sequence[Segment]) -> tuple[Segment, ...]:
    """The carries among ``segments`` from above the pick towards the slot, in order."""
    return tuple(s for s in segments if s.label == HOLD_CHECK_SEGMENT)


def put_back(job: Job, carried: Sequence[Segment]) -> None:
    """Carry the held domino back along the ``carried`` transfers (the first from above
    where it was picked, each later one from where the one before it ended) to above
    where it was picked (the way it came, with this hold), let it drop onto the pile from
    there, and go back along the first: out of the cameras' view of the pile before the
    next look, where the next plan starts as after a placement. The pile changes: the
    look at it made while placing and the pick asked ahead are dropped."""
    log("put back on the pile: carrying it back to where it was picked and letting it drop")
    job.pile_look = None
    ahead.drop(job, "the domino is put back on the pile")
    for transfer in reversed(carried):
        move(job, transfer.trajectory.reversed(BACK_OUT_LEAD), "putting it back")
    grip(job, LET_GO_OPENING, 0.0)
    move(job, carried[0].trajectory, "leaving the pile")


def grasp_problem(job: Job, opening: float) -> str:
    """What the finger opening after a close says is wrong with the grasp, or ""."""
    inside = DOMINO_SIZE[1] - opening
    if abs(inside) > job.settings.grasp_width_tolerance:
        return "missed"
    if inside > job.settings.grasp_squeeze_limit:
        return "on an edge"
    return ""


def back_out(job: Job, segment: Segment) -> None:
    """After a failed grasp: open, and retrace the approach to where it started.

    The way in was collision-free, so the way back is too, and it takes the arm out of
    the cameras' view of the pile before perception looks again.
    """
    grip(job, segment.gripper_position + LET_GO_OPENING, 0.0)
    if moves(segment):
        move(job, segment.trajectory.reversed(BACK_OUT_LEAD), "backing out")


def moves(segment: Segment) -> bool:
    """Whether a segment's trajectory goes anywhere: the planner's gripper-only steps
    (``open_gripper``) have one point, where the arm stands, and a goal for it costs an
    action round trip (40-55 ms simulated) for nothing."""
    return len(segment.trajectory.times) > 1


def move(job: Job, trajectory: Trajectory, what: str) -> None:
    """Run ``trajectory`` off plan (a way back); a failure is logged, not raised: the next
    plan starts from wherever the arm stopped."""
    motion = job.cell.execute(trajectory)
    if not motion.ok:
        log(f"{what} failed: {motion.error}")


def end_of(segments: Sequence[Segment]) -> dict[str, float]:
    """Where the arm's joints stand once ``segments`` have run: their last point."""
    last = next(s.trajectory for s in reversed(segments) if len(s.trajectory.times))
    return dict(zip(last.joint_names, last.positions[-1].tolist(), strict=True))


def is_approach(segment: Segment) -> bool:
    """The segment that brings the open gripper down to a domino (regrasps included)."""
    return segment.label.endswith("approach_grasp")

"""What to pick for a slot: candidates from the pile and the fallen run dominoes, offered
to the planner in tiers of how the pile is treated, until one plans."""

from __future__ import annotations

import functools
import math
from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np

from dombot_bringup.layouts import DOMINO_LENGTH
from dombot_bringup.offers import PILE_BOXES, PILE_CORES, PILE_IGNORED, pile_cores
from dombot_bringup.sections import count_refusal
from dombot_bringup.task import ahead
from dombot_bringup.task.cell import (
    CellError,
    Detection,
    Detections,
    PlaceRequest,
    Plan,
    Pose,
    Posture,
    planner_request,
)
from dombot_bringup.task.checks import look_again, settle
from dombot_bringup.task.geometry import (
    near,
    near_any,
    neighbours_of,
    points_near,
    spot_of,
)
from dombot_bringup.task.state import Job, log
from dombot_description import tilt_from_vertical
from dombot_description.scenario import load_scenario
from dombot_planner.arm_reach import WristReach
from dombot_planner.errors import ErrorCode
from dombot_planner.foreseen_refusal import foreseen_refusal
from dombot_planner.settings import PlannerSettings

DETECT_TRIES = 5
# The planner has the last word. Upright, the canonical grasp holds a domino as it holds
# it placed (bench_lay_flat: 3 of 3 lone upright pile dominoes planned); no grasp of the
# family holds one on its edge (the fingers would close across its vertical width).
PICKABLE_POSTURES = (Posture.FLAT, Posture.TILTED, Posture.UPRIGHT)
# Refusals about the domino, not the slot: remembered for the run. A search that used up
# its budget (one domino cost 5 s at every slot of an S-curve) would use it up again.
GRASP_REFUSALS = (ErrorCode.GRASP_UNREACHABLE, ErrorCode.TIMEOUT)
# What foreseen_refusal judges the pads by: the planner's settings as arm_job starts it
# (the defaults; only its budget clock differs, which the pads' tests do not read).
PLANNER_SETTINGS = PlannerSettings()
POSTURE_NAMES = {
    Posture.FLAT: "flat",
    Posture.ON_EDGE: "on edge",
    Posture.UPRIGHT: "upright",
    Posture.TILTED: "leaning",
}
PILE_WORDS = {
    PILE_BOXES: "",
    PILE_CORES: " with its pile's cores",
    PILE_IGNORED: " ignoring its pile",
}


@dataclass
class Candidate:
    """Something to pick: a pile detection or a fallen run domino, with what lies near it."""

    pose: Pose
    run_index: int | None = None  # layout index of a fallen run domino; None: the pile
    neighbours: list[Pose] = field(default_factory=list)
    posture: Posture | None = None  # None: a fallen run domino (``run_posture``)
    scored: bool = True  # perception found room for the fingers
    clearance: float = math.inf  # m beside the finger contact sides, as perception measured
    # Perception's grasp, clear of every point the cameras saw (undetected dominoes too);
    # None for a fallen run domino: the planner chooses.
    grasp: Pose | None = None
    # seen points near it on no detected domino: the planner keeps the pads' path clear
    points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    toppled: bool = False  # one an earlier cycle knocked down (``BuildState.toppled``)

    def spot(self) -> np.ndarray:
        return spot_of(self.pose)

    @property
    def leaning(self) -> bool:
        return self.posture == Posture.TILTED

    @property
    def posture_name(self) -> str:
        return "fallen" if self.posture is None else POSTURE_NAMES[self.posture]

    @property
    def from_pile(self) -> bool:
        return self.run_index is None and not self.toppled

    @property
    def source(self) -> str:
        if self.toppled:
            return "toppled domino"
        return "pile" if self.run_index is None else f"run domino {self.run_index + 1}"


@dataclass(frozen=True)
class Refusal:
    """A candidate the planner refused for a slot, with its error code and message."""

    candidate: Candidate
    code: int
    message: str

    @property
    def about_the_slot(self) -> bool:
        return self.code not in GRASP_REFUSALS


@dataclass(frozen=True)
class Offer:
    """A candidate that planned, with how its pile went to the planner (offers.PILE_*)."""

    candidate: Candidate
    pile: str
    plan: Plan


def candidates(
    job: Job, failed: list[np.ndarray], index: int
) -> tuple[list[Candidate], list[Candidate]]:
    """What to offer: fallen run dominoes first (they block the run), then those an
    earlier cycle toppled (``toppled_candidates``; looked at again first where
    something moved near them, ``checks.look_again``), then the pile's detections in
    perception's order (best grasp first); none where an attempt failed or no grasp
    reaches. And the pile dominoes no grasp takes as they lie, for
    ``clearing.lay_flat``: on their edge first (no grasp of the family holds them),
    then those refused even ignoring their pile (or whose pick failed), and leaning ones
    refused for this slot (a hold leaning with the domino may have no place pose)."""
    look_again(job)  # toppled dominoes near what moved since they were seen
    unpickable = job.state.unpickable
    avoid = failed + unpickable
    fallen, lying, way = job.state.fallen, job.state.lying(), in_its_way(job, index)
    run = [
        Candidate(pose, k, neighbours_of(pose, lying), posture=run_posture(pose))
        for k, pose in sorted(fallen.items(), key=lambda item: not is_among(item[1], way))
        if is_among(pose, lying) and not near_any(spot_of(pose), avoid)  # a twin once
    ]
    run += toppled_candidates(job, index, avoid)
    detections, unexplained = look_at_pile(job)
    pile = [pile_candidate(d, detections, unexplained) for d in detections]
    graspable = [c for c in pile if c.posture in PICKABLE_POSTURES]
    offers = [c for c in graspable if not near_any(c.spot(), avoid)]
    stuck = [c for c in pile if c.posture not in PICKABLE_POSTURES] + [
        c
        for c in graspable
        if near_any(c.spot(), unpickable) or (c.leaning and near_any(c.spot(), failed))
    ]
    return run + offers, stuck


def run_posture(pose: Pose) -> Posture | None:
    """How a run domino out of place is offered: UPRIGHT if perception saw it standing
    (nearer vertical than lying; ``checks.second_look`` chose to pick it up again), named
    so in the log, never as fallen; None (fallen: the planner chooses) otherwise."""
    return Posture.UPRIGHT if tilt_from_vertical(pose) < math.pi / 4 else None


def toppled_candidates(job: Job, index: int, avoid: list[np.ndarray]) -> list[Candidate]:
    """The dominoes an earlier cycle toppled, those in the way of slot ``index``
    (``in_its_way``) first, then nearest the slot first: one lying over the slot is
    cleared by becoming its domino, and the rest of a fallen row lies ahead."""
    lying, place, way = job.state.lying(), spot_of(job.targets[index]), in_its_way(job, index)
    toppled = [
        pose
        for pose in job.state.toppled
        if is_among(pose, lying) and not near_any(spot_of(pose), avoid)
    ]
    toppled.sort(
        key=lambda pose: (not is_among(pose, way), float(np.linalg.norm(spot_of(pose) - place)))
    )
    return [
        Candidate(pose, neighbours=neighbours_of(pose, lying), toppled=True) for pose in toppled
    ]


def in_its_way(job: Job, index: int) -> list[Pose]:
    """The lying dominoes (fallen, toppled) in the way of slot ``index``'s domino and the
    pads beside it (``Job.in_the_way``): each is taken as the slot's domino or swept aside
    before anything is placed there."""
    return [pose for pose in job.state.lying() if job.in_the_way(index, pose)]


def is_among(pose: Pose, poses: Sequence[Pose]) -> bool:
    """``pose`` is one of ``poses`` (the same object: the same remembered domino)."""
    return any(pose is other for other in poses)


def pile_candidate(
    detection: Detection, detections: Sequence[Detection], unexplained: np.ndarray
) -> Candidate:
    return Candidate(
        detection.pose,
        None,
        neighbours_of(detection.pose, [d.pose for d in detections]),
        posture=detection.posture,
        scored=detection.score > 0.0,
        clearance=detection.clearance,
        grasp=detection.grasp,
        points=points_near(detection.pose, unexplained),
    )


def look_at_pile(job: Job) -> tuple[list[Detection], np.ndarray]:
    """Perception's detections in fresh frames, and the points seen on none of them.
    A failure or an empty pile (e.g. the cameras' first frames after the reset not yet
    through) is asked again a camera period on (a run whose first looks came at once
    after the reset found no frames for four attempts); an empty answer after that is
    taken as the pile's end. Nothing moved since the last placement check: its frames
    serve (no frame to wait for); a look asked for while the arm placed
    (``job.pile_look``) serves when it found dominoes."""
    early, job.pile_look = job.pile_look, None
    if early is not None:
        try:
            answer = early()
        except CellError as error:
            answer = Detections(False, str(error))
        if answer.success and answer.dominoes:
            return list(answer.dominoes), answer.unexplained
        log(f"perception while placing: {answer.message}; looking again")
    period = 1.0 / job.settings.camera_rate
    for attempt in range(DETECT_TRIES):
        if attempt:  # a camera period on: frames asked for at once may not be out yet
            not_before = settle(job, period)
        else:
            not_before = settle(job) if job.still_since is None else job.still_since
        answer = job.cell.detect(not_before)
        job.pile_seen_at = not_before
        if answer.success and answer.dominoes:
            return list(answer.dominoes), answer.unexplained
        log(f"perception: {answer.message}; asking again")
    if answer.success:
        return [], np.zeros((0, 3))
    raise CellError(f"perception: {answer.message}")


def first_plan(
    job: Job,
    index: int,
    offers: Sequence[tuple[Candidate, str]],
    failed: list[np.ndarray],
    refusals: list[Refusal],
) -> tuple[Offer | None, int]:
    """The first of ``offers`` (candidate, pile tier) that plans for slot ``index`` and how
    many were refused before it. Every refusal goes to ``refusals``; those about the slot
    to ``failed`` too; those about the domino are remembered for the run (see
    ``attempts.attempt``)."""
    refused = 0
    for candidate, pile in offers:
        spot = candidate.spot()
        if near_any(spot, failed):
            continue  # refused for this slot already
        request = place_request(job, index, candidate, pile)
        plan = ahead.answer(job, request) or foreseen(job, request) or job.cell.plan_place(request)
        if plan.success:
            return Offer(candidate, pile, plan), refused
        refused += 1
        where = (
            f"{candidate.source} ({candidate.posture_name}) at "
            f"{spot.round(3).tolist()}{PILE_WORDS[pile]}"
        )
        log(f"{job.domino(index)}: refused {where}: {plan.message.split(' (')[0]}")
        count_refusal(job.report.dominoes[index].refusals, plan.error, plan.foreseen)
        refusals.append(Refusal(candidate, plan.error, plan.message))
        if refusals[-1].about_the_slot:
            failed.append(spot)
        elif pile == PILE_BOXES:
            job.state.crowded.append(spot)
        elif pile == PILE_CORES:
            job.state.cored.append(spot)
        elif pile == PILE_IGNORED:
            job.state.unpickable.append(spot)
            job.state.remember_why(spot, f"refused ignoring its pile: {plan.message}")
    return None, refused


@functools.cache
def planner_reach() -> WristReach:
    """The planner's wrist shell: its arm as the scenario the bring-up runs has it
    (measured once on a shadow plant, ~0.1 s CPU)."""
    return WristReach.of_scenario(load_scenario())


def foreseen(job: Job, request: PlaceRequest) -> Plan | None:
    """The planner's refusal of ``request`` when it is told without asking the planner
    (``dombot_planner.foreseen_refusal``: every grasp it would try has its pads' path on seen
    points, its pads beyond pile_nudge in a pile domino, or its wrist beyond the elbow's
    reach at the grasp or on every lift line, or is a turned grasp whose hold has no place
    pose at the slot, before any IK), else None (settings foresee_refusals). Of 68
    recorded pile requests, 21 of the 34 refused were told by the pads alone, in ~0.05 s
    CPU each; the planner took 0.05-0.91 s CPU to refuse them, and the bring-up waited
    that and a service round trip (docs/PLANNER.md)."""
    if not job.settings.foresee_refusals or request.holding:
        return None
    why = foreseen_refusal(planner_request(request, np.zeros(0)), PLANNER_SETTINGS, planner_reach())
    if not why:
        return None
    return Plan(False, ErrorCode.GRASP_UNREACHABLE, f"foreseen: {why}", foreseen=True)


def place_request(job: Job, index: int, candidate: Candidate, pile: str) -> PlaceRequest:
    """What the planner is asked to pick ``candidate`` for slot ``index`` with ``pile``."""
    with_pile = pile != PILE_IGNORED
    release = job.releases[index]
    return PlaceRequest(
        domino=candidate.pose,
        place=release,
        standing=(
            *job.state.standing.values(),
            *debris(job, candidate, with_pile, spot_of(release)),
        ),
        # tried first, then the planner's own (regrasp included): the planner knows only
        # the detected pile, and grasps missed as the fingers closed on dominoes
        # perception had within 1.2 mm of the truth
        grasp=candidate.grasp,
        pile=tuple(candidate.neighbours) if with_pile else (),
        # unlike the pile's boxes, kept in the last resort too: it missed 8 of 11
        # picks, and a domino never detected is nothing the pads may push
        pile_points=pile_points(job, candidate, pile),
        # with the cores, only the gripper body and arm keep clear of the boxes: in 2 of
        # 3 such picks that missed, the body was 6-9 mm inside one
        pads_into_pile=pile == PILE_CORES,
        time_budget=job.settings.plan_budget,
    )


def pile_points(job: Job, candidate: Candidate, pile: str) -> np.ndarray:
    """The points the planner keeps the pads' path from: those seen on no detected
    domino, and with PILE_CORES the cores of the pile neighbours (``offers.pile_cores``)."""
    if pile != PILE_CORES:
        return candidate.points
    cores = pile_cores(candidate.spot(), candidate.neighbours, job.settings.pile_core_shrink)
    return np.concatenate([candidate.points.reshape(-1, 3), cores])


def debris(
    job: Job, candidate: Candidate, with_pile: bool = True, place: np.ndarray | None = None
) -> list[Pose]:
    """Fallen and toppled dominoes lying in the build area (not the one to pick): the
    carry and the placement must keep clear of them as of the standing ones (a placement
    that met one fell). Its pile neighbours go to the planner as its pile instead; ignoring its
    pile, those within a domino length of the ``place`` stay obstacles: a run domino
    picked so was placed onto the fallen ones beside it, and fell (S-curve seed 2)."""
    pile = [
        pose
        for pose in candidate.neighbours
        if with_pile or place is None or not near(spot_of(pose), place, DOMINO_LENGTH)
    ]
    return [
        pose
        for pose in job.state.lying()
        if pose is not candidate.pose and not any(pose is p for p in pile)
    ]

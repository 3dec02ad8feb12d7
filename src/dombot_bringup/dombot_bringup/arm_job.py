"""The arm job: build a user's domino run from the pile, knock it down, report.

Starts ``sim_node``, ``perception_node`` and ``planner_node`` as separate processes,
then for each domino of the layout, in run order:

perceive the pile → choose the best graspable detection → ``/plan_place`` with the
dominoes already standing as obstacles → execute the segments (trajectories and
gripper events) → check the grasp by the finger opening → carry it above its slot and
look at the hold (carried again if it turned in the hand) → place → check the placement
with perception (camera_2 watches the build area) → on failure retry with the next
candidate; a domino that fell is picked up again from where perception found it.

A fallen domino that no grasp reaches and that lies where a slot goes is swept aside
(``/plan_strike`` with a sweep direction: pushed low across the run); so is a pile
domino out of a crowd that no pick plans for.

A slot that cannot be filled (its attempts used up) is left empty and the run is built
around it. Then ``/plan_strike`` knocks over the first domino of each section (consecutive
standing dominoes; the whole run when every slot was filled), from the run's end
backwards (``sections``), and perception checks that every one fell. The simulator's
ground truth goes into the report only.
"""

from __future__ import annotations

import contextlib
import json
import math
import re
import sys
import time
from collections.abc import Callable, Iterable, Sequence
from dataclasses import dataclass, field
from pathlib import Path
from typing import TextIO

import numpy as np
import rclpy
from geometry_msgs.msg import Point, Pose, Quaternion, Vector3
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from dombot_bringup.cell_client import CallFailedError, CellClient
from dombot_bringup.debris import sweep_pushes
from dombot_bringup.layouts import DOMINO_LENGTH, DominoPlacement, safety_gaps
from dombot_bringup.offers import (
    NEIGHBOUR_RADIUS,
    PILE_BOXES,
    PILE_CORES,
    PILE_IGNORED,
    pile_cores,
    roomiest_first,
    with_pile_first,
)
from dombot_bringup.process_group import NodeDiedError, ProcessGroup
from dombot_bringup.run_report import (
    DominoOutcome,
    EmptySlot,
    RunReport,
    SectionOutcome,
    TruthPose,
    target_of,
    write_report,
)
from dombot_bringup.sections import (
    VERDICTS,
    Section,
    count_refusal,
    empty_message,
    empty_reason,
    sections_of,
    strike_order,
)
from dombot_bringup.spread import spread_pushes, stir_pushes
from dombot_description import DOMINO_SIZE, tilt_from_vertical
from dombot_description.pose_messages import duration_message, pose_matrix, seconds_of
from dombot_msgs.msg import DominoDetection, TrajectorySegment
from dombot_msgs.srv import CheckPlacement, PlanPlace, PlanStrike

NodeCommand = Callable[[str, str, dict], list[str]]
BACK_OUT_LEAD = 0.5  # s to get from where a failed approach stopped back onto its path
LET_GO_OPENING = 0.04  # m the fingers open to, around a 24 mm domino, to let go of it
PUT_BACK = "put back on the pile"  # how an attempt whose hold could not be placed ended
DISTURBED_RADIUS = 0.05  # m: a pick moves the dominoes whose centres are this close to it
RECORDING_FILE, SCENE_FILE = "run.mcap", "scene.html"  # in the report folder, --record
MESHCAT_URL = re.compile(r"Meshcat: (\S+)")  # sim_node's log line
REPORT_CAMERA = "camera_2"  # its frames of the run before and after the strike go in the report
DETECT_TRIES = 5
POINTS_RADIUS = 0.12  # m: seen points farther from a pick than this cannot meet the pads
SAME_SPOT = 0.01  # m: detections this close are taken for the same domino
# Refusals about the domino, not the slot: remembered for the run. A search that used up
# its budget (one domino cost 5 s at every slot of an S-curve) would use it up again.
GRASP_REFUSALS = (PlanPlace.Response.GRASP_UNREACHABLE, PlanPlace.Response.TIMEOUT)
PLACED, FAILED, DEFERRED = "placed", "failed", "deferred"  # how a slot's turn ended
SPREAD_TRIES = 2  # pushes of one pile domino offered to the planner (the shortest first)
PILE_WORDS = {
    PILE_BOXES: "",
    PILE_CORES: " with its pile's cores",
    PILE_IGNORED: " ignoring its pile",
}
# What the in-hand check says when it cannot measure the held domino.
IN_HAND_WORDS = {
    CheckPlacement.Response.FALLEN: "no upright domino fitted below the pads",
    CheckPlacement.Response.MISSING: "nothing seen below the pads (dropped?)",
    CheckPlacement.Response.NOT_SEEN: "not seen well enough (hidden, or seen edge-on)",
}
# ends straight above the slot, where the hold is looked at (a regrasp's own is prefixed)
HOLD_CHECK_SEGMENT = "transfer"
REGRASP_PREFIX = "regrasp_"  # the planner's turn in place before the pick proper
NEEDED_SERVICES = (
    "/sim/reset",
    "/perception/detect",
    "/perception/check_placement",
    "/plan_place",
    "/plan_strike",
)


@dataclass(frozen=True)
class ArmJobSettings:
    pile: int = 30  # dominoes poured
    seed: int = 0
    max_attempts: int = 4  # per domino: perceive, plan, carry and place
    # ... and picks that failed before anything was carried (missed, blocked): they leave
    # the run as it was and stir the pile. S-curve seed 3 stopped after 4 misses in a row
    # at its last gap with 16 dominoes still detected in the pile.
    max_missed_picks: int = 8
    # Per attempt, dominoes offered to the planner with their pile until one plans, then
    # the roomiest with their pile's cores (the pads may reach into a neighbour's box but
    # not its core; the gripper body keeps clear of the box), then ignoring the pile
    # (unless the slot can be put off instead).
    # Ignoring it, 6 of 12 picks failed (f611c37); replayed, each of the 6 had the pads'
    # path 3.3-7.7 mm deep in a detected neighbour, the 6 that held at most 2.9 mm.
    max_candidates: int = 16
    last_resort_candidates: int = 3
    # m per side a neighbour's core is smaller than its box: the planner keeps the pads'
    # path 1.5 mm (pile_point_clearance) from the core, so ~3 mm deep in the box at most.
    pile_core_shrink: float = 0.0045
    # ... and when nothing plans with the cores either, a pile domino is pushed out of its
    # crowd (``spread``) and the pile looked at again, at most max_spreads times a slot,
    # before the pile is ignored: the shortest push after which nothing seen lies within
    # spread_clearance of its long sides (perception's scoring caps its clearance at
    # 15 mm), its centre within spread_radius of the pile's centre (the cameras see 0.16 m
    # around it); the roomiest first, asking the planner at most spread_plans times; when
    # none of those plans (the pile is jammed), a push through the neighbours
    # (``spread.stir_pushes``), as many times at most.
    max_spreads: int = 2
    spread_clearance: float = 0.016  # m
    spread_radius: float = 0.13  # m
    spread_plans: int = 6
    pile_center: tuple[float, float] = (0.55, -0.30)  # m, the scenario's pile_area
    section: int = 4  # dominoes between safety gaps, which are filled last (0: run order)
    plan_budget: float = 5.0  # s of planning per request
    settle_after_place: float = 0.5  # s simulated before checking a placement
    topple_wait: float = 3.0  # s simulated after the strike
    place_tolerance: float = 0.003  # m, perception's check
    place_tilt_tolerance: float = math.radians(3.0)
    # An upright domino up to this far off its target stays where it stands (it still
    # topples the next; spacing is ~60 % of its height): lifting it out of the run again is
    # where cascades started (a re-pick 4.4 mm off knocked four standing ones). 0: re-pick.
    keep_off_target: float = 0.006  # m
    # ... and up to this far off once picking it up again failed: it blocks its own slot
    # (S-curve seed 4: one stood 8.9 mm off, both re-picks missed, and every place for its
    # slot was refused for ever). 12 mm off, the next still stands within the toppling range.
    keep_when_stuck: float = 0.012  # m
    # Released dominoes end up behind the pose they were released at, along the run: by
    # 0.75 mm on average in truth (sd 0.6-1.0 mm; 170 placements, arc and S-curve alike):
    # ~0.45 mm from the grasp, the rest as the pads let go. The arm releases them this much
    # ahead (the check still measures from the target).
    place_lead: float = 0.00075  # m
    # Straight above its slot, before the descent, perception looks at the held domino:
    # one whose foot is this far from where it should be held there, or that leans this
    # much, turned or slid in the hand on the way (the off placements seen with sim_node's
    # motion log did: 2.1 mm / 5.4° in the hand, 3.4 mm off once let go) and is carried
    # again from there, once. (Looked at on its slot, a correction carried it out from
    # between its standing neighbours: twice it left the fingers and knocked them over.)
    # 0: no check (it costs a camera frame and the fits, ~1 s simulated per domino).
    # With nothing wrong the foot reads ~1 mm off (rendered holds; median 1.35 mm over the
    # benchmark's readings), the tilt within 0.2°.
    in_hand_tolerance: float = 0.002  # m
    in_hand_tilt_tolerance: float = math.radians(1.5)
    # However far it turned: placed as held, a domino leaning more than ~9° (its thickness
    # over its height) cannot stand. The two holds read 12.1° and 12.2° off in the
    # benchmark of 4e6913a were placed as held (the bound was 12°) and fell, one at a
    # safety gap taking four standing neighbours with it; a correction from above the slot
    # placed one read 10.8° off 0.8 mm from its target (7500eb1).
    # A foot read farther off than this is taken as a misreading: pinched at its top and
    # turned 12°, the foot moves ~7 mm (35 mm of lever), plus what the hold slides
    # (≤ 5.4 mm read in the benchmarks). One read 13.1 mm off at 1.5°
    # in a stale frame (now refused: not_before), whose hold the simulator had shifting
    # 1.1 mm / 1.2°, was "corrected" 12.9 mm off; at 6 mm (e81930d) a real 6.2 mm / 3.9°
    # shift was refused and the domino stood 7.1 mm off.
    in_hand_max_off: float = 0.012  # m
    # A hold leaning more than this whose correction the planner refused is not placed
    # (it would fall, at a safety gap onto standing neighbours: S-curve seed 3 of f457642's
    # validation, 12.3°) but carried back over the pile and dropped there: the ~8.9° at
    # which a domino's weight leaves its foot (thickness over height). Not less: carried
    # back, a loose hold read 8.3° slipped out over the run and felled four (ec6d172).
    put_back_lean: float = math.atan2(DOMINO_SIZE[2], DOMINO_SIZE[0])
    grasp_width_tolerance: float = 0.003  # m: fingers stopped this close to the domino width
    # ... but not this much inside it: a flat hold stops 0.2-0.8 mm inside (the pads' give
    # at grip_force); 0.9 mm and more inside, the pads met an edge and the domino hangs
    # tilted (both such grasps seen fell when released; rejected, the domino drops back).
    grasp_squeeze_limit: float = 0.00085  # m
    # An approach that ends this close to its grasp pose (rad per joint; the simulator's
    # default is 0.01) closes the gripper and lets the grasp check judge: the gripper body
    # resting 0.1 mm deep on a pile domino stopped joint 6 0.012 rad (~1.5 mm) short.
    approach_goal_tolerance: float = 0.02  # rad
    # Fallen dominoes no grasp reaches, lying within a domino length of the slot to build
    # (debris of a cascade, wedged between standing neighbours), are pushed across the
    # run until they lie this far beyond its side; at most max_sweeps per slot.
    sweep_margin: float = 0.008  # m
    max_sweeps: int = 2
    real_time_factor: float = 1.0
    camera_rate: float = 2.0
    meshcat: bool = False  # show the cell in Meshcat; keep it up at the end until Enter
    # --record: every topic into OUT/run.mcap (raw images thinned to this rate, Hz) and
    # Meshcat's recording into OUT/scene.html
    record: bool = False
    record_image_rate: float = 1.0
    foxglove_port: int | None = None  # serve the topics live to Foxglove here
    # a folder for each executed pick's record: what was offered and planned, and the
    # simulator's truth then (benchmarks/replay_pick.py replays it); None: not recorded
    record_picks: Path | None = None


@dataclass
class Candidate:
    """Something to pick: a pile detection or a fallen run domino, with what lies near it."""

    pose: Pose
    run_index: int | None = None  # layout index of a fallen run domino; None: the pile
    neighbours: list[Pose] = field(default_factory=list)
    posture: int | None = None  # perception's DominoDetection posture; None: fallen run domino
    scored: bool = True  # perception found room for the fingers
    clearance: float = math.inf  # m beside the finger contact sides, as perception measured
    # Perception's grasp, clear of every point the cameras saw (undetected dominoes too);
    # None for a fallen run domino: the planner chooses.
    grasp: Pose | None = None
    # seen points near it on no detected domino: the planner keeps the pads' path clear
    points: list[Point] = field(default_factory=list)

    def spot(self) -> np.ndarray:
        return spot_of(self.pose)

    @property
    def leaning(self) -> bool:
        return self.posture == DominoDetection.POSTURE_TILTED

    @property
    def posture_name(self) -> str:
        return "fallen" if self.posture is None else POSTURE_NAMES[self.posture]

    @property
    def source(self) -> str:
        return "pile" if self.run_index is None else f"run domino {self.run_index + 1}"


@dataclass
class BuildState:
    standing: dict[int, Pose] = field(default_factory=dict)  # layout index → target pose
    fallen: dict[int, Pose] = field(default_factory=dict)  # layout index → measured pose
    # (x, y) of dominoes no grasp reaches or whose pick failed: not offered again
    unpickable: list[np.ndarray] = field(default_factory=list)
    stuck: set[int] = field(default_factory=set)  # run dominoes whose pick-up again failed
    crowded: list[np.ndarray] = field(default_factory=list)  # (x, y) refused with its pile


def placement_pose(placement: DominoPlacement, lead: float = 0.0) -> Pose:
    """The domino's target pose, moved ``lead`` metres ahead along the run."""
    w, x, y, z = placement.quaternion_wxyz()
    ahead = lead * np.array([math.cos(placement.heading), math.sin(placement.heading)])
    return Pose(
        position=Point(x=placement.x + ahead[0], y=placement.y + ahead[1], z=placement.z),
        orientation=Quaternion(x=x, y=y, z=z, w=w),
    )


def log(message: str) -> None:
    print(f"[bringup] {message}", flush=True)


class ArmJob:
    """One run: the task loop over a connected ``CellClient``."""

    def __init__(
        self,
        client: CellClient,
        layout: Sequence[DominoPlacement],
        name: str,
        settings: ArmJobSettings,
    ) -> None:
        self.client = client
        self.layout = list(layout)
        self.targets = [placement_pose(p) for p in self.layout]
        self.releases = [placement_pose(p, settings.place_lead) for p in self.layout]
        self.settings = settings
        self.state = BuildState()
        self.report = RunReport(
            layout=name,
            dominoes=[DominoOutcome(p.index, target_of(p)) for p in self.layout],
            pile=settings.pile,
            seed=settings.seed,
        )
        self.picks_recorded = 0  # files in settings.record_picks
        # Simulated time since which nothing has moved (the arm at rest after a placement
        # check): the pile cameras' frames from then on are fresh for the next look too.
        self.still_since: float | None = None
        self.pictures: dict[str, np.ndarray] = {}  # REPORT_CAMERA's frames, for the report

    # ------------------------------------------------------------------ the run
    def run(self) -> RunReport:
        started_wall, settings = time.monotonic(), self.settings
        reset = self.client.reset(settings.pile, settings.seed)
        log(reset.message)
        started_sim = self.client.sim_time
        gaps = safety_gaps(self.layout, settings.section)
        queue = [i for i in range(len(self.layout)) if i not in gaps] + gaps
        if gaps:
            numbers = ", ".join(str(i + 1) for i in gaps)
            log(f"safety gaps at dominoes {numbers}: built once the rest stands")
        deferred: set[int] = set()  # slots put off since the last placement
        while queue:
            index = queue.pop(0)
            if index in self.state.standing:
                continue  # kept standing where it was (see _keep_if_standing)
            # Only slots still to build count: a standing one left behind in the queue kept
            # two slots nothing planned for putting each other off for ever (S-curve seed 2).
            settled = deferred | set(self.state.standing)  # no turn to wait for
            may_defer = any(i not in settled for i in queue)
            result = self._place_with_retries(index, may_defer)
            if result == DEFERRED:
                deferred.add(index)
                # before the safety gaps (filled last), but after at least one other slot
                # that was not put off (its turn may free this one): behind only gaps it
                # came straight back (S-curve 4); behind a slot put off too, the two took
                # turns for ever while a gap behind them never had one (S-curve 3)
                open_slots = (k for k, i in enumerate(queue) if i not in settled)
                first_open = next(open_slots, len(queue) - 1)
                first_gap = next((k for k, i in enumerate(queue) if i in gaps), len(queue))
                queue.insert(max(first_gap, first_open + 1), index)
                continue
            if result == FAILED:  # given up: left empty, the run is built around it
                outcome = self.report.dominoes[index]
                reason = empty_reason(outcome.failures, outcome.deferrals, outcome.refusals)
                self.report.empty_slots.append(EmptySlot(index + 1, reason))
                log(empty_message(index, reason))
            else:
                deferred.clear()
            # Slots built earlier that no longer stand (knocked over, or their fallen domino
            # was picked up for another slot) are built again first; given-up ones are not.
            given_up = {e.slot - 1 for e in self.report.empty_slots}
            empty = [i for i in range(len(self.layout)) if i not in self.state.standing]
            queue = [i for i in empty if i not in queue and i not in given_up] + queue
        self.report.built = len(self.state.standing) == len(self.layout)
        if self.report.empty_slots:
            self.report.message = "; ".join(
                empty_message(e.slot - 1, e.reason) for e in self.report.empty_slots
            )
        self._record_truth(before_strike=True)
        self._take_picture("before_strike", self.client.sim_time)
        if self.state.standing:
            self._strike()
        self._record_truth(before_strike=False)
        self.report.simulated_s = self.client.sim_time - started_sim
        self.report.wall_s = time.monotonic() - started_wall
        return self.report

    def _place_with_retries(self, index: int, may_defer: bool) -> str:
        """PLACED; FAILED after max_attempts carries or max_missed_picks picks that failed;
        or DEFERRED: no offer planned (e.g. fallen dominoes lie where it stands) and other
        slots may be built first, which may use up those fallen dominoes. A deferral costs
        planning calls, not an attempt."""
        outcome = self.report.dominoes[index]
        failed: list[np.ndarray] = []
        missed = 0  # picks that failed (the attempt returned where)
        sweeps = 0
        sim_start, wall_start = self.client.sim_time, time.monotonic()
        activities = self.client.simulated_by_activity
        spent = dict(activities)
        settings = self.settings
        while (
            outcome.attempts - missed < settings.max_attempts and missed < settings.max_missed_picks
        ):
            try:
                success, why, spot, moved = self._attempt(index, failed, not may_defer)
            except CallFailedError as error:
                success, why, spot, moved = False, str(error), None, True
            outcome.simulated_s += self.client.sim_time - sim_start
            outcome.wall_s += time.monotonic() - wall_start
            sim_start, wall_start = self.client.sim_time, time.monotonic()
            spent = add_spent(outcome.simulated_by_activity, activities, spent)
            if not moved and sweeps < settings.max_sweeps and self._sweep_debris(index, failed):
                sweeps += 1
                failed.clear()  # refused while the debris lay there (missed picks: unpickable)
                continue
            if not moved and may_defer:
                outcome.deferrals.append(why)
                log(f"domino {index + 1}/{len(self.layout)} put off ({why}): others first")
                return DEFERRED
            outcome.attempts += 1
            if success:
                outcome.placed = True
                kept = " (off target, left standing: it still topples the next)"
                log(
                    f"domino {index + 1}/{len(self.layout)} placed (attempt {outcome.attempts}): "
                    f"{outcome.check}{kept if outcome.off_target else ''}; "
                    f"{outcome.simulated_s:.1f} s simulated, {outcome.wall_s:.1f} s wall"
                )
                return PLACED
            outcome.failures.append(why)
            if spot is not None:
                failed.append(spot)
                missed += 1
            log(f"domino {index + 1}/{len(self.layout)} attempt {outcome.attempts} failed: {why}")
        return FAILED

    # ------------------------------------------------------------------ one attempt
    def _attempt(
        self, index: int, failed: list[np.ndarray], ignore_pile: bool = False, turned: bool = False
    ) -> tuple[bool, str, np.ndarray | None, bool]:
        """Offer the planner candidates until one plans; execute and check it.

        First with their pile neighbours as obstacles (the planner keeps the pads clear of
        them, or lets them nudge one a few millimetres), in ``offers.with_pile_first``'s
        order; when every one is refused, the roomiest with their pile's cores (the pads
        may push a neighbour up to pile_core_shrink, the gripper body keeps clear); then,
        unless a refusal was about the slot and not ``ignore_pile`` (other slots may be
        built first; refusals about the dominoes would recur at every slot), a pile domino
        is pushed out of its crowd (``_spread``) and the attempt starts again from a fresh
        look (up to max_spreads a slot); only then the roomiest ignoring the pile (a miss
        is caught by the grasp check and backed out of, and stirs the pile). A refusal
        costs a planning call, not an attempt: the arm has not moved (the last of the
        returned success, why, spot, moved says whether it did). Refusals and failed picks
        are remembered for the run (refused with the pile: not offered with it again;
        refused ignoring it, or the pick blocked or missed: not offered at all), until a
        pick within DISTURBED_RADIUS moves it.

        A pile domino the planner turns in place first (no grasp reached it as it lay) is
        turned, then looked at again and the attempt goes on from there (once: ``turned``):
        picked blind where the plan expected it to settle, 3 of 7 such picks missed
        (f611c37 and the first runs of 7500eb1).
        """
        candidates = self._candidates(failed)
        crowded, settings = self.state.crowded, self.settings
        ranked = [c for c in with_pile_first(candidates) if not near_any(c.spot(), crowded)]
        roomiest = roomiest_first(candidates)[: settings.last_resort_candidates]
        slot_refusals: list[np.ndarray] = []
        with_pile = [
            *((c, PILE_BOXES) for c in ranked[: settings.max_candidates]),
            *((c, PILE_CORES) for c in roomiest),
        ]
        found, refused = self._first_plan(index, with_pile, failed, slot_refusals)
        if found is None and (ignore_pile or not slot_refusals):
            spreads = self.report.dominoes[index].spreads
            if len(spreads) < settings.max_spreads and self._spread(index, candidates):
                return self._attempt(index, failed, ignore_pile, turned)
            ignoring = [(c, PILE_IGNORED) for c in roomiest]
            found, more = self._first_plan(index, ignoring, failed, slot_refusals)
            refused += more
        if found is None:
            if refused:
                return False, f"planning: {refused} offers refused", None, False
            return False, "no graspable domino seen", None, False
        return self._pick(index, *found, failed, ignore_pile, turned)

    def _pick(
        self,
        index: int,
        candidate: Candidate,
        pile: str,
        plan: PlanPlace.Response,
        failed: list[np.ndarray],
        ignore_pile: bool,
        turned: bool,
    ) -> tuple[bool, str, np.ndarray | None, bool]:
        """Execute ``plan`` (``candidate`` picked with its ``pile`` tier) and check the
        placement; as ``_attempt`` returns."""
        spot = candidate.spot()
        log(
            f"domino {index + 1}/{len(self.layout)}: picking {candidate.source} "
            f"({candidate.posture_name}) at {spot.round(3).tolist()}, "
            f"{plan.message}{PILE_WORDS[pile]}"
        )
        self._forget_refusals_near(spot)  # the pick disturbs its neighbours
        truth = self._truth()
        truth_name, seen_off = nearest_truth(truth, candidate.pose)
        self.report.dominoes[index].pick_seen_off_mm.append(seen_off)
        record = self._pick_record(index, candidate, pile, plan, truth)
        turn = [s for s in plan.segments if s.label.startswith(REGRASP_PREFIX)]
        look_again = bool(turn) and candidate.run_index is None and not turned
        segments = turn if look_again else plan.segments
        executed, why = self._execute(segments, (index, plan.held_above_place, candidate.pose))
        self._write_pick_record(record, why or ("turned in place only" if look_again else ""))
        if candidate.run_index is not None and (executed or why.startswith(PUT_BACK)):
            self.state.fallen.pop(candidate.run_index, None)  # carried away
        if why.startswith(PUT_BACK):  # an attempt (the arm moved), not a pick that failed
            return False, why, None, True
        if not executed:  # blocked or missed: unless it moved, the same would happen again
            if seen_off is not None:  # the name finds it in sim_node's "during the" lines
                log(f"(truth, report only: {truth_name} lay {seen_off:.1f} mm from where seen)")
            # A run domino stays where it was: an obstacle for every later carry (a new
            # domino was once built into one that still stood there).
            self.state.unpickable.append(spot)
            if candidate.run_index is not None:
                return self._keep_if_standing(index, candidate.run_index, why, spot)
            return False, why, spot, True
        if look_again:
            log(f"domino {index + 1}/{len(self.layout)}: turned it in place; looking again")
            return self._attempt(index, failed, ignore_pile, turned=True)
        return self._check(index), self.report.dominoes[index].check, None, True

    def _first_plan(
        self,
        index: int,
        offers: Sequence[tuple[Candidate, str]],
        failed: list[np.ndarray],
        slot_refusals: list[np.ndarray],
    ) -> tuple[tuple[Candidate, str, PlanPlace.Response] | None, int]:
        """The first of ``offers`` (candidate, pile tier) that plans for slot ``index``
        and how many were refused before it. Refusals about the slot go to ``failed`` and
        ``slot_refusals``; those about the domino are remembered for the run (see
        ``_attempt``)."""
        refused = 0
        for candidate, pile in offers:
            spot = candidate.spot()
            if near_any(spot, failed):
                continue  # refused for this slot already
            plan = self._plan(index, candidate, pile)
            if plan.success:
                return (candidate, pile, plan), refused
            refused += 1
            self._log_refusal(index, candidate, pile, plan.message)
            count_refusal(self.report.dominoes[index].refusals, plan.error_code)
            if plan.error_code not in GRASP_REFUSALS:
                failed.append(spot)
                slot_refusals.append(spot)
            elif pile == PILE_BOXES:
                self.state.crowded.append(spot)
            elif pile == PILE_IGNORED:
                self.state.unpickable.append(spot)
        return None, refused

    def _sweep_debris(self, index: int, failed: list[np.ndarray]) -> bool:
        """Push aside the nearest fallen domino within a domino length of slot ``index`` that
        no grasp reached (refused, or its pick failed); True once one was pushed (or the
        push failed after the arm moved)."""
        place, avoid = spot_of(self.releases[index]), failed + self.state.unpickable
        debris = sorted(
            (float(np.linalg.norm(spot_of(pose) - place)), k)
            for k, pose in self.state.fallen.items()
            if near(spot_of(pose), place, DOMINO_LENGTH) and near_any(spot_of(pose), avoid)
        )
        for _, k in debris:
            pose = self.state.fallen[k]
            others = [p for i, p in self.state.fallen.items() if i != k]
            margin = self.settings.sweep_margin
            for direction, distance in sweep_pushes(pose_matrix(pose), self.layout[index], margin):
                what = f"domino {k + 1} lying at {spot_of(pose).round(3).tolist()}"
                swept = self._sweep(pose, others, direction, distance, what, "across the run")
                if swept is None:
                    continue
                self.report.dominoes[index].sweeps.append(swept)
                log(f"domino {index + 1}/{len(self.layout)}: {swept}")
                self.state.fallen.pop(k)
                self._check(k, just_placed=False)  # still there (fallen again) or gone
                return True
        return False

    def _spread(self, index: int, candidates: Sequence[Candidate]) -> bool:
        """Push one of the pile ``candidates`` (none of which planned; roomiest first) out of
        its crowd (``spread.spread_pushes``, the planner keeping it clear of its
        neighbours), or when no such push plans, through them (``spread.stir_pushes``: the
        pile is jammed), asking the planner at most spread_plans times for each; True once
        the arm moved."""
        settings, asked = self.settings, [0, 0]
        pile = roomiest_first([c for c in candidates if c.run_index is None])
        for jammed in (False, True):
            for candidate in pile:
                if asked[jammed] == settings.spread_plans:
                    break
                pushes, obstacles, how = self._pushes(candidate, jammed)
                what = f"pile domino at {candidate.spot().round(3).tolist()}"
                for direction, distance in pushes[:SPREAD_TRIES]:
                    if asked[jammed] == settings.spread_plans:
                        break
                    asked[jammed] += 1
                    spread = self._sweep(candidate.pose, obstacles, direction, distance, what, how)
                    if spread is not None:
                        self.report.dominoes[index].spreads.append(spread)
                        log(f"domino {index + 1}/{len(self.layout)}: spreading the pile: {spread}")
                        return True
        if not any(asked):
            log(f"domino {index + 1}/{len(self.layout)}: no push would spread the pile")
        return False

    def _pushes(
        self, candidate: Candidate, jammed: bool
    ) -> tuple[list[tuple[np.ndarray, float]], list[Pose], str]:
        """The pushes of pile ``candidate`` to ask for (out of its crowd, or ``jammed``:
        through it), what the planner keeps it clear of, and how the log says it went."""
        settings = self.settings
        seen = [pose_matrix(p) for p in (*candidate.neighbours, *self.state.standing.values())]
        points = np.array([(p.x, p.y, p.z) for p in candidate.points])
        target, centre = pose_matrix(candidate.pose), np.asarray(settings.pile_center)
        fallen = list(self.state.fallen.values())
        if jammed:  # the neighbours are pushed along: only the run is an obstacle
            pushes = stir_pushes(target, seen, points, centre, settings.spread_radius)
            return pushes, fallen, "through its neighbours"
        pushes = spread_pushes(
            target, seen, points, centre, settings.spread_radius, settings.spread_clearance
        )
        return pushes, [*candidate.neighbours, *fallen], ""

    def _sweep(
        self,
        pose: Pose,
        others: Sequence[Pose],
        direction: np.ndarray,
        distance: float,
        what: str,
        where: str = "",
    ) -> str | None:
        """Push the domino at ``pose`` ``distance`` along ``direction`` (/plan_strike's
        sweep), keeping clear of ``others`` and the standing run: what was done, or None
        if the planner refused (the arm has not moved)."""
        plan = self.client.plan_strike(
            PlanStrike.Request(
                domino_pose=pose,
                standing_dominoes=[*self.state.standing.values(), *others],
                sweep_direction=Vector3(x=direction[0], y=direction[1], z=0.0),
                push_distance=distance,
                time_budget=self.settings.plan_budget,
            ),
            timeout=self.settings.plan_budget + 30.0,
        )
        if not plan.success:
            log(f"sweeping {what} refused: {plan.message.split(' (')[0]}")
            return None
        executed, why = self._execute(plan.segments, holds_domino=False)
        self._forget_refusals_near(spot_of(pose))
        self._forget_refusals_near(spot_of(pose) + distance * np.asarray(direction)[:2])
        swept = f"{what}: swept {distance * 1e3:.0f} mm {where}".rstrip()
        return swept + ("" if executed else f", stopped ({why})")

    def _keep_if_standing(
        self, index: int, run_index: int, why: str, spot: np.ndarray
    ) -> tuple[bool, str, np.ndarray | None, bool]:
        """After a failed pick of run domino ``run_index``: if it still stands upright within
        keep_when_stuck of its target, it stays as that slot's domino (when that is the slot
        being built, the attempt succeeded); otherwise the attempt failed with ``why``."""
        self.state.stuck.add(run_index)
        if not self._check(run_index):
            return False, why, spot, True
        self.state.fallen.pop(run_index, None)
        outcome = self.report.dominoes[run_index]
        outcome.placed = True
        if run_index == index:
            return True, outcome.check, None, True
        log(f"domino {run_index + 1} kept standing where it is ({outcome.check})")
        return False, why, spot, True

    def _log_refusal(self, index: int, candidate: Candidate, pile: str, why: str) -> None:
        """One short line per refusal: the planner's reason up to its details."""
        where = f"{candidate.source} at {candidate.spot().round(3).tolist()}{PILE_WORDS[pile]}"
        log(f"domino {index + 1}/{len(self.layout)}: refused {where}: {why.split(' (')[0]}")

    def _plan(self, index: int, candidate: Candidate, pile: str) -> PlanPlace.Response:
        with_pile = pile != PILE_IGNORED
        return self.client.plan_place(
            PlanPlace.Request(
                domino_pose=candidate.pose,
                # tried first, then the planner's own (regrasp included): the planner knows
                # only the detected pile, and grasps missed as the fingers closed on dominoes
                # perception had within 1.2 mm of the truth
                grasp_pose=candidate.grasp or Pose(),
                pile_dominoes=candidate.neighbours if with_pile else [],
                # with the cores, only the gripper body and arm keep clear of the boxes: in
                # 2 of 3 such picks that missed (4e6913a), the body was 6-9 mm inside one
                pads_into_pile=pile == PILE_CORES,
                # unlike the pile's boxes, kept in the last resort too: it missed 8 of 11
                # (58ee708), and a domino never detected is nothing the pads may push
                pile_points=self._pile_points(candidate, pile),
                grasp_width=0.0,
                place_pose=self.releases[index],
                standing_dominoes=[
                    *self.state.standing.values(),
                    *self._debris(candidate, with_pile, spot_of(self.releases[index])),
                ],
                time_budget=self.settings.plan_budget,
            ),
            timeout=self.settings.plan_budget + 30.0,
        )

    def _pile_points(self, candidate: Candidate, pile: str) -> list[Point]:
        """The points the planner keeps the pads' path from: those seen on no detected
        domino, and with PILE_CORES the cores of the pile neighbours (``offers.pile_cores``)."""
        if pile != PILE_CORES:
            return candidate.points
        neighbours = [pose_matrix(p) for p in candidate.neighbours]
        cores = pile_cores(candidate.spot(), neighbours, self.settings.pile_core_shrink)
        return [*candidate.points, *(Point(x=x, y=y, z=z) for x, y, z in cores.tolist())]

    def _debris(
        self, candidate: Candidate, with_pile: bool = True, place: np.ndarray | None = None
    ) -> list[Pose]:
        """Fallen run dominoes lying in the build area (not the one to pick): the carry and
        the placement must keep clear of them as of the standing ones (a placement that met
        one fell). Its pile neighbours go to the planner as its pile instead; ignoring its
        pile, those within a domino length of the ``place`` stay obstacles: a run domino
        picked so was placed onto the fallen ones beside it, and fell (S-curve seed 2)."""
        pile = [
            pose
            for pose in candidate.neighbours
            if with_pile or place is None or not near(spot_of(pose), place, DOMINO_LENGTH)
        ]
        return [
            pose
            for pose in self.state.fallen.values()
            if pose is not candidate.pose and not any(pose is p for p in pile)
        ]

    def _candidates(self, failed: list[np.ndarray]) -> list[Candidate]:
        """Fallen run dominoes first (they block the run), then the pile's detections in
        perception's order (best grasp first); none where an attempt failed or no grasp
        reaches."""
        avoid = failed + self.state.unpickable
        fallen = [
            Candidate(pose, index, neighbours_of(pose, self.state.fallen.values()))
            for index, pose in sorted(self.state.fallen.items())
            if not near_any(spot_of(pose), avoid)
        ]
        detections, unexplained = self._detect()
        return fallen + [
            Candidate(
                detection.pose,
                None,
                neighbours_of(detection.pose, [d.pose for d in detections]),
                posture=detection.posture,
                scored=detection.score > 0.0,
                clearance=detection.clearance,
                grasp=detection.grasp_pose,
                points=points_near(detection.pose, unexplained),
            )
            for detection in detections
            if detection.posture in PICKABLE_POSTURES
            and not near_any(spot_of(detection.pose), avoid)
        ]

    def _detect(self) -> tuple[list[DominoDetection], list[Point]]:
        """Perception's detections in fresh frames, and the points seen on none of them.
        A failure or an empty pile (e.g. the cameras' first frames after the reset not yet
        through) is asked again a camera period on (a run whose first looks came at once
        after the reset found no frames for four attempts); an empty answer after that is
        taken as the pile's end. Nothing moved since the last placement check: its frames serve
        (no frame to wait for)."""
        period = 1.0 / self.settings.camera_rate
        for attempt in range(DETECT_TRIES):
            if attempt:  # a camera period on: frames asked for at once may not be out yet
                not_before = self._settle(period)
            else:
                not_before = self._settle() if self.still_since is None else self.still_since
            answer = self.client.detect(not_before)
            if answer.success and answer.detections.detections:
                return list(answer.detections.detections), list(answer.unexplained_points)
            log(f"perception: {answer.message}; asking again")
        if answer.success:
            return [], []
        raise CallFailedError(f"perception: {answer.message}")

    def _forget_refusals_near(self, spot: np.ndarray) -> None:
        state = self.state
        state.unpickable = [u for u in state.unpickable if not near(u, spot, DISTURBED_RADIUS)]
        state.crowded = [u for u in state.crowded if not near(u, spot, DISTURBED_RADIUS)]

    def _execute(
        self,
        segments: Sequence[TrajectorySegment],
        slot: tuple[int, Pose, Pose] | None = None,
        holds_domino: bool = True,
    ) -> tuple[bool, str]:
        """Run the segments and their gripper events.

        A close that should hold a domino is checked by where the fingers stopped (the
        strike closes them on nothing). When a grasp fails, the arm backs out the way it
        came before anything else is tried. ``slot``: the index of the slot the domino
        goes to, where it should be held when "transfer" ends above it, and where it was
        picked; it is looked at in the hand there (``_carried_again``).
        """
        self.still_since = None
        for segment in segments:
            points = segment.trajectory.points
            if points:
                # Wall-clock timeouts are generous: the simulator may run well below real time.
                approach = is_approach(segment)
                tolerance = self.settings.approach_goal_tolerance if approach else 0.0
                result = self.client.execute(
                    segment.trajectory, seconds(points[-1]) * 60 + 120, tolerance
                )
                if result.error_code != 0:
                    if approach:
                        self._back_out(segment)
                    return False, f"{segment.label}: {result.error_string}"
            if segment.gripper_after == TrajectorySegment.GRIPPER_CLOSE:
                closed = self.client.gripper(segment.gripper_position, segment.gripper_max_effort)
                problem = self._grasp_problem(closed.position)
                if holds_domino and problem:
                    self._back_out(segment)
                    return False, (
                        f"{segment.label}: grasp {problem} (fingers stopped at "
                        f"{closed.position * 1e3:.1f} mm, domino {DOMINO_SIZE[1] * 1e3:.0f} mm)"
                    )
            elif segment.gripper_after == TrajectorySegment.GRIPPER_OPEN:
                self.client.gripper(segment.gripper_position, 0.0)
            if slot is not None and segment.label == HOLD_CHECK_SEGMENT:
                again = self._carried_again(*slot)
                if isinstance(again, str):
                    self._put_back(segment)
                    return False, again
                if again is not None:
                    return self._execute(again)
        return True, ""

    def _carried_again(
        self, index: int, held_above: Pose, picked: Pose
    ) -> list[TrajectorySegment] | str | None:
        """The held domino straight above slot ``index`` (planned to be held at
        ``held_above``), seen by perception: when it turned or slid in the hand on the way
        (``in_hand_tolerance``), a plan from where it is held to its release pose (down
        onto it from above, the fingers open there, then the retreat). None: placed as
        planned (within the tolerance, read beyond ``in_hand_max_off``, not seen well, or
        no plan for a hold that may still stand). A string (why, starting with PUT_BACK):
        no plan, and leaning over ``put_back_lean`` it would fall: not to be placed."""
        settings = self.settings
        if settings.in_hand_tolerance <= 0.0:
            return None
        fresh = self._settle()
        release, n = self.releases[index], len(self.layout)
        answer = self.client.check_placement([held_above], in_hand=True, not_before=fresh)
        if not (answer.success and answer.status[0] == CheckPlacement.Response.STANDING):
            status = IN_HAND_WORDS.get(answer.status[0], "?") if answer.success else answer.message
            log(f"domino {index + 1}/{n} in the hand: {status}; placing it")
            return None
        measured, tilt = answer.measured[0], answer.tilt[0]
        off = foot_distance(measured, held_above)
        seen = f"foot {off * 1e3:.1f} mm off, leaning {math.degrees(tilt):.1f}°"
        if off <= settings.in_hand_tolerance and tilt <= settings.in_hand_tilt_tolerance:
            log(f"domino {index + 1}/{n} in the hand: {seen}; placing it")
            return None
        if off > settings.in_hand_max_off:
            log(
                f"domino {index + 1}/{n} in the hand: {seen}; too far off: a misreading, placing it"
            )
            return None
        self.report.dominoes[index].corrected_in_hand.append(seen)
        plan = self.client.plan_place(
            PlanPlace.Request(
                domino_pose=measured,
                place_pose=release,
                # a fallen run domino being carried is no obstacle where it lay (S-curve
                # seed 5 of ec6d172: its own pose "overlapped" its slot, every correction
                # was refused, and the build stopped at that slot)
                standing_dominoes=[
                    *self.state.standing.values(),
                    *(pose for pose in self.state.fallen.values() if pose is not picked),
                ],
                time_budget=self.settings.plan_budget,
                holding=True,
            ),
            timeout=self.settings.plan_budget + 30.0,
        )
        if not plan.success:
            refused = f"carrying it again refused ({plan.message.split(' (')[0]})"
            if tilt > settings.put_back_lean:
                self.report.dominoes[index].put_back.append(seen)
                log(f"domino {index + 1}/{n} in the hand: {seen}; {refused}; it would fall")
                return f"{PUT_BACK}: held {seen}, {refused}"
            log(f"domino {index + 1}/{n} in the hand: {seen}; {refused}; placing it as it is")
            return None
        log(f"domino {index + 1}/{n} in the hand: {seen}; carrying it again from where it is held")
        return list(plan.segments)

    def _put_back(self, transfer: TrajectorySegment) -> None:
        """Carry the held domino back along ``transfer`` to above where it was picked
        (the way it came, with this hold), let it drop onto the pile from there, and go
        back along ``transfer``: out of the cameras' view of the pile before the next
        look, where the next plan starts as after a placement."""
        log(f"{PUT_BACK}: carrying it back to where it was picked and letting it drop")
        self._move(reversed_trajectory(transfer.trajectory, BACK_OUT_LEAD), "putting it back")
        self.client.gripper(LET_GO_OPENING, 0.0)
        self._move(transfer.trajectory, "leaving the pile")

    def _grasp_problem(self, opening: float) -> str:
        """What the finger opening after a close says is wrong with the grasp, or ""."""
        inside = DOMINO_SIZE[1] - opening
        if abs(inside) > self.settings.grasp_width_tolerance:
            return "missed"
        if inside > self.settings.grasp_squeeze_limit:
            return "on an edge"
        return ""

    def _back_out(self, segment: TrajectorySegment) -> None:
        """After a failed grasp: open, and retrace the approach to where it started.

        The way in was collision-free, so the way back is too, and it takes the arm out
        of the cameras' view of the pile before perception looks again.
        """
        self.client.gripper(segment.gripper_position + LET_GO_OPENING, 0.0)
        if segment.trajectory.points:
            self._move(reversed_trajectory(segment.trajectory, BACK_OUT_LEAD), "backing out")

    def _move(self, trajectory: JointTrajectory, what: str) -> None:
        """Run ``trajectory`` off plan (a way back); a failure is logged, not raised: the
        next plan starts from wherever the arm stopped."""
        result = self.client.execute(trajectory, 60.0 * seconds(trajectory.points[-1]) + 120)
        if result.error_code != 0:
            log(f"{what} failed: {result.error_string}")

    # ------------------------------------------------------------------ checks
    def _settle(self, settle: float = 0.0) -> float:
        """The simulated time from which on camera frames show the scene as it is
        ``settle`` seconds from now (waited for here), for perception's ``not_before``:
        perception waits for the first frame stamped then or later (on a loaded CPU the
        images arrive after the joint states: a frame from before a placement once had
        perception call the domino standing there MISSING, and the next carry swept
        through it). Waiting here a camera period more cost ~0.3 s simulated a look."""
        fresh = self.client.sim_time + settle
        if settle > 0.0:
            self.client.wait_for_sim_time(settle)
        return fresh

    def _check(self, index: int, just_placed: bool = True) -> bool:
        """Perception looks at every domino placed so far and at slot ``index``; fallen
        ones are queued again.

        One hidden from the camera (NOT_SEEN: most of it behind something, e.g. the arm
        above the domino just placed) is taken as standing until the next check: rebuilt
        on perception's word alone, a domino that still stood there was hit by the next
        (a whole run fell so). One upright but off target by up to keep_off_target is left
        standing where perception measured it, not picked up from within the run; so is
        one that stays within the tolerance of where it was left, and one whose pick-up
        again failed, up to keep_when_stuck. A hidden ``index`` not ``just_placed`` (e.g.
        the slot a fallen domino was swept out of) is not taken as standing."""
        fresh = self._settle(self.settings.settle_after_place)
        self.still_since = fresh
        indices = sorted(set(self.state.standing) | {index})
        answer = self.client.check_placement([self.targets[i] for i in indices], not_before=fresh)
        if not answer.success:
            self.report.dominoes[index].check = f"placement check failed: {answer.message}"
            return False
        placed = False
        settings = self.settings
        tolerance, tilt_tolerance = settings.place_tolerance, settings.place_tilt_tolerance
        for position, i in enumerate(indices):
            status = answer.status[position]
            error, tilt = answer.position_error[position], answer.tilt[position]
            hidden = status == CheckPlacement.Response.NOT_SEEN and (just_placed or i != index)
            measured, last = answer.measured[position], self.state.standing.get(i)
            # within the tolerance of where it was last taken to stand: not moved (one
            # left 6.0 mm off read 6.6 mm at the next check and was to be picked again)
            stayed = last is not None and near(spot_of(measured), spot_of(last), tolerance)
            erect = status == CheckPlacement.Response.STANDING and tilt <= tilt_tolerance
            keep = settings.keep_when_stuck if i in self.state.stuck else settings.keep_off_target
            off_target = erect and error > tolerance and (error <= keep or stayed)
            upright = hidden or off_target or (erect and error <= tolerance)
            if i == index:
                outcome = self.report.dominoes[index]
                outcome.check = check_words(status, error, tilt)
                outcome.measured_error_mm, outcome.measured_tilt_deg = (
                    (None, None) if hidden else (error * 1e3, math.degrees(tilt))
                )
                outcome.off_target = off_target
                placed = upright
            if upright:
                moved = off_target and last is self.targets[i]
                if i != index and (hidden or moved):
                    words = check_words(status, error, tilt)
                    log(f"domino {i + 1} moved ({words}); left standing" if moved else words)
                where = (last if stayed else measured) if off_target else self.targets[i]
                self.state.standing[i] = where  # for the planner to keep clear of
            else:
                self.state.standing.pop(i, None)
                self._remember_fallen(i, status, measured, tilt)
                if i != index:
                    self.report.dominoes[i].placed = False  # until it is built again
                    log(
                        f"domino {i + 1} is no longer standing ({check_words(status, error, tilt)})"
                    )
        return placed

    def _remember_fallen(self, index: int, status: int, measured: Pose, tilt: float) -> None:
        """A run domino out of place is picked up again from where perception fitted it;
        one that fell where no box fits (perception answers the standing target, tilt 0)
        is left where it lies, and a domino from the pile takes its place."""
        if status == CheckPlacement.Response.STANDING or (
            status == CheckPlacement.Response.FALLEN and tilt > self.settings.place_tilt_tolerance
        ):
            self.state.fallen[index] = measured
        elif status == CheckPlacement.Response.FALLEN:
            self.state.fallen.pop(index, None)
            log(f"domino {index + 1} fell where perception cannot fit it; left where it lies")

    # ------------------------------------------------------------------ knock-down
    def _strike(self) -> None:
        """Knock down what stands as sections (each group of consecutive standing slots
        struck from its own first domino), in ``sections.strike_order``: from the run's
        end backwards, so that no strike reaches a section still standing. Then perception
        counts what fell, section by section."""
        built = sorted(self.state.standing)
        sections = sections_of(built)
        self.report.sections = [SectionOutcome(s.first + 1, s.last + 1) for s in sections]
        outcomes = dict(zip(sections, self.report.sections, strict=True))
        for section in strike_order(sections, self.layout):
            outcome = outcomes[section]
            outcome.message = self._strike_section(section, built)
            outcome.struck = not outcome.message
            if outcome.message:
                words = f"{section}: {outcome.message}"
                self.report.message = "; ".join(m for m in (self.report.message, words) if m)
                log(words)
        if not any(s.struck for s in self.report.sections):
            return
        self.report.struck = all(s.struck for s in self.report.sections)
        fresh = self._settle(self.settings.topple_wait)
        self._take_picture("after_strike", fresh)
        answer = self.client.check_placement([self.targets[i] for i in built], not_before=fresh)
        down = [s != CheckPlacement.Response.STANDING for s in answer.status]
        fallen = dict(zip(built, down if answer.success else [False] * len(built), strict=True))
        for section, outcome in outcomes.items():
            outcome.toppled_by_perception = sum(fallen[i] for i in section.slots)
        self.report.toppled_by_perception = answer.success and all(fallen.values())
        log(f"after the strike perception sees {sum(fallen.values())}/{len(built)} dominoes down")

    def _strike_section(self, section: Section, built: Sequence[int]) -> str:
        """Strike ``section``'s first domino, every other of the ``built`` slots an
        obstacle; "" once the arm pushed it, or why not."""
        whole = len(built) == len(self.layout)
        log("the run stands: knocking it down" if whole else f"knocking down {section}")
        plan = self.client.plan_strike(
            PlanStrike.Request(
                domino_pose=self.targets[section.first],
                standing_dominoes=[self.targets[i] for i in built if i != section.first],
                time_budget=self.settings.plan_budget,
            ),
            timeout=self.settings.plan_budget + 30.0,
        )
        if not plan.success:
            return f"strike planning failed: {plan.message}"
        executed, why = self._execute(plan.segments, holds_domino=False)
        return "" if executed else f"strike failed: {why}"

    def _take_picture(self, name: str, not_before: float) -> None:
        """REPORT_CAMERA's view for the report (for people; nothing acts on it)."""
        try:
            self.pictures[name] = self.client.color_frame(REPORT_CAMERA, not_before)
        except CallFailedError as error:
            log(f"no picture {name} for the report: {error}")

    def _truth(self) -> list[tuple[str, np.ndarray]]:
        """The simulator's dominoes now, names and 4x4 poses: for the report only."""
        truth = self.client.ground_truth(newer_than=self.client.sim_time - 0.01)
        return [(d.name, pose_matrix(d.pose)) for d in truth.dominoes]

    def _pick_record(
        self,
        index: int,
        candidate: Candidate,
        pile: str,
        plan: PlanPlace.Response,
        truth: list[tuple[str, np.ndarray]],
    ) -> dict | None:
        """What a pick was planned from and the simulator's truth at the time, to replay it
        offline (``settings.record_picks``); None when not recorded."""
        if self.settings.record_picks is None:
            return None
        joints, grasp = self.client.joint_state(), candidate.grasp
        return {
            "slot": index + 1,
            "attempt": self.report.dominoes[index].attempts,
            "source": candidate.source,
            "domino_pose": pose_matrix(candidate.pose).tolist(),
            "grasp_pose": None if grasp is None else pose_matrix(grasp).tolist(),
            "pile": pile,
            "pile_dominoes": [pose_matrix(p).tolist() for p in candidate.neighbours],
            "pile_points": [[p.x, p.y, p.z] for p in self._pile_points(candidate, pile)],
            "plan": plan.message,
            "place_pose": pose_matrix(self.releases[index]).tolist(),
            "start": {"names": list(joints.name), "positions": list(joints.position)},
            "segments": [segment_record(s) for s in plan.segments],
            "truth": {name: matrix.tolist() for name, matrix in truth},
        }

    def _write_pick_record(self, record: dict | None, failure: str) -> None:
        if record is None:
            return
        folder = self.settings.record_picks
        folder.mkdir(parents=True, exist_ok=True)
        record["failure"] = failure  # "": carried to the slot
        path = folder / f"pick{self.picks_recorded:03d}_slot{record['slot']}.json"
        path.write_text(json.dumps(record))
        self.picks_recorded += 1

    def _record_truth(self, before_strike: bool) -> None:
        """Ground truth for the report: the simulator domino nearest each target."""
        poses = [matrix for _, matrix in self._truth()]
        if not poses:
            return
        centres = np.array([p[:2, 3] for p in poses])
        down = 0
        standing = 0
        for outcome, target in zip(self.report.dominoes, self.layout, strict=True):
            distances = np.linalg.norm(centres - [target.x, target.y], axis=1)
            nearest = int(np.argmin(distances))
            if distances[nearest] > (0.02 if before_strike else DOMINO_LENGTH):
                continue
            pose = poses[nearest]
            tilt = math.degrees(tilt_from_vertical(pose))
            along = pose[:3, 2]
            record = TruthPose(
                float(pose[0, 3]),
                float(pose[1, 3]),
                math.atan2(along[1], along[0]),
                tilt,
                float(distances[nearest] * 1e3),
            )
            if before_strike:
                outcome.truth_built = record
                standing += tilt < 10.0
            elif outcome.placed:  # an empty slot's nearest is a neighbour's
                outcome.truth_after_strike = record
                down += tilt > 45.0
        if before_strike:
            self.report.standing_by_truth = standing
        elif self.report.struck:
            self.report.toppled_by_truth = down == sum(d.placed for d in self.report.dominoes)


PICKABLE_POSTURES = (  # lying flat or leaning; the planner has the last word
    DominoDetection.POSTURE_FLAT,
    DominoDetection.POSTURE_TILTED,
)
POSTURE_NAMES = {
    DominoDetection.POSTURE_FLAT: "flat",
    DominoDetection.POSTURE_ON_EDGE: "on edge",
    DominoDetection.POSTURE_UPRIGHT: "upright",
    DominoDetection.POSTURE_TILTED: "leaning",
}


def nearest_truth(truth: list[tuple[str, np.ndarray]], pose: Pose) -> tuple[str, float | None]:
    """The simulator's domino whose centre is nearest ``pose``'s, and how far [mm]."""
    if not truth:
        return "", None
    centres = np.array([matrix[:3, 3] for _, matrix in truth])
    distances = np.linalg.norm(centres - pose_matrix(pose)[:3, 3], axis=1)
    nearest = int(np.argmin(distances))
    return truth[nearest][0], float(distances[nearest] * 1e3)


def segment_record(segment: TrajectorySegment) -> dict:
    """A planned segment as plain numbers (times in s from its start)."""
    points = segment.trajectory.points
    return {
        "label": segment.label,
        "joint_names": list(segment.trajectory.joint_names),
        "times": [seconds(p) for p in points],
        "positions": [list(p.positions) for p in points],
        "velocities": [list(p.velocities) for p in points],
        "gripper_after": int(segment.gripper_after),
        "gripper_position": segment.gripper_position,
        "gripper_max_effort": segment.gripper_max_effort,
    }


def spot_of(pose: Pose) -> np.ndarray:
    """Where a domino lies on the table: (x, y) [m]."""
    return np.array([pose.position.x, pose.position.y])


def foot_distance(measured: Pose, expected: Pose) -> float:
    """Horizontal distance [m] between the lower ends (feet) of two dominoes' length axes:
    where a leaning domino's foot is, it will stand once let go."""
    feet = []
    for pose in (measured, expected):
        matrix = pose_matrix(pose)
        axis = matrix[:3, 0] * (1.0 if matrix[2, 0] <= 0.0 else -1.0)  # pointing down
        feet.append(matrix[:2, 3] + axis[:2] * DOMINO_LENGTH / 2.0)
    return float(np.linalg.norm(feet[0] - feet[1]))


def points_near(pose: Pose, points: Sequence[Point]) -> list[Point]:
    """The ``points`` within POINTS_RADIUS of ``pose`` horizontally: all the pads can meet."""
    xy = np.array([(p.x, p.y) for p in points]).reshape(-1, 2)
    near = np.hypot(*(xy - spot_of(pose)).T) < POINTS_RADIUS
    return [points[i] for i in np.flatnonzero(near)]


def near(spot: np.ndarray, other: np.ndarray, radius: float) -> bool:
    return bool(np.linalg.norm(spot - other) < radius)


def near_any(spot: np.ndarray, spots: Sequence[np.ndarray]) -> bool:
    """``spot`` is one of ``spots`` (within SAME_SPOT): the same domino seen again."""
    return any(near(spot, other, SAME_SPOT) for other in spots)


def add_spent(
    into: dict[str, float], spent: dict[str, float], before: dict[str, float]
) -> dict[str, float]:
    """Add to ``into`` the simulated seconds per activity that ``spent`` grew by since
    ``before``; ``spent`` as it is now, to count from next."""
    for activity, seconds in spent.items():
        grown = seconds - before.get(activity, 0.0)
        if grown:
            into[activity] = round(into.get(activity, 0.0) + grown, 3)
    return dict(spent)


def is_approach(segment: TrajectorySegment) -> bool:
    """The segment that brings the open gripper down to a domino (regrasps included)."""
    return segment.label.endswith("approach_grasp")


def seconds(point: JointTrajectoryPoint) -> float:
    return seconds_of(point.time_from_start)


def reversed_trajectory(trajectory: JointTrajectory, lead: float) -> JointTrajectory:
    """The same path run backwards in time (velocities negated), starting ``lead`` seconds
    late: the arm may have stopped short of the path's end (blocked by what it touched),
    and the controller eases it from where it is onto the path over that time."""
    end = seconds(trajectory.points[-1])
    points = []
    for point in reversed(trajectory.points):
        elapsed = lead + end - seconds(point)
        points.append(
            JointTrajectoryPoint(
                positions=list(point.positions),
                velocities=[-v for v in point.velocities],
                time_from_start=duration_message(elapsed),
            )
        )
    return JointTrajectory(joint_names=list(trajectory.joint_names), points=points)


def neighbours_of(pose: Pose, others: Iterable[Pose]) -> list[Pose]:
    """Those of ``others`` (``pose`` itself aside) close enough to it to matter for the
    fingers: a pick's pile, or the fallen beside a fallen run domino (a run that fell lies
    in a row, each on the next)."""
    centre = spot_of(pose)
    return [
        other
        for other in others
        if other is not pose and near(spot_of(other), centre, NEIGHBOUR_RADIUS)
    ]


def check_words(status: int, error: float, tilt: float) -> str:
    if status == CheckPlacement.Response.NOT_SEEN:
        return "not seen (hidden from the camera): taken as standing until the next check"
    name = {0: "standing", 1: "fallen", 2: "missing"}.get(status, str(status))
    return f"{name}, {error * 1e3:.1f} mm and {math.degrees(tilt):.1f}° from the target"


def restarted(group: ProcessGroup) -> dict[str, int]:
    """The nodes started again during the job, and how often."""
    return {name: count for name, count in group.restarts().items() if count}


def run_arm_job(
    out_dir: Path,
    layout: Sequence[DominoPlacement],
    layout_name: str,
    settings: ArmJobSettings,
    node_command: NodeCommand,
) -> int:
    """Start the nodes, run the job, write the report; the exit status: 0 full success,
    3 partial (slots left empty, what stood knocked down), 1 failed."""
    sim_parameters = {
        "domino_count": 0,  # the job's reset pours the pile
        "real_time_factor": settings.real_time_factor,
        "camera_rate": settings.camera_rate,
        "meshcat": settings.meshcat or settings.record,
    }
    if settings.record:  # (an empty value is no parameter rule rcl can parse)
        sim_parameters["meshcat_recording_path"] = str((out_dir / SCENE_FILE).resolve())
    meshcat_urls: list[str] = []
    # writing scene.html and closing run.mcap take a few seconds after the stop signal
    with ProcessGroup(stop_timeout=60.0 if settings.record else 5.0) as group:
        recorder = recorder_command(out_dir, settings, node_command)
        if recorder:
            group.start("record", recorder)
        group.start(
            "sim_node",
            node_command("dombot_sim", "sim_node", sim_parameters),
            on_line=lambda line: meshcat_urls.extend(MESHCAT_URL.findall(line)),
        )
        on_sim_time = {"use_sim_time": True}  # frame ages and timers in simulated seconds
        on_demand = on_sim_time | {"continuous": False}  # the job asks; no CPU spent otherwise
        # perception and planner answer from the request and the scene: one that dies is
        # started again and asked again; the simulator's state cannot be restored
        group.start(
            "perception_node",
            node_command("dombot_perception", "perception_node", on_demand),
            restartable=True,
        )
        group.start(
            "planner_node",
            node_command("dombot_planner", "planner_node", on_sim_time),
            restartable=True,
        )
        rclpy.init()
        client = CellClient(watchdog=group.check, restarts=group.restarts)
        job = None
        try:
            group.wait_until(lambda: client.ready(NEEDED_SERVICES), 600.0, "the nodes to be ready")
            if settings.meshcat and meshcat_urls:
                log(f"Meshcat: {meshcat_urls[0]}")
            log(
                f"nodes ready; building '{layout_name}' ({len(layout)} dominoes) "
                f"from a pile of {settings.pile} (seed {settings.seed})"
            )
            job = ArmJob(client, layout, layout_name, settings)
            if settings.record:  # written when the nodes stop, whatever happens
                job.report.files |= {"recording": RECORDING_FILE, "meshcat_scene": SCENE_FILE}
            report = job.run()
            group.check()
            report.node_restarts = restarted(group)
            status = finish_report(report, out_dir, job.pictures)
            if settings.meshcat and meshcat_urls:
                hold_viewer(meshcat_urls[0])
        except NodeDiedError as error:
            if job is not None:  # what was built so far, for the user to see
                job.report.node_restarts = restarted(group)
                job.report.message = (
                    f"stopped: node '{error.name}' died (exit code {error.returncode})"
                )
                json_path, png_path = write_report(job.report, out_dir, job.pictures)
                log(f"{job.report.message}; partial report: {json_path}  picture: {png_path}")
            raise
        finally:
            client.close()
            rclpy.try_shutdown()
    if settings.record:
        log(f"recording: {out_dir / RECORDING_FILE}  Meshcat scene: {out_dir / SCENE_FILE}")
    return status


def recorder_command(out_dir: Path, settings: ArmJobSettings, node_command: NodeCommand):
    """argv of the recorder for --record and --foxglove (empty: neither), on simulated time."""
    options = []
    if settings.record:
        options += ["-o", str(out_dir / RECORDING_FILE)]
        options += ["--image-rate", str(settings.record_image_rate)]
    if settings.foxglove_port is not None:
        options += ["--foxglove-port", str(settings.foxglove_port)]
    if not options:
        return []
    command = node_command("dombot_bringup", "record", {"use_sim_time": True})
    return command[:1] + options + command[1:]


def finish_report(report: RunReport, out_dir: Path, pictures: dict[str, np.ndarray]) -> int:
    """Write the report, print its summary; the exit status (``sections.exit_status``)."""
    json_path, png_path = write_report(report, out_dir, pictures)
    summary = report.summary()
    log(
        f"{summary['placed']}/{summary['dominoes']} placed "
        f"({summary['placed_first_attempt']} on the first attempt, {summary['retries']} retries), "
        f"toppled: perception {summary['toppled_by_perception']}, "
        f"truth {summary['toppled_by_truth']}; "
        f"{report.simulated_s:.0f} s simulated, {report.wall_s:.0f} s wall"
    )
    log(f"report: {json_path}  picture: {png_path}")
    status = report.exit_status
    print(VERDICTS[status], file=sys.stderr if status else sys.stdout, flush=True)
    return status


def hold_viewer(url: str, stdin: TextIO = sys.stdin) -> None:
    """On a terminal, keep the nodes (and Meshcat's page) up until the user presses Enter;
    elsewhere (CI, a pipe) go on at once."""
    if not stdin.isatty():
        return
    log(f"Meshcat stays at {url}; press Enter to stop")
    with contextlib.suppress(EOFError):
        stdin.readline()

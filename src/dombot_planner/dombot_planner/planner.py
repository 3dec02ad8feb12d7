"""Pick-and-place planning: coarse KTO moves, straight-line final approaches, TOPP-RA timing.

Plan of a request (docs/PLANNER.md has the picture):

1. *Ends.* For each grasp (the request's, or dombot_description.grasp's ranked list) solve
   IK at the grasp and a straight vertical line up to ``pick_approach_distance`` above it,
   IK-continued every ``waypoint_spacing``; check its clearances with the open fingers
   (approach) and with the closed fingers holding the domino (lift). Then the same for the
   place pose's symmetric equivalents (ranked so the gripper leans over the run's free
   side), checked holding the domino (descent) and with released fingers (retreat).
2. *Coarse moves* by KinematicTrajectoryOptimization: start → above the grasp (open
   fingers), above the grasp → above the placement (holding the domino), seeded by the
   straight joint line, then by a raised via configuration, then by perturbed ones;
   every result is checked at dense samples before it is accepted.
3. *Timing:* every piece is retimed by TOPP-RA and pieces join at rest. Segments:
   open the gripper; approach and grasp (close); lift, transfer, descend (open); retreat.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import (
    FINGER_SWAP,
    comes_from_above,
    domino_in_tcp,
    pick_grasps,
    place_grasps,
    pregrasp_opening,
    release_opening,
    top_grasp,
)
from dombot_description.scenario import Scenario
from dombot_planner import coarse
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.ik import PoseIK, straight_line
from dombot_planner.request import PickPlaceRequest, check_request
from dombot_planner.scene import (
    HELD,
    MOVING,
    OBSTACLES,
    PADS,
    SELF,
    STANDING,
    TABLE,
    TARGET,
    ClearanceRules,
    Scene,
    ShadowPlants,
)
from dombot_planner.settings import PlannerSettings
from dombot_planner.timing import JointLimits, TimedPath, line_path, retime

GRIPPER_NONE, GRIPPER_OPEN, GRIPPER_CLOSE = "none", "open", "close"
MAX_JOINT_STEP = 0.1  # rad between line waypoints; more means the arm flips
COARSE_CHECK_SAMPLES = 120  # at least this many clearance checks of each KTO result ...
CHECK_JOINT_STEP = 0.01  # rad ... and no joint moving more than this between them
CHECK_MARGIN = 5e-4  # m the planner's own check adds to the required clearance
LINE_GRID_POINTS = 100  # TOPP-RA grid on a line (its end point is only loosely constrained)
FREE_SIDE_RADIUS = 0.1  # m: standing dominoes this close decide the free side
UP = np.array([0.0, 0.0, 1.0])


@dataclass(frozen=True)
class SampledSegment:
    """One executed segment: joint samples and the gripper event after it."""

    label: str
    times: np.ndarray
    positions: np.ndarray  # samples × 7
    velocities: np.ndarray
    accelerations: np.ndarray
    gripper_after: str  # "none" | "open" | "close"
    gripper_position: float


@dataclass
class Segment:
    """A trajectory (pieces played in order, each from rest to rest) and a gripper event."""

    label: str
    pieces: list[TimedPath]
    finger_opening: float  # m while this segment runs
    gripper_after: str = GRIPPER_NONE
    gripper_position: float = 0.0
    gripper_effort: float = 0.0
    start: np.ndarray | None = None  # for a segment without motion

    @property
    def duration(self) -> float:
        return sum(piece.duration for piece in self.pieces)

    def sample(self, period: float) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
        """Times (from the segment start), positions, velocities, accelerations.

        Each piece is sampled every ``period`` and at its end, so every rest point (piece
        ends) is a sample.
        """
        if not self.pieces:
            q = np.atleast_2d(self.start)
            return np.zeros(1), q, np.zeros_like(q), np.zeros_like(q)
        times, q, qd, qdd = [np.zeros(1)], [], [], []
        offset = 0.0
        first = self.pieces[0].sample(np.zeros(1))
        q.append(first[0]), qd.append(first[1]), qdd.append(first[2])
        for piece in self.pieces:
            local = np.append(np.arange(period, piece.duration, period), piece.duration)
            values = piece.sample(local)
            times.append(offset + local)
            q.append(values[0]), qd.append(values[1]), qdd.append(values[2])
            offset += piece.duration
        return np.concatenate(times), np.vstack(q), np.vstack(qd), np.vstack(qdd)


@dataclass
class Plan:
    segments: list[Segment]
    grasp_pose: RigidTransform  # TCP when the gripper closes
    release_pose: RigidTransform  # TCP when it opens
    held_in_tcp: RigidTransform  # the domino in the TCP frame while held
    planning_time: float = 0.0
    kto_attempts: dict[str, int] = field(default_factory=dict)
    regrasped: bool = False  # the domino was turned in place first (two picks)

    def final_positions(self) -> np.ndarray:
        """Arm joint positions when the plan has been executed."""
        last = self.segments[-1]
        if not last.pieces:
            return np.asarray(last.start)
        return last.pieces[-1].sample(np.array([last.pieces[-1].duration]))[0][0]

    def sampled(self, period: float) -> list[SampledSegment]:
        """The segments as executed: samples every ``period`` (and at every rest point)."""
        result = []
        for segment in self.segments:
            times, q, qd, qdd = segment.sample(period)
            result.append(
                SampledSegment(
                    segment.label,
                    times,
                    q,
                    qd,
                    qdd,
                    segment.gripper_after,
                    segment.gripper_position,
                )
            )
        return result


@dataclass
class End:
    """One end of the transfer: IK at the pose and the vertical line above it."""

    tcp_pose: RigidTransform
    line: np.ndarray  # waypoints from the pose (index 0) up to the approach height

    @property
    def above(self) -> np.ndarray:
        return self.line[-1]


def lift_directions(grasp: RigidTransform) -> list[np.ndarray]:
    """Straight up, else 45° up and towards where the approach points horizontally.

    A grasp leaning away from the arm base on the near side of the pile has the wrist
    so close to the shoulder that lifting straight up runs into the elbow limit; the
    tilted lift moves the wrist outwards instead (the open pads pass beside the domino).
    """
    horizontal = grasp.rotation().matrix()[:, 2] * [1.0, 1.0, 0.0]
    norm = np.linalg.norm(horizontal)
    if norm < 1e-6:
        return [UP]
    return [UP, (UP + horizontal / norm) / np.sqrt(2.0)]


def _reasons(failures: Counter) -> str:
    return ", ".join(f"{reason}: {count}" for reason, count in failures.most_common()) or "none"


class Deadline:
    def __init__(self, budget: float) -> None:
        self.start = time.monotonic()
        self.end = self.start + budget

    def check(self, stage: str) -> None:
        if time.monotonic() > self.end:
            raise PlanningError(
                ErrorCode.TIMEOUT, stage, f"time budget of {self.end - self.start:.2f} s used up"
            )

    def elapsed(self) -> float:
        return time.monotonic() - self.start


@dataclass
class EndSearch:
    """What the search for pick and place ends tried: the error when nothing was found."""

    grasp_candidates: int = 0
    place_candidates: int = 0
    picks_found: int = 0
    grasp_failures: Counter = field(default_factory=Counter)
    place_failures: Counter = field(default_factory=Counter)

    def error(self) -> PlanningError:
        if self.picks_found == 0:
            return PlanningError(
                ErrorCode.GRASP_UNREACHABLE,
                "grasp",
                f"no collision-free IK and approach line for any of {self.grasp_candidates} "
                f"grasps ({_reasons(self.grasp_failures)})",
            )
        return PlanningError(
            ErrorCode.PLACE_UNREACHABLE,
            "place",
            f"no collision-free IK and approach line for any of {self.place_candidates} "
            f"place poses ({_reasons(self.place_failures)})",
        )


class PickPlacePlanner:
    """Plans /plan_place requests; keeps shadow plants between requests (not thread-safe)."""

    def __init__(self, scenario: Scenario, settings: PlannerSettings | None = None) -> None:
        self.scenario = scenario
        self.settings = settings or PlannerSettings()
        self.plants = ShadowPlants(scenario)
        plant = self.plants.get(DOMINO_SIZE[1]).plant
        self.lower = plant.GetPositionLowerLimits()
        self.upper = plant.GetPositionUpperLimits()
        self.limits = JointLimits(
            velocity=plant.GetVelocityUpperLimits() * self.settings.velocity_scale,
            acceleration=np.full(plant.num_velocities(), self.settings.acceleration_limit),
        )

    def coarse_rules(self, floor: float | None = None) -> ClearanceRules:
        """Everything ``floor`` (default coarse_clearance) from the table and dominoes."""
        clearance = self.settings.coarse_clearance if floor is None else floor
        rules = {(moving, other): clearance for moving in MOVING for other in OBSTACLES}
        rules.update({(moving, SELF): self.settings.self_clearance for moving in MOVING})
        return ClearanceRules(rules)

    def fine_rules(self) -> ClearanceRules:
        """Within the lines only pads and the held domino come near the table and dominoes."""
        s = self.settings
        rules = self.coarse_rules().minimum.copy()
        rules.update(
            {
                (PADS, TABLE): s.pad_table_clearance,
                (PADS, STANDING): s.fine_obstacle_clearance,
                (PADS, TARGET): s.fine_obstacle_clearance,
                (HELD, TABLE): -s.release_height - 1e-3,  # lies on the table at pick
                (HELD, STANDING): s.fine_obstacle_clearance,
            }
        )
        return ClearanceRules(rules)

    def plan(self, request: PickPlaceRequest) -> Plan:
        """A plan for ``request``; raises PlanningError with a code and the failing stage."""
        check_request(request, self.settings)
        deadline = Deadline(request.time_budget or self.settings.default_time_budget)
        try:
            plan = RequestPlanning(self, request, deadline).plan()
        except PlanningError as error:
            if not (
                error.code == ErrorCode.GRASP_UNREACHABLE
                and request.grasp_pose is None
                and self.settings.allow_regrasp
            ):
                raise
            plan = self._plan_with_regrasp(request, deadline, error)
        plan.planning_time = deadline.elapsed()
        return plan

    def _plan_with_regrasp(
        self, request: PickPlaceRequest, deadline: Deadline, error: PlanningError
    ) -> Plan:
        """Turn the domino a quarter turn in place with the top grasp, then pick it again.

        Where the domino lies along the radius close to the arm, no tilted grasp reaches it
        (the wrist would come closer to the shoulder than the elbow allows); lying across
        the radius it is reachable. A quarter turn is the only distinct one (a half turn is
        a symmetry of the box).
        """
        domino = request.domino_pose
        turned = RigidTransform(
            RotationMatrix.MakeZRotation(math.pi / 2) @ domino.rotation(), domino.translation()
        )
        top = pick_grasps(domino, tcp_in_domino=top_grasp())[0].pose
        try:
            turn = replace(request, place_pose=turned, grasp_pose=top)
            first = RequestPlanning(self, turn, deadline).plan()
            pick_again = replace(request, domino_pose=turned, start=first.final_positions())
            second = RequestPlanning(self, pick_again, deadline).plan()
        except PlanningError as regrasp_error:
            if regrasp_error.code == ErrorCode.TIMEOUT:
                raise
            raise PlanningError(
                error.code,
                error.stage,
                f"{error.message}; turning it first failed too ({regrasp_error})",
            ) from None
        for segment in first.segments:
            segment.label = f"regrasp_{segment.label}"
        return Plan(
            first.segments + second.segments,
            second.grasp_pose,
            second.release_pose,
            second.held_in_tcp,
            kto_attempts={
                **{f"regrasp_{k}": v for k, v in first.kto_attempts.items()},
                **second.kto_attempts,
            },
            regrasped=True,
        )


class RequestPlanning:
    """The planning of one request: its scenes, random seeds, deadline and search record."""

    def __init__(
        self, planner: PickPlacePlanner, request: PickPlaceRequest, deadline: Deadline
    ) -> None:
        self.planner, self.settings = planner, planner.settings
        self.request, self.deadline = request, deadline
        self.rng = np.random.default_rng(self.settings.seed)
        closed = request.grasp_width or DOMINO_SIZE[1]
        self.openings = {
            "pregrasp": pregrasp_opening(closed),
            "closed": closed,
            "release": release_opening(closed),
        }
        self.approach = self._scene("pregrasp", target=request.domino_pose)
        self.retreat = self._scene("release", target=request.place_pose)
        self.search = EndSearch()

    def _scene(self, opening: str, **dominoes) -> Scene:
        shadow = self.planner.plants.get(self.openings[opening])
        return Scene(shadow, self.planner.scenario.tcp_frame, self.request.standing, **dominoes)

    def plan(self) -> Plan:
        self._check_start()
        connect_error = None
        for pick, place, transfer in self._ends():
            try:
                return self._connect(pick, place, transfer)
            except PlanningError as error:
                if error.code == ErrorCode.TIMEOUT:
                    raise
                connect_error = error  # try the next pair of ends
        raise connect_error or self.search.error()

    # ------------------------------------------------------------------ ends
    def _check_start(self) -> None:
        clearance = self.approach.clearance(self.request.start)
        violations = self.planner.coarse_rules(floor=0.0).violations(clearance)
        if violations:
            raise PlanningError(
                ErrorCode.INVALID_REQUEST, "start", f"start state in collision: {violations[0]}"
            )

    def _seeds(self, first: list[np.ndarray]) -> list[np.ndarray]:
        """IK seeds: ``first``, home, then seeded random configurations inside the limits."""
        lower, upper = self.planner.lower, self.planner.upper
        middle, half = (lower + upper) / 2, 0.8 * (upper - lower) / 2
        count = self.settings.ik_random_seeds
        random = self.rng.uniform(middle - half, middle + half, (count, len(lower)))
        return [*first, self.planner.scenario.home_position, *random]

    def _ends(self) -> Iterator[tuple[End, End, Scene]]:
        """Pick and place ends that pass their checks, best candidates first."""
        request, s = self.request, self.settings
        if request.grasp_pose is not None:
            grasps = [request.grasp_pose, request.grasp_pose @ FINGER_SWAP]
        else:
            grasps = [g.pose for g in pick_grasps(request.domino_pose) if comes_from_above(g.pose)]
        self.search.grasp_candidates = len(grasps)
        release = RigidTransform(s.release_height * UP) @ request.place_pose
        free = self._free_direction()
        for grasp in grasps:
            self.deadline.check("grasp")
            held = domino_in_tcp(grasp, request.domino_pose)
            transfer = self._scene("closed", held_in_tcp=held)
            pick = self._end(
                grasp,
                s.pick_approach_distance,
                lift_directions(grasp),
                [self.approach, transfer],
                self._seeds([request.start]),
                self.search.grasp_failures,
            )
            if pick is None:
                continue
            self.search.picks_found += 1
            places = [p for p in place_grasps(release, held, free) if comes_from_above(p)]
            self.search.place_candidates = len(places)
            for place_pose in places:
                place = self._end(
                    place_pose,
                    s.place_approach_distance,
                    [UP],
                    [transfer, self.retreat],
                    self._seeds([pick.line[0], request.start]),
                    self.search.place_failures,
                )
                if place is not None:
                    yield pick, place, transfer

    def _free_direction(self) -> np.ndarray:
        """The side of the place pose (±its z) where standing dominoes are farthest."""
        forward = self.request.place_pose.rotation().matrix()[:, 2]
        centre = self.request.place_pose.translation()

        def nearest(sign: float) -> float:
            ahead = [
                np.linalg.norm(p.translation() - centre)
                for p in self.request.standing
                if sign * (p.translation() - centre) @ forward > 0
            ]
            return min([FREE_SIDE_RADIUS, *ahead])

        return forward if nearest(1.0) >= nearest(-1.0) else -forward

    def _end(
        self,
        tcp_pose: RigidTransform,
        distance: float,
        directions: list[np.ndarray],
        scenes: list[Scene],
        seeds: list[np.ndarray],
        failures: Counter,
    ) -> End | None:
        """IK at ``tcp_pose`` and a straight line away from it, clear in every scene.

        ``directions`` are tried in order for the line; ``failures`` counts why seeds failed.
        """
        ik = PoseIK(scenes[0], tcp_pose.rotation())
        target = tcp_pose.translation()
        rules = self.planner.fine_rules()
        top_rules = self.planner.coarse_rules(self.settings.coarse_clearance + 1e-3)
        for seed in seeds:
            self.deadline.check("ends")
            q = ik.solve(target, seed, seed)
            if q is None:
                failures["no IK"] += 1
                continue
            if any(rules.violations(scene.clearance(q)) for scene in scenes):
                failures["in collision at the pose"] += 1
                continue
            for direction in directions:
                line = straight_line(
                    ik,
                    q,
                    target,
                    distance * direction,
                    self.settings.waypoint_spacing,
                    MAX_JOINT_STEP,
                )
                if line is None:
                    failures["line leaves the reach"] += 1
                elif any(top_rules.violations(scene.clearance(line[-1])) for scene in scenes):
                    failures["line end too close"] += 1
                elif any(
                    rules.violations(scene.clearance(waypoint))
                    for scene in scenes
                    for waypoint in line[1:-1]
                ):
                    failures["line too close"] += 1
                else:
                    return End(tcp_pose, line)
        return None

    # ------------------------------------------------------------------ connect
    def _connect(self, pick: End, place: End, transfer: Scene) -> Plan:
        """Coarse moves between the ends, retimed and assembled into segments."""
        attempts: dict[str, int] = {}
        start = self.request.start
        to_pick = self._coarse("approach_grasp", self.approach, start, pick.above, attempts)
        to_place = self._coarse("transfer", transfer, pick.above, place.above, attempts)
        self.deadline.check("retiming")
        openings, force = self.openings, self.settings.grip_force
        pieces = {
            "down_to_grasp": self._line("descend_to_grasp", pick.line[::-1], self.approach),
            "lift": self._line("lift", pick.line, transfer),
            "down_to_place": self._line("descend_to_place", place.line[::-1], transfer),
            "retreat": self._line("retreat", place.line, self.retreat),
        }
        segments = [
            Segment(
                "open_gripper",
                [],
                openings["release"],
                GRIPPER_OPEN,
                openings["pregrasp"],
                start=start,
            ),
            Segment(
                "approach_grasp",
                [to_pick, pieces["down_to_grasp"]],
                openings["pregrasp"],
                GRIPPER_CLOSE,
                0.0,
                force,
            ),
            Segment(
                "transfer",
                [pieces["lift"], to_place, pieces["down_to_place"]],
                openings["closed"],
                GRIPPER_OPEN,
                openings["release"],
            ),
            Segment("retreat", [pieces["retreat"]], openings["release"]),
        ]
        held_in_tcp = domino_in_tcp(pick.tcp_pose, self.request.domino_pose)
        return Plan(segments, pick.tcp_pose, place.tcp_pose, held_in_tcp, kto_attempts=attempts)

    def _line(self, label: str, waypoints: np.ndarray, scene: Scene) -> TimedPath:
        spacing = self.settings.waypoint_spacing
        timed = retime(
            label,
            line_path(waypoints, spacing),
            scene.plant,
            self.planner.limits,
            fine=True,
            tcp=scene.tcp,
            tcp_speed=self.settings.approach_speed,
            grid_points=LINE_GRID_POINTS,
        )
        if timed is None:
            length = spacing * (len(waypoints) - 1)
            raise PlanningError(
                ErrorCode.PLANNING_FAILED, label, f"TOPP-RA found no timing for a {length} m line"
            )
        return timed

    def _coarse(
        self,
        label: str,
        scene: Scene,
        q_start: np.ndarray,
        q_goal: np.ndarray,
        attempts: dict[str, int],
    ) -> TimedPath:
        """A KTO move from ``q_start`` to ``q_goal`` that passes the dense clearance check."""
        s = self.settings
        ends = min(scene.minimum_distance(q_start), scene.minimum_distance(q_goal))
        bound = min(s.coarse_clearance + s.coarse_margin, 0.9 * ends)
        rules = self.planner.coarse_rules(min(s.coarse_clearance + CHECK_MARGIN, 0.9 * ends))
        failure = "no attempt"
        for attempt in range(s.kto_attempts):
            self.deadline.check(label)
            attempts[label] = attempt + 1
            guess = coarse.initial_guess(
                scene, q_start, q_goal, attempt, s.kto_control_points, self.rng
            )
            samples = s.kto_collision_samples * (1 + attempt // 2)
            path = coarse.optimize(scene, q_start, q_goal, guess, bound, samples)
            if path is None:
                failure = "SNOPT found no feasible trajectory"
                continue
            violations = dense_violations(scene, path, rules)
            if violations:
                failure = f"too close between samples: {violations[0]}"
                continue
            timed = retime(label, path, scene.plant, self.planner.limits)
            if timed is not None:
                return timed
            failure = "TOPP-RA found no timing"
        raise PlanningError(
            ErrorCode.PLANNING_FAILED,
            label,
            f"KTO failed after {attempts.get(label, 0)} attempts ({failure})",
        )


def dense_violations(scene: Scene, path, rules: ClearanceRules) -> list[str]:
    """Rule violations at samples no more than CHECK_JOINT_STEP apart (any joint)."""
    coarse_samples = path.vector_values(np.linspace(path.start_time(), path.end_time(), 50))
    travel = np.abs(np.diff(coarse_samples, axis=1)).max(axis=0).sum()
    count = max(COARSE_CHECK_SAMPLES, int(np.ceil(travel / CHECK_JOINT_STEP)))
    for q in path.vector_values(np.linspace(path.start_time(), path.end_time(), count)).T:
        violations = rules.violations(scene.clearance(q))
        if violations:
            return violations
    return []

"""What every plan is built from, shared by the pick-and-place and the strike planner
(the plans themselves, ``Segment``/``Plan``, are in ``plan_segments``).

* ``ArmPlanner``: the robot side kept between requests (shadow plants per finger opening,
  joint limits, clearance rules).
* ``RequestMotions``: the moves of one request under its deadline: IK solutions and
  straight TCP lines that keep their clearances, coarse KTO moves checked at dense
  samples, TOPP-RA timing.
"""

from __future__ import annotations

import time
from collections import Counter
from collections.abc import Iterator, Sequence

import numpy as np
from pydrake.math import RigidTransform

from dombot_description import DOMINO_SIZE
from dombot_description.scenario import Scenario
from dombot_planner import coarse
from dombot_planner.arm_reach import WristReach, elbow_not_up, faces_away
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.ik import PoseIK, straight_line
from dombot_planner.scene import (
    HELD,
    MOVING,
    OBSTACLES,
    PILE,
    SELF,
    TARGET,
    ClearanceRules,
    Scene,
    ShadowPlants,
    table_top,
)
from dombot_planner.settings import BUDGET_CLOCKS, PlannerSettings
from dombot_planner.timing import JointLimits, TimedPath, line_path, retime

MAX_JOINT_STEP = 0.1  # rad between line waypoints; more means the arm flips
COARSE_CHECK_SAMPLES = 120  # at least this many clearance checks of each KTO result ...
CHECK_JOINT_STEP = 0.01  # rad ... and no joint moving more than this between them
CHECK_MARGIN = 5e-4  # m the planner's own check adds to the required clearance
LIMIT_SAMPLES = 10  # per line piece, for the joint limit check of its spline
LINE_GRID_POINTS = 100  # TOPP-RA grid on a line (its end point is only loosely constrained)
LINE_END_MARGIN = 1e-3  # m beyond coarse_clearance where a line meets a coarse move
ESCAPE_DISTANCE = 0.08  # m: the longest straight line out of a start close to something
ESCAPE_TOLERANCE = 5e-4  # m an escape may come closer to anything than the start was
ENDS_SHARE = 0.9  # of its ends' clearance, the most a coarse move's bound asks for
QUERY_MARGIN = 1e-3  # m the scenes' distance queries look beyond what any rule reads
PERCEIVED = (TARGET, PILE)  # obstacles known only from perception (± 2 mm)
SEED_TURN = 0.8  # rad: random IK seeds turn joint 1 up to this far from the target
UP = np.array([0.0, 0.0, 1.0])
RISE_SAMPLES = 40  # along a coarse move, for the TCP's height
WRIST_OUT = "no IK: the wrist beyond the elbow's reach"
LINE_WRIST_OUT = "line leaves the reach: the wrist beyond the elbow's reach"

# A clearance check: the scene and the rules it must keep there.
Check = tuple[Scene, ClearanceRules]


def reasons(failures: Counter) -> str:
    return ", ".join(f"{reason}: {count}" for reason, count in failures.most_common()) or "none"


class Deadline:
    """A request's time budget on one of BUDGET_CLOCKS; ``elapsed`` is wall time."""

    def __init__(self, budget: float, clock: str = "wall") -> None:
        self.clock = clock
        self.now = getattr(time, BUDGET_CLOCKS[clock])
        self.began = time.monotonic()
        self.start = self.now()
        self.end = self.start + budget

    def check(self, stage: str) -> None:
        if self.now() > self.end:
            what = "CPU time" if self.clock == "cpu" else "time"
            raise PlanningError(
                ErrorCode.TIMEOUT, stage, f"{what} budget of {self.end - self.start:.2f} s used up"
            )

    def elapsed(self) -> float:
        return time.monotonic() - self.began


class ArmPlanner:
    """The robot side of planning, kept between requests (not thread-safe).

    ``plants``: shadow plants to share with another planner of the same scenario.
    """

    def __init__(
        self,
        scenario: Scenario,
        settings: PlannerSettings | None = None,
        plants: ShadowPlants | None = None,
    ) -> None:
        self.scenario = scenario
        self.settings = settings or PlannerSettings()
        self.plants = plants or ShadowPlants(scenario)
        plant = self.plants.get(DOMINO_SIZE[1]).plant  # any opening: only the arm's limits
        self.table = table_top(self.plants.get(DOMINO_SIZE[1]))
        self.wrist_reach = WristReach.of_scenario(scenario, self.plants.get(DOMINO_SIZE[1]))
        self.lower = plant.GetPositionLowerLimits()
        self.upper = plant.GetPositionUpperLimits()
        self.velocity_limits = plant.GetVelocityUpperLimits()
        self.limits = JointLimits(
            velocity=plant.GetVelocityUpperLimits() * self.settings.velocity_scale,
            acceleration=np.full(plant.num_velocities(), self.settings.acceleration_limit),
        )
        # moves with no domino in the hand
        self.free_limits = JointLimits(
            velocity=self.limits.velocity,
            acceleration=np.maximum(
                self.limits.acceleration, self.settings.free_acceleration_limits
            ),
        )

    @property
    def query_distance(self) -> float:
        """How far the scenes' distance queries look [m]: far enough that every distance
        the planner compares (the clearance rules, the escape's "no closer than at the
        start", a coarse move's bound from its ends) is measured, not the cap; pairs
        farther apart only cost the geometry engine work nobody reads."""
        s = self.settings
        read = max(
            (s.coarse_clearance + s.coarse_margin) / ENDS_SHARE,
            s.coarse_clearance + LINE_END_MARGIN + ESCAPE_TOLERANCE,
            s.pile_arm_clearance,
            s.fine_obstacle_clearance,
            s.pile_clearance,
        )
        return read + QUERY_MARGIN

    def coarse_rules(self, floor: float | None = None) -> ClearanceRules:
        """Everything ``floor`` (default coarse_clearance) from the table and dominoes."""
        clearance = self.settings.coarse_clearance if floor is None else floor
        rules = {(moving, other): clearance for moving in MOVING for other in OBSTACLES}
        rules.update({(moving, SELF): self.settings.self_clearance for moving in MOVING})
        return ClearanceRules(rules)

    def relaxed_rules(self, changes: dict[tuple[str, str], float]) -> ClearanceRules:
        """The coarse rules with ``changes`` (-inf: that pair may touch)."""
        return ClearanceRules({**self.coarse_rules().minimum, **changes})

    def line_end_rules(self) -> ClearanceRules:
        """Where a straight line meets a coarse move: LINE_END_MARGIN more than coarse."""
        return self.coarse_rules(self.settings.coarse_clearance + LINE_END_MARGIN)


class RequestMotions:
    """The moves of one request: its random seeds, deadline and start configuration."""

    def __init__(self, planner: ArmPlanner, start: np.ndarray, deadline: Deadline) -> None:
        self.planner, self.settings = planner, planner.settings
        self.start, self.deadline = start, deadline
        self.rng = np.random.default_rng(self.settings.seed)

    def check_start(self, scene: Scene, held_perceived: bool = False) -> None:
        """A start inside the table, a standing domino or the arm itself is refused.

        Perceived dominoes (the target, the pile; ``held_perceived``: the held one) are
        ±2 mm: the arm may already touch them where it stopped (e.g. after a grasp that
        missed), a held domino may touch the table where it is about to stand.
        """
        touching = self.planner.coarse_rules(floor=0.0).minimum

        def perceived(pair: tuple[str, str]) -> bool:
            return pair[1] in PERCEIVED or (held_perceived and pair[0] == HELD)

        rules = ClearanceRules(
            {pair: -np.inf if perceived(pair) else low for pair, low in touching.items()}
        )
        violations = rules.violations(scene.clearance(self.start))
        if violations:
            raise PlanningError(
                ErrorCode.INVALID_REQUEST, "start", f"start state in collision: {violations[0]}"
            )

    def escape(self, scene: Scene) -> np.ndarray | None:
        """Waypoints moving the TCP straight out of a start that is close to something.

        A coarse move cannot begin where its clearance does not hold (KTO then fails or
        times out): e.g. where a missed grasp left the pads a few millimetres above the
        table. None when the start keeps the line-end rules; otherwise a line straight up,
        else back along the approach axis (TCP z), ending at the first waypoint that keeps
        them, on which nothing comes closer to anything than it was at the start.
        """
        clearance = scene.clearance(self.start)
        end_rules = self.planner.line_end_rules()
        too_close = end_rules.violations(clearance)
        if not too_close:
            return None
        no_closer = ClearanceRules(
            {
                pair: min(minimum, clearance.get(pair, scene.query_distance) - ESCAPE_TOLERANCE)
                for pair, minimum in self.planner.coarse_rules().minimum.items()
            }
        )
        tcp = scene.tcp_pose(self.start)
        ik = PoseIK(scene, tcp.rotation())
        backwards = -tcp.rotation().matrix()[:, 2]
        failures: Counter = Counter()
        for direction in [UP] + ([backwards] if backwards @ UP < 0.99 else []):
            self.deadline.check("escape")
            line = straight_line(
                ik,
                self.start,
                tcp.translation(),
                ESCAPE_DISTANCE * direction,
                self.settings.waypoint_spacing,
                MAX_JOINT_STEP,
            )
            escape, why = self._escape_part(line, scene, no_closer, end_rules)
            if escape is not None:
                return escape
            failures[why] += 1
        raise PlanningError(
            ErrorCode.PLANNING_FAILED,
            "escape",
            f"the start is too close ({too_close[0]}) and no straight line of "
            f"{ESCAPE_DISTANCE * 1000:.0f} mm gets clear ({reasons(failures)})",
        )

    def seeds(self, first: list[np.ndarray], toward: np.ndarray) -> list[np.ndarray]:
        """IK seeds: ``first``, home, then seeded random configurations inside the limits
        that face ``toward`` (a TCP position): joint 1 within SEED_TURN of its azimuth,
        joint 2 leaning forward, so that IK lands in the arm's usual branch (see
        ``faces_away``)."""
        lower, upper = self.planner.lower, self.planner.upper
        middle, half = (lower + upper) / 2, 0.8 * (upper - lower) / 2
        count = self.settings.ik_random_seeds
        random = self.rng.uniform(middle - half, middle + half, (count, len(lower)))
        turn = np.arctan2(toward[1], toward[0]) + self.rng.uniform(-SEED_TURN, SEED_TURN, count)
        random[:, 0] = np.clip(turn, middle[0] - half[0], middle[0] + half[0])
        random[:, 1] = self.rng.uniform(0.0, middle[1] + half[1], count)
        return [*first, self.planner.scenario.home_position, *random]

    def _escape_part(
        self,
        line: np.ndarray | None,
        scene: Scene,
        rules: ClearanceRules,
        end_rules: ClearanceRules,
    ) -> tuple[np.ndarray | None, str]:
        """``line`` up to its first waypoint that keeps ``end_rules``, checked, or why not."""
        if line is None:
            return None, "line leaves the reach"
        for index, q in enumerate(line[2:], start=2):  # a C2 spline needs 3 waypoints
            if not first_violation(q, [(scene, end_rules)]):
                return self.checked_line(line[: index + 1], [(scene, rules)], end_rules)
        return None, "no waypoint clear"

    def clear_solutions(
        self,
        ik: PoseIK,
        position: np.ndarray,
        seeds: Sequence[np.ndarray],
        checks: Sequence[Check],
        failures: Counter,
        fixed_pairs: tuple[str, ...] = (),
    ) -> Iterator[np.ndarray]:
        """IK solutions for the TCP at ``position`` (one per seed) that pass ``checks``.

        ``failures`` counts why seeds gave none (once: a wrist point beyond the elbow's
        reach). ``fixed_pairs`` (e.g. "pads–standing"): distances that every configuration
        reaching the pose shares; one of them too close ends the search.
        """
        if not self.planner.wrist_reach.reaches(RigidTransform(ik.rotation, position)):
            failures[WRIST_OUT] += 1
            return
        for seed in seeds:
            self.deadline.check("ends")
            q = ik.solve(position, seed, seed)
            if q is None:
                failures["no IK"] += 1
                continue
            if faces_away(q, position):
                failures["arm turned away (shoulder over backwards)"] += 1
                continue
            if elbow_not_up(ik.scene, self.planner.scenario.arm_joints, q):
                failures["elbow not up"] += 1
                continue
            too_close = first_violation(q, checks)
            if not too_close:
                yield q
                continue
            failures[f"in collision at the pose ({too_close})"] += 1
            if too_close in fixed_pairs:
                return

    def clear_line(
        self,
        ik: PoseIK,
        q: np.ndarray,
        start: np.ndarray,
        offset: np.ndarray,
        checks: Sequence[Check],
        end_rules: ClearanceRules | None = None,
    ) -> tuple[np.ndarray | None, str]:
        """Waypoints moving the TCP from ``start`` (at ``q``) by ``offset``, or why not.

        Every waypoint after ``q`` keeps ``checks``; with ``end_rules`` the last one keeps
        those instead (where a coarse move begins or ends).
        """
        line = straight_line(ik, q, start, offset, self.settings.waypoint_spacing, MAX_JOINT_STEP)
        if line is None:
            return None, "line leaves the reach"
        return self.checked_line(line, checks, end_rules)

    def checked_line(
        self,
        line: np.ndarray,
        checks: Sequence[Check],
        end_rules: ClearanceRules | None = None,
    ) -> tuple[np.ndarray | None, str]:
        """``line`` if its spline keeps the joint limits and its waypoints ``checks`` (the
        last one ``end_rules`` instead, when given), else None and why."""
        if not self._spline_within_limits(line):
            return None, "line leaves the joint limits"
        if end_rules is not None:
            too_close = first_violation(line[-1], [(scene, end_rules) for scene, _ in checks])
            if too_close:
                return None, f"line end too close ({too_close})"
        for waypoint in line[1:-1] if end_rules is not None else line[1:]:
            too_close = first_violation(waypoint, checks)
            if too_close:
                return None, f"line too close ({too_close})"
        return line, ""

    def _spline_within_limits(self, waypoints: np.ndarray) -> bool:
        """The executed spline through the waypoints (each within the limits) may
        overshoot a joint limit between two of them; checked at LIMIT_SAMPLES per piece."""
        path = line_path(waypoints, self.settings.waypoint_spacing)
        times = np.linspace(0.0, path.end_time(), LIMIT_SAMPLES * (len(waypoints) - 1) + 1)
        q = path.vector_values(times).T
        return bool(np.all(q >= self.planner.lower) and np.all(q <= self.planner.upper))

    def timed_line(
        self,
        label: str,
        waypoints: np.ndarray,
        scene: Scene,
        tcp_speed: float | None = None,
        free: bool = False,
    ) -> TimedPath:
        """A straight line retimed by TOPP-RA (TCP speed ``tcp_speed``, default
        approach_speed; ``free``: no domino in the hand, ``free_limits``)."""
        spacing = self.settings.waypoint_spacing
        timed = retime(
            label,
            line_path(waypoints, spacing),
            scene.plant,
            self.planner.free_limits if free else self.planner.limits,
            fine=True,
            tcp=scene.tcp,
            tcp_speed=tcp_speed or self.settings.approach_speed,
            grid_points=LINE_GRID_POINTS,
        )
        if timed is None:
            length = spacing * (len(waypoints) - 1)
            raise PlanningError(
                ErrorCode.PLANNING_FAILED, label, f"TOPP-RA found no timing for a {length} m line"
            )
        return timed

    def coarse_move(
        self,
        label: str,
        scene: Scene,
        q_start: np.ndarray,
        q_goal: np.ndarray,
        attempts: dict[str, int],
        free: bool = False,
    ) -> TimedPath:
        """A KTO move from ``q_start`` to ``q_goal`` that passes the dense clearance check
        (``free``: no domino in the hand, retimed to ``free_limits``)."""
        s = self.settings
        ends = min(scene.minimum_distance(q_start), scene.minimum_distance(q_goal))
        bound = min(s.coarse_clearance + s.coarse_margin, ENDS_SHARE * ends)
        rules = self.planner.coarse_rules(min(s.coarse_clearance + CHECK_MARGIN, ENDS_SHARE * ends))
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
            rise = tcp_rise(scene, path)
            if rise > s.max_coarse_rise:  # the ends lie in different IK branches: so will any
                failure = f"the TCP swung {rise:.2f} m above the higher end"
                break
            limits = self.planner.free_limits if free else self.planner.limits
            timed = retime(label, path, scene.plant, limits)
            if timed is not None:
                return timed
            failure = "TOPP-RA found no timing"
        raise PlanningError(
            ErrorCode.PLANNING_FAILED,
            label,
            f"KTO failed after {attempts.get(label, 0)} attempts ({failure})",
        )


def first_violation(q: np.ndarray, checks: Sequence[Check]) -> str:
    """The pair of classes (e.g. "pads–standing") first found too close at ``q``, or ""."""
    for scene, rules in checks:
        violations = rules.violations(scene.clearance(q))
        if violations:
            return violations[0].split(" ")[0]
    return ""


def tcp_rise(scene: Scene, path) -> float:
    """How far [m] the TCP rises along ``path`` above the higher of its ends."""
    samples = path.vector_values(np.linspace(path.start_time(), path.end_time(), RISE_SAMPLES))
    heights = [scene.tcp_pose(q).translation()[2] for q in samples.T]
    return max(heights) - max(heights[0], heights[-1])


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

"""Strike planning (/plan_strike): the move that knocks a run down, and sweeps.

The closed fingers are one blunt pusher (two 16 × 8 mm pads side by side, 60 mm long),
pointing down. Plan of a request:

1. *Strike pose.* For each pusher orientation (``pusher_rotations``: straight down, then
   leaning sideways), the TCP pose that puts the fingertips at ``strike_height`` of the
   domino's height and the pads ``PUSHER_STANDOFF`` behind its back face (behind = against
   its body z, the direction it topples). IK there, then three straight TCP lines at that
   orientation: the descent from ``strike_approach_height`` above (clear of everything by
   ``coarse_clearance``), the push along body z to ``push_distance`` past the back face
   (only the pads may touch, and only the struck domino) and the retreat up and back to
   where the descent began (the struck domino has gone forward).
2. *Approach* by KTO from the start to the top of the descent, fingers closed, clear of
   the table and every domino of the run by ``coarse_clearance``; a start closer than that
   (e.g. at the end of a placement's final line) is left first by a straight line up
   (``RequestMotions.escape``).
3. *Timing* by TOPP-RA: the push at ``push_speed`` (up to ~0.1 m/s the pads reach it
   within the standoff), the descent and the retreat at ``approach_speed``.

Segments: ``close_gripper`` (only if the start may have the fingers open), ``approach``,
``push``, ``retreat``.

A *sweep* is the same move for a domino in any pose, pushed along a horizontal direction
the request gives (``StrikeRequest.sweep``), its fingertips at ``SWEEP_HEIGHT`` of the
domino's vertical extent (low, so a flat domino slides rather than the pads riding over
it): the bring-up clears fallen dominoes out of the run's way when no grasp reaches
them.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterator
from dataclasses import dataclass, field

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description.grasp import gripper_geometry
from dombot_description.pusher import PUSHER_STANDOFF, SWEEP_HEIGHT
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.ik import PoseIK
from dombot_planner.motion import UP, ArmPlanner, Deadline, RequestMotions, reasons
from dombot_planner.plan_segments import GRIPPER_CLOSE, Plan, Segment
from dombot_planner.request import StrikeRequest, box_corners, check_strike_request
from dombot_planner.scene import PADS, STANDING, TABLE, TARGET, Scene

CLOSED = 0.0  # m: the pads touch
CLOSED_TOLERANCE = 0.001  # m: a start opening up to this needs no close command
PUSHER_TILT = math.radians(30.0)  # sideways lean of the pusher where upright is out of reach
# The pads' path is the same for every arm configuration and pusher orientation: if it
# is too close to the table or a domino, the strike itself is blocked, not the arm.
PUSHER_BLOCKED = ("pads–table", "pads–standing", "pads–target")


def blocks_pusher(why: str) -> bool:
    """A failure reason that names the pads against the table or a domino."""
    return any(pair in why for pair in PUSHER_BLOCKED)


def pusher_corners() -> np.ndarray:
    """Corners (16 × 3, TCP frame) of the closed pads: the pusher."""
    signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
    return np.vstack(
        [
            (box.pose @ (signs * box.size / 2).T).T
            for box in gripper_geometry().pad_boxes_in_tcp(CLOSED)
        ]
    )


def push_direction(request: StrikeRequest) -> np.ndarray:
    """Horizontal unit vector of the push: a sweep's, else the domino's body z (where it
    topples)."""
    if request.sweep is not None:
        return np.asarray(request.sweep, dtype=float)
    along = request.domino_pose.rotation().matrix()[:, 2] * [1.0, 1.0, 0.0]
    return along / np.linalg.norm(along)


def pusher_rotations(direction: np.ndarray) -> list[RotationMatrix]:
    """TCP orientations for a push along ``direction``, the preferred first.

    Fingers pointing straight down, closing across then along the push; then the same
    leaning PUSHER_TILT to either side of the push (a turn about it, so the pads' front
    stays square to the domino): near the arm base the wrist then comes far enough from the
    shoulder for the elbow, which a vertical pusher closer than ~0.40 m from the base axis
    does not allow.
    """
    across = np.cross(UP, direction)
    down = -UP
    vertical = [
        RotationMatrix(np.column_stack([np.cross(y, down), y, down]))
        for y in (across, -across, direction, -direction)
    ]
    tilted = [
        RotationMatrix(AngleAxis(angle, direction)) @ rotation
        for angle in (PUSHER_TILT, -PUSHER_TILT)
        for rotation in vertical
    ]
    return vertical + tilted


def strike_pose(
    domino_pose: RigidTransform,
    rotation: RotationMatrix,
    direction: np.ndarray,
    height: float,
    standoff: float,
) -> RigidTransform:
    """TCP pose with the fingertips at ``height`` × the domino's vertical extent above its
    lowest corner and the pads ``standoff`` behind its hindmost corner along ``direction``."""
    corners = (rotation.matrix() @ pusher_corners().T).T
    box = box_corners(domino_pose)
    centre = domino_pose.translation()
    back = (box @ direction).min() - centre @ direction
    position = centre + (back - standoff - (corners @ direction).max()) * direction
    base, top = box[:, 2].min(), box[:, 2].max()
    position[2] = base + height * (top - base) - corners[:, 2].min()
    return RigidTransform(rotation, position)


@dataclass(kw_only=True)
class StrikePlan(Plan):
    strike_pose: RigidTransform  # TCP where the push begins
    closes_gripper: bool = False  # the plan closes the fingers first


@dataclass
class Lines:
    """The three straight lines of one strike pose (waypoints, index 0 first executed)."""

    strike_pose: RigidTransform
    descent: np.ndarray
    push: np.ndarray
    retreat: np.ndarray


class StrikePlanner(ArmPlanner):
    """Plans /plan_strike requests; keeps shadow plants between requests (not thread-safe)."""

    def check(self, request: StrikeRequest) -> None:
        """What can be said without planning; raises PlanningError."""
        check_strike_request(request, self.settings, self.table)

    def plan(self, request: StrikeRequest) -> StrikePlan:
        """A plan for ``request``; raises PlanningError with a code and the failing stage."""
        self.check(request)
        deadline = Deadline(
            request.time_budget or self.settings.default_time_budget, self.settings.budget_clock
        )
        plan = StrikePlanning(self, request, deadline).plan()
        plan.planning_time = deadline.elapsed()
        return plan


@dataclass
class StrikeSearch:
    orientations: int = 0
    failures: Counter = field(default_factory=Counter)

    def error(self) -> PlanningError:
        blocked = any(blocks_pusher(why) for why in self.failures)
        code = ErrorCode.PLACE_IN_COLLISION if blocked else ErrorCode.PLACE_UNREACHABLE
        return PlanningError(
            code,
            "strike",
            f"no collision-free IK and push lines for any of {self.orientations} pusher "
            f"orientations ({reasons(self.failures)})",
        )


class StrikePlanning(RequestMotions):
    """The planning of one strike request: scenes, rules, push geometry."""

    def __init__(self, planner: StrikePlanner, request: StrikeRequest, deadline: Deadline):
        super().__init__(planner, request.start, deadline)
        self.request = request
        s = self.settings
        self.direction = push_direction(request)
        self.height = s.strike_height if request.sweep is None else SWEEP_HEIGHT
        self.push_length = PUSHER_STANDOFF + (request.push_distance or s.push_distance)
        self.push_speed = request.push_speed or s.push_speed
        shadow, tcp = planner.plants.get(CLOSED), planner.scenario.tcp_frame
        reach = planner.query_distance
        self.run = Scene(shadow, tcp, request.standing, request.domino_pose, query_distance=reach)
        self.after = Scene(shadow, tcp, request.standing, query_distance=reach)  # struck one gone
        deadline.check("scene")  # building the scenes counts against the budget
        # the pads may come as near the table as on a placement: a sweep pushes low
        low_pads = {(PADS, TABLE): s.pad_table_clearance}
        pads_near_run = {**low_pads, (PADS, STANDING): s.fine_obstacle_clearance}
        self.rules = {
            "descent": planner.relaxed_rules(low_pads),
            "push": planner.relaxed_rules({**pads_near_run, (PADS, TARGET): -math.inf}),
            "retreat": planner.relaxed_rules(pads_near_run),
            "top": planner.line_end_rules(),
        }
        self.search = StrikeSearch()
        self.escape_line: np.ndarray | None = None  # out of a start close to something

    def plan(self) -> StrikePlan:
        self.check_start(self.run)
        self.escape_line = self.escape(self.run)
        connect_error = None
        for lines in self._lines():
            try:
                return self._connect(lines)
            except PlanningError as error:
                if error.code == ErrorCode.TIMEOUT:
                    raise
                connect_error = error  # try the next strike pose
        raise connect_error or self.search.error()

    def _lines(self) -> Iterator[Lines]:
        """Strike poses whose descent, push and retreat lines keep their clearances."""
        rotations = pusher_rotations(self.direction)
        self.search.orientations = len(rotations)
        checks = [(self.run, self.rules["descent"])]
        for rotation in rotations:
            pose = strike_pose(
                self.request.domino_pose, rotation, self.direction, self.height, PUSHER_STANDOFF
            )
            ik = PoseIK(self.run, rotation)
            at = pose.translation()
            seeds = self.seeds([self.start], at)
            failures = self.search.failures
            for q in self.clear_solutions(ik, at, seeds, checks, failures, PUSHER_BLOCKED):
                lines = self._lines_at(ik, q, pose)
                if isinstance(lines, Lines):
                    yield lines
                    break  # other seeds give the same pusher path: next orientation
                failures[lines] += 1
                if blocks_pusher(lines):
                    break  # so would every other seed

    def _lines_at(self, ik: PoseIK, q: np.ndarray, pose: RigidTransform) -> Lines | str:
        """The three lines from ``q`` at the strike ``pose``, or why one is blocked."""
        at, rules = pose.translation(), self.rules
        descent = self.settings.strike_approach_height * UP
        push = self.push_length * self.direction
        down, why = self.clear_line(
            ik, q, at, descent, [(self.run, rules["descent"])], rules["top"]
        )
        if down is None:
            return f"descent {why}"
        pushed, why = self.clear_line(ik, q, at, push, [(self.run, rules["push"])])
        if pushed is None:
            return f"push {why}"
        back = [(self.after, rules["retreat"])]
        up, why = self.clear_line(ik, pushed[-1], at + push, descent - push, back, rules["top"])
        if up is None:
            return f"retreat {why}"
        return Lines(pose, down[::-1], pushed, up)

    def _connect(self, lines: Lines) -> StrikePlan:
        """The coarse approach to the top of the descent, retimed into segments."""
        attempts: dict[str, int] = {}
        escape = self.escape_line
        begin = self.start if escape is None else escape[-1]
        approach = self.coarse_move("approach", self.run, begin, lines.descent[0], attempts)
        self.deadline.check("retiming")
        out = [] if escape is None else [self.timed_line("escape", escape, self.run)]
        descend = self.timed_line("descend", lines.descent, self.run)
        push = self.timed_line("push", lines.push, self.run, self.push_speed)
        retreat = self.timed_line("retreat", lines.retreat, self.after)
        segments = [
            Segment("approach", [*out, approach, descend], CLOSED),
            Segment("push", [push], CLOSED),
            Segment("retreat", [retreat], CLOSED),
        ]
        opening = self.request.finger_opening
        closes = opening is None or opening > CLOSED_TOLERANCE
        if closes:
            close = Segment(
                "close_gripper",
                [],
                opening or 0.0,
                GRIPPER_CLOSE,
                CLOSED,
                self.settings.grip_force,
                start=self.start,
            )
            segments.insert(0, close)
        return StrikePlan(
            segments,
            strike_pose=lines.strike_pose,
            closes_gripper=closes,
            kto_attempts=attempts,
        )

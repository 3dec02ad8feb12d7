"""What the arm job asks of the cell, in plain types: the ``Cell`` protocol.

Poses are 4x4 homogeneous transforms (numpy) in the world frame, domino body frames as
in dombot_msgs/DominoDetection; points are N x 3 arrays (types that hold arrays compare
by identity). ``cell_client.CellClient`` implements it over the nodes' services and
actions; anything else that answers the same (an in-process simulation, a test's
script) runs the same task core.
"""

from __future__ import annotations

from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import IntEnum
from typing import Generic, Protocol, TypeVar

import numpy as np
from pydrake.math import RigidTransform

from dombot_planner.errors import ErrorCode
from dombot_planner.request import PickPlaceRequest
from dombot_planner.request import StrikeRequest as PlannerStrikeRequest

Pose = np.ndarray  # 4x4, world frame
T = TypeVar("T")


class CellError(RuntimeError):
    """The cell did not answer (a call timed out, a goal was refused)."""


@dataclass(frozen=True)
class Later(Generic[T]):
    """An answer asked for now and taken later: calling it waits for the answer (and
    raises ``CellError`` when none comes); ``answered()`` says, without waiting, whether
    it has come (a caller that must not wait asks first)."""

    wait: Callable[[], T]
    answered: Callable[[], bool] = lambda: True

    def __call__(self) -> T:
        return self.wait()


class Posture(IntEnum):
    """How a detected domino lies (dombot_msgs/DominoDetection's POSTURE_*)."""

    FLAT = 0
    ON_EDGE = 1
    UPRIGHT = 2
    TILTED = 3  # leaning on other dominoes


class Seen(IntEnum):
    """What perception sees where a domino should stand (CheckPlacement's statuses)."""

    STANDING = 0
    FALLEN = 1
    MISSING = 2
    NOT_SEEN = 3  # no camera sees the place well enough (hidden behind something)


class GripperEvent(IntEnum):
    """What the gripper does once a segment's trajectory ends."""

    NONE = 0
    OPEN = 1
    CLOSE = 2


@dataclass(frozen=True, eq=False)
class Detection:
    """One pile domino perception found."""

    pose: Pose
    posture: Posture
    score: float = 0.0  # grasp score; 0: no room for the fingers found
    clearance: float = 0.0  # m beside the finger contact sides
    grasp: Pose | None = None  # perception's grasp (TCP pose), clear of every seen point


@dataclass(frozen=True, eq=False)
class Detections:
    """A look at the pile: the detections (best grasp first) and the points seen on none."""

    success: bool
    message: str = ""
    dominoes: tuple[Detection, ...] = ()
    unexplained: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))


@dataclass(frozen=True, eq=False)
class PlacementCheck:
    """Perception's look at where dominoes should stand, one entry per expected pose."""

    success: bool
    message: str = ""
    status: tuple[Seen, ...] = ()
    measured: tuple[Pose, ...] = ()  # the expected pose when MISSING or NOT_SEEN
    position_error: tuple[float, ...] = ()  # m, horizontal
    tilt: tuple[float, ...] = ()  # rad of the length axis from vertical


@dataclass(frozen=True, eq=False)
class Trajectory:
    """Joint positions and velocities at times [s] from its start."""

    joint_names: tuple[str, ...]
    times: np.ndarray  # (N,)
    positions: np.ndarray  # (N, joints)
    velocities: np.ndarray  # (N, joints); (0, joints) when none are given

    @property
    def duration(self) -> float:
        return float(self.times[-1]) if len(self.times) else 0.0

    def reversed(self, lead: float) -> Trajectory:
        """The same path run backwards in time (velocities negated), starting ``lead``
        seconds late: the arm may have stopped short of the path's end (blocked by what it
        touched), and the controller eases it from where it is onto the path over that time."""
        return Trajectory(
            self.joint_names,
            lead + self.duration - self.times[::-1],
            self.positions[::-1].copy(),
            -self.velocities[::-1],
        )


NO_TRAJECTORY = Trajectory((), np.zeros(0), np.zeros((0, 0)), np.zeros((0, 0)))


@dataclass(frozen=True, eq=False)
class Segment:
    """One piece of a plan: a trajectory, then a gripper event."""

    label: str  # e.g. "approach_grasp", "transfer", "place", "retreat"
    trajectory: Trajectory = NO_TRAJECTORY
    gripper_after: GripperEvent = GripperEvent.NONE
    gripper_position: float = 0.0  # m finger opening
    gripper_max_effort: float = 0.0  # N


@dataclass(frozen=True, eq=False)
class Plan:
    """The planner's answer to a place or strike request."""

    success: bool
    error: ErrorCode = ErrorCode.SUCCESS
    message: str = ""
    segments: tuple[Segment, ...] = ()
    held_above_place: Pose | None = None  # the hold where "transfer" ends, as planned
    foreseen: bool = False  # a refusal told without asking the planner (task.picking)


@dataclass(frozen=True, eq=False)
class PlaceRequest:
    """Pick ``domino`` and place it at ``place`` (or, ``holding``: carry it from the hand)."""

    domino: Pose
    place: Pose
    standing: tuple[Pose, ...] = ()  # obstacles to keep clear of
    grasp: Pose | None = None  # tried first; None: the planner's own grasps
    pile: tuple[Pose, ...] = ()  # neighbours the pads keep clear of
    pile_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    pads_into_pile: bool = False  # only the gripper body and arm keep clear of ``pile``
    holding: bool = False
    time_budget: float = 0.0  # s; 0: the planner's default
    # the arm's joints (name → rad) the plan starts from; None: where the arm stands when
    # the planner takes the request
    start: Mapping[str, float] | None = None


def planner_request(request: PlaceRequest, start: np.ndarray) -> PickPlaceRequest:
    """``request`` as the planner's ``PickPlaceRequest``, planned from ``start`` (the arm's
    joint positions)."""
    return PickPlaceRequest(
        domino_pose=RigidTransform(request.domino),
        place_pose=RigidTransform(request.place),
        start=start,
        grasp_pose=None if request.grasp is None else RigidTransform(request.grasp),
        standing=tuple(RigidTransform(p) for p in request.standing),
        pile=tuple(RigidTransform(p) for p in request.pile),
        pile_points=request.pile_points.reshape(-1, 3),
        pads_into_pile=request.pads_into_pile,
        time_budget=request.time_budget,
        holding=request.holding,
    )


@dataclass(frozen=True, eq=False)
class StrikeRequest:
    """Knock ``domino`` over (``sweep`` None) or push it along ``sweep`` (x, y) that far."""

    domino: Pose
    standing: tuple[Pose, ...] = ()
    sweep: np.ndarray | None = None
    push_distance: float = 0.0  # m; 0: the planner's default
    time_budget: float = 0.0


def planner_strike_request(
    request: StrikeRequest, start: np.ndarray, opening: float | None
) -> PlannerStrikeRequest:
    """``request`` as the planner's ``StrikeRequest``, planned from ``start`` (the arm's
    joint positions) with the fingers ``opening`` apart (None: not known)."""
    return PlannerStrikeRequest(
        domino_pose=RigidTransform(request.domino),
        start=start,
        finger_opening=opening,
        standing=tuple(RigidTransform(p) for p in request.standing),
        push_distance=request.push_distance,
        time_budget=request.time_budget,
        sweep=None if request.sweep is None else np.array([*request.sweep[:2], 0.0]),
    )


# What a caller does while it waits for a motion to end: called again and again until it
# ends, on the caller's own thread (the job's state as the caller left it); it neither
# moves the arm or the fingers nor waits long.
Meanwhile = Callable[[], None]


@dataclass(frozen=True)
class Motion:
    """How a trajectory ran: ``error`` says why it did not reach its end."""

    ok: bool
    error: str = ""


class Cell(Protocol):
    """Everything the task loop asks of the world. Calls block until answered and raise
    ``CellError`` when no answer comes."""

    @property
    def sim_time(self) -> float:  # s of the cell's clock
        ...

    @property
    def time_spent(self) -> Mapping[str, float]:
        """Simulated seconds spent so far waiting for each activity (motion, planning, ...)."""
        ...

    def reset(self, pile: int, seed: int) -> str:
        """Pour a new pile; what was done, in words."""
        ...

    def detect(self, not_before: float) -> Detections:
        """Perception's look at the pile in frames stamped at or after ``not_before``."""
        ...

    def detect_later(self, not_before: float) -> Later[Detections]:
        """Ask for ``detect(not_before)`` now and take the answer later: perception looks
        while the arm goes on."""
        ...

    def check_placement(
        self, expected: Sequence[Pose], in_hand: bool = False, not_before: float = 0.0
    ) -> PlacementCheck: ...

    def plan_place(self, request: PlaceRequest) -> Plan: ...

    def plan_place_later(self, request: PlaceRequest) -> Later[Plan]:
        """Ask for ``plan_place(request)`` now and take the answer later: the planner
        plans while the arm retreats and perception checks a placement."""
        ...

    def plan_strike(self, request: StrikeRequest) -> Plan: ...

    def execute(
        self,
        trajectory: Trajectory,
        goal_tolerance: float = 0.0,
        path_tolerance: float = 0.0,
        *,
        meanwhile: Meanwhile | None = None,
    ) -> Motion:
        """Run ``trajectory``; each joint must end within ``goal_tolerance`` rad of its last
        point (0: the controller's default). With ``path_tolerance``, a joint that falls
        that far [rad] behind the trajectory aborts it at once, the arm held where it is
        (something pressed against: 0, not checked). ``meanwhile`` is called now and
        then until it has ended (``Meanwhile``)."""
        ...

    def gripper(
        self, position: float, max_effort: float, *, meanwhile: Meanwhile | None = None
    ) -> float:
        """Move the fingers to the opening ``position`` [m]; where they stopped [m].
        ``meanwhile`` as ``execute``'s."""
        ...

    def gripper_later(self, position: float, max_effort: float) -> Later[float]:
        """Start ``gripper(position, max_effort)`` now and take where the fingers stopped
        later: they move while the arm runs a trajectory."""
        ...

    def wait_for_sim_time(self, seconds: float) -> None: ...

    def joints(self) -> tuple[list[str], list[float]]:
        """The arm's and fingers' joint names and positions now."""
        ...

    def truth(self, newer_than: float) -> list[tuple[str, Pose]]:
        """The simulator's dominoes (name, pose) for the report only: nothing acts on it."""
        ...

    def picture(self, camera: str, not_before: float) -> np.ndarray:
        """An RGB frame (height x width x 3) of ``camera``, for the report."""
        ...

"""One scripted ``Cell`` for the task core's tests: each answer is what the test says,
and every call is recorded, so a test drives the real loop and reads what it asked."""

from __future__ import annotations

from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np

from dombot_bringup.task.cell import (
    CellError,
    Detection,
    Detections,
    GripperEvent,
    Later,
    Meanwhile,
    Motion,
    PlacementCheck,
    PlaceRequest,
    Plan,
    Pose,
    Posture,
    Seen,
    Segment,
    StrikeRequest,
    Trajectory,
)
from dombot_description import DOMINO_SIZE
from dombot_planner.errors import ErrorCode

HELD = DOMINO_SIZE[1] - 0.0005  # m: fingers closed on a flat hold (the pads' give)


def lying(x: float, y: float) -> Pose:
    """A domino lying flat at (x, y)."""
    pose = np.eye(4)
    pose[:3, 3] = [x, y, 0.00375]
    return pose


def shifted(pose: Pose, dx: float) -> Pose:
    moved = pose.copy()
    moved[0, 3] += dx
    return moved


def flat(x: float, y: float = -0.3, posture: Posture = Posture.FLAT) -> Detection:
    """A pile detection perception scored, with 10 mm beside the fingers."""
    return Detection(lying(x, y), posture, score=0.9, clearance=0.01)


def path(label: str, start: float = 0.0, end: float = 0.0, duration: float = 1.0) -> Trajectory:
    """A one-joint trajectory named after ``label``: what ran is read from its joint name."""
    return Trajectory(
        (label,), np.array([0.0, duration]), np.array([[start], [end]]), np.zeros((2, 1))
    )


def planned(*segments: Segment | str, held_above: Pose | None = None) -> Plan:
    """A plan of ``segments`` (labels: segments with a trajectory named after them)."""
    return Plan(
        True,
        message="planned",
        segments=tuple(s if isinstance(s, Segment) else Segment(s, path(s)) for s in segments),
        held_above_place=held_above,
    )


def refused(code: ErrorCode = ErrorCode.PLACE_IN_COLLISION, message: str = "refused") -> Plan:
    return Plan(False, code, message)


def seen(
    statuses: Sequence[Seen],
    errors: Sequence[float] | None = None,
    tilts: Sequence[float] | None = None,
) -> Callable[[Sequence[Pose], bool], PlacementCheck]:
    """Placement checks answering ``statuses`` (one per expected pose), each measured
    ``errors`` off in x (1 mm unless told) and tilted ``tilts`` (0 unless told); expected
    poses beyond those (e.g. the slots ``checks.look_again`` asks after the lying dominoes) are
    empty places (MISSING)."""

    def check(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        told = len(statuses)
        if len(expected) < told:
            raise ValueError(f"{told} statuses scripted for {len(expected)} expected poses")
        empty = len(expected) - told
        off = [*(errors or [0.001] * told), *[0.0] * empty]
        return PlacementCheck(
            True,
            status=(*statuses, *[Seen.MISSING] * empty),
            measured=tuple(shifted(p, e) for p, e in zip(expected, off, strict=True)),
            position_error=tuple(off),
            tilt=(*(tilts or [0.0] * told), *[0.0] * empty),
        )

    return check


def all_standing(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
    return seen([Seen.STANDING] * len(expected))(expected, in_hand)


@dataclass
class ScriptedCell:
    """A cell whose answers the test scripts; the calls it got, in order."""

    pile: list[Detection] = field(default_factory=list)  # seen on every look
    unexplained: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    place: Callable[[PlaceRequest], Plan] = lambda request: refused(ErrorCode.GRASP_UNREACHABLE)
    strike: Callable[[StrikeRequest], Plan] = lambda request: refused()
    placements: Callable[[Sequence[Pose], bool], PlacementCheck] = all_standing
    grip: float = HELD  # where the fingers stop when closed
    looks_without_frames: int = 0  # the first looks find no camera frames
    looks_answer_at_once: bool = True  # a look asked for later has answered when asked
    dominoes: list[tuple[str, Pose]] = field(default_factory=list)  # the simulator's truth
    # the arm's and fingers' joints: each trajectory run moves its joints to its end
    joint_positions: tuple[list[str], list[float]] = ([], [])
    motion: Callable[[Trajectory], Motion] = lambda trajectory: Motion(True)  # how each ran
    sim_time: float = 0.0
    time_spent: dict[str, float] = field(default_factory=dict)
    # what the task asked
    resets: list[tuple[int, int]] = field(default_factory=list)  # (pile, seed) poured
    looks: list[float] = field(default_factory=list)  # each look's not_before
    place_requests: list[PlaceRequest] = field(default_factory=list)
    strike_requests: list[StrikeRequest] = field(default_factory=list)
    checks: list[tuple[list[Pose], bool, float]] = field(default_factory=list)
    executed: list[Trajectory] = field(default_factory=list)
    path_tolerances: list[float] = field(default_factory=list)  # each execute's [rad]
    openings: list[float] = field(default_factory=list)  # every gripper command's opening
    # of those sent without waiting: (opening, trajectories executed before it was sent)
    openings_while_moving: list[tuple[float, int]] = field(default_factory=list)
    truths_asked: list[float] = field(default_factory=list)  # each truth's newer_than
    # while a motion's ``meanwhile`` runs (once, after ``motion``'s verdict): what moves,
    # its trajectory's first joint (``path``'s label) or "gripper"; "" otherwise
    waiting_on: str = ""

    def reset(self, pile: int, seed: int) -> str:
        self.resets.append((pile, seed))
        return f"poured {pile} (seed {seed})"

    def detect(self, not_before: float) -> Detections:
        self.looks.append(not_before)
        if len(self.looks) <= self.looks_without_frames:
            return Detections(False, "no colour received yet")
        return Detections(True, "", tuple(self.pile), self.unexplained)

    def detect_later(self, not_before: float) -> Later[Detections]:
        answer = self.detect(not_before)
        return Later(lambda: answer, lambda: self.looks_answer_at_once)

    def check_placement(
        self, expected: Sequence[Pose], in_hand: bool = False, not_before: float = 0.0
    ) -> PlacementCheck:
        self.checks.append((list(expected), in_hand, not_before))
        return self.placements(expected, in_hand)

    def plan_place(self, request: PlaceRequest) -> Plan:
        self.place_requests.append(request)
        return self.place(request)

    def plan_place_later(self, request: PlaceRequest) -> Later[Plan]:
        answer = self.plan_place(request)
        return Later(lambda: answer)

    def plan_strike(self, request: StrikeRequest) -> Plan:
        self.strike_requests.append(request)
        return self.strike(request)

    def execute(
        self,
        trajectory: Trajectory,
        goal_tolerance: float = 0.0,
        path_tolerance: float = 0.0,
        *,
        meanwhile: Meanwhile | None = None,
    ) -> Motion:
        self.executed.append(trajectory)
        self.path_tolerances.append(path_tolerance)
        motion = self.motion(trajectory)
        self.wait(trajectory.joint_names[0] if trajectory.joint_names else "", meanwhile)
        if motion.ok and len(trajectory.times):
            names, positions = self.joint_positions
            joints = dict(zip(names, positions, strict=True))
            joints.update(zip(trajectory.joint_names, trajectory.positions[-1], strict=True))
            self.joint_positions = (list(joints), list(joints.values()))
        return motion

    def gripper(
        self, position: float, max_effort: float, *, meanwhile: Meanwhile | None = None
    ) -> float:
        self.openings.append(position)
        self.wait("gripper", meanwhile)
        return self.grip if max_effort > 0.0 else position

    def wait(self, moving: str, meanwhile: Meanwhile | None) -> None:
        """Call ``meanwhile`` once, while ``moving`` moves (``waiting_on``)."""
        if meanwhile is None:
            return
        self.waiting_on = moving
        try:
            meanwhile()
        finally:
            self.waiting_on = ""

    def gripper_later(self, position: float, max_effort: float) -> Later[float]:
        stopped = self.gripper(position, max_effort)
        self.openings_while_moving.append((position, len(self.executed)))
        return Later(lambda: stopped)

    def wait_for_sim_time(self, seconds: float) -> None:
        self.sim_time += seconds

    def joints(self) -> tuple[list[str], list[float]]:
        return self.joint_positions

    def truth(self, newer_than: float) -> list[tuple[str, Pose]]:
        self.truths_asked.append(newer_than)
        return self.dominoes

    def picture(self, camera: str, not_before: float) -> np.ndarray:
        raise CellError(f"no {camera} here: the report goes without pictures")


def closing(label: str = "approach_grasp") -> Segment:
    """A segment that closes the fingers on the domino at its end."""
    return Segment(label, path(label), GripperEvent.CLOSE, 0.0, 40.0)

"""Is this arm or gripper goal met? One answer for the simulator's action servers and for
the benchmarks that drive the simulated world directly.

The rules follow control_msgs FollowJointTrajectory as joint_trajectory_controller reads
them: a path tolerance aborts the goal the moment it is exceeded; after the trajectory's
end every joint must come within its goal tolerance, allowing ``settle`` seconds
(``goal_time_tolerance``) to get there. A gripper goal ends when the fingers reach the
opening, stall on an object (still while pushing at the force limit) or time out.
Plain code with no ROS or Drake types: times are simulated seconds, positions numpy.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from enum import Enum

import numpy as np

DEFAULT_GOAL_TOLERANCE = 0.01  # rad per joint at the trajectory's end
GOAL_SETTLE_TIME = 0.5  # s simulated allowed after the trajectory ends, by default
GRIPPER_REACHED = 1e-3  # m from the commanded opening
GRIPPER_STALL_SPEED = 1e-3  # m/s
GRIPPER_STALL_TIME = 0.1  # s simulated below that speed
GRIPPER_START_GRACE = 0.05  # s: fingers at rest before they start are not stalled
GRIPPER_SPARE_TIME = 1.0  # s allowed beyond a full stroke at full speed
FORCE_LIMIT_SHARE = 0.99  # pushing at this share of the limit counts as at the limit


class Outcome(Enum):
    RUNNING = "running"
    SUCCEEDED = "succeeded"
    PATH_TOLERANCE_VIOLATED = "path tolerance violated"
    GOAL_TOLERANCE_VIOLATED = "goal tolerance violated"


@dataclass(frozen=True)
class Tolerances:
    """Per-joint position tolerances [rad] (<= 0: not checked) and the settle time [s]."""

    path: np.ndarray
    goal: np.ndarray
    settle: float = GOAL_SETTLE_TIME

    @classmethod
    def defaults(cls, joints: int) -> Tolerances:
        """No path tolerance, DEFAULT_GOAL_TOLERANCE at the end, GOAL_SETTLE_TIME."""
        return cls(np.full(joints, -1.0), np.full(joints, DEFAULT_GOAL_TOLERANCE))


def joint_tolerances(
    given: Sequence[tuple[str, float]], names: Sequence[str], default: float
) -> np.ndarray:
    """Per-joint tolerance from (joint, tolerance) pairs, as control_msgs reads them:
    0 means the default, < 0 means not checked; joints not named get the default."""
    values = np.full(len(names), default)
    for name, value in given:
        if name in names and value != 0.0:
            values[list(names).index(name)] = value
    return values


@dataclass(frozen=True)
class Verdict:
    """What the monitor says now; ``error`` is the joint error it judged (actual - desired)."""

    outcome: Outcome
    message: str = ""
    error: np.ndarray | None = None


class TrajectoryMonitor:
    """Judges one trajectory goal from samples of (time, actual, desired) positions."""

    def __init__(self, names: Sequence[str], end: float, tolerances: Tolerances) -> None:
        self.names = list(names)
        self.end = end
        self.tolerances = tolerances
        self.worst = 0.0  # largest absolute joint error seen along the way [rad]

    def check(self, now: float, actual: np.ndarray, desired: np.ndarray) -> Verdict:
        error = np.asarray(actual, dtype=float) - np.asarray(desired, dtype=float)
        magnitude = np.abs(error)
        self.worst = max(self.worst, float(magnitude.max(initial=0.0)))
        path = self.tolerances.path
        violated = (path > 0.0) & (magnitude > path)
        if violated.any():
            j = int(np.argmax(violated))
            return Verdict(
                Outcome.PATH_TOLERANCE_VIOLATED,
                f"path tolerance violated on {self.names[j]}: {magnitude[j]:.4f} rad off the "
                f"trajectory (allowed {path[j]:.4f} rad)",
                error,
            )
        if now < self.end:
            return Verdict(Outcome.RUNNING, error=error)
        goal = self.tolerances.goal
        within = (goal <= 0.0) | (magnitude <= goal)
        if within.all():
            return Verdict(Outcome.SUCCEEDED, error=error)
        if now <= self.end + self.tolerances.settle:
            return Verdict(Outcome.RUNNING, error=error)
        j = int(np.argmin(within))
        return Verdict(
            Outcome.GOAL_TOLERANCE_VIOLATED,
            f"{self.names[j]} ended {magnitude[j]:.4f} rad from the goal",
            error,
        )


@dataclass(frozen=True)
class GripperVerdict:
    done: bool
    reached: bool
    stalled: bool


class GripperMonitor:
    """Judges one gripper goal (an opening [m]) from samples of the fingers' state."""

    def __init__(self, goal: float, start: float, stroke_time: float) -> None:
        """``stroke_time``: seconds a full stroke takes at the fingers' speed."""
        self.goal = goal
        self.start = start
        self.limit = start + stroke_time + GRIPPER_SPARE_TIME
        self._slow_since: float | None = None

    def check(
        self, now: float, opening: float, rate: float, force: float, force_limit: float
    ) -> GripperVerdict:
        reached = abs(opening - self.goal) < GRIPPER_REACHED
        slow = abs(rate) < GRIPPER_STALL_SPEED and now - self.start > GRIPPER_START_GRACE
        if not slow:
            self._slow_since = None
        elif self._slow_since is None:
            self._slow_since = now
        stalled = (
            not reached
            and self._slow_since is not None
            and now - self._slow_since > GRIPPER_STALL_TIME
            and abs(force) >= FORCE_LIMIT_SHARE * force_limit
        )
        return GripperVerdict(reached or stalled or now > self.limit, reached, stalled)


def tracking_summary(worst: float, error: np.ndarray | None) -> str:
    """The tracking figures a FollowJointTrajectory result has no fields for."""
    summary = f"largest tracking error {worst:.2e} rad"
    if error is None:
        return summary
    return summary + f", when it ended {float(np.abs(error).max()):.2e} rad"

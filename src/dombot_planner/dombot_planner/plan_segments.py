"""What a plan is made of: segments of rest-to-rest pieces, each followed by an optional
gripper event; sampled as they are sent and executed."""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

from dombot_planner.timing import TimedPath

GRIPPER_NONE, GRIPPER_OPEN, GRIPPER_CLOSE = "none", "open", "close"


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
    planning_time: float = 0.0
    kto_attempts: dict[str, int] = field(default_factory=dict)

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

"""Which pile dominoes the bring-up offers the planner, and in what order (no ROS).

Shared by the arm job and ``benchmarks/bench_pile_picks.py``, so that the benchmark
measures the ranking that runs.
"""

from __future__ import annotations

from collections.abc import Mapping, MutableMapping, Sequence
from typing import Protocol, TypeVar

import numpy as np
from pydrake.math import RigidTransform

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import OrientedBox

# m: detections within this of the pick go to the planner as its pile. Not just the close
# ones: the gripper body spans 15 cm and leans 60° at a grasp, and the coarse moves pass
# low over the pile (with 8 cm, a third of the grasps on one S-curve pile ran the gripper
# into a domino 8-16 cm away).
NEIGHBOUR_RADIUS = 0.25
# How a pick's pile goes to the planner: as boxes the pads keep clear of (or nudge a few
# millimetres); as boxes only the gripper body and arm keep clear of, with the points of
# their cores for the pads' path (it may reach into a box up to the core); or not at all,
# the last resort (see task.attempts.attempt).
PILE_BOXES, PILE_CORES, PILE_IGNORED = "boxes", "cores", "ignored"
CORE_RADIUS = 0.08  # m: neighbours whose centres are farther cannot meet the pads' path
CORE_STEP = 0.002  # m between the points of a core's faces


class Offer(Protocol):
    @property
    def scored(self) -> bool:  # perception found room for the fingers
        ...

    @property
    def leaning(self) -> bool:  # on other dominoes, not flat on the table
        ...

    @property
    def clearance(self) -> float:  # m beside the finger contact sides
        ...


OfferT = TypeVar("OfferT", bound=Offer)


class Lying(Protocol):
    def spot(self) -> np.ndarray:  # (x, y) where it lies
        ...


LyingT = TypeVar("LyingT", bound=Lying)


def roomiest_first(candidates: Sequence[OfferT]) -> list[OfferT]:
    """Scored before unscored, flat before leaning, then the most room for the fingers:
    the order of the last resort, offers planned without their pile."""
    return sorted(candidates, key=lambda c: (not c.scored, c.leaning, -c.clearance))


def with_pile_first(candidates: Sequence[OfferT]) -> list[OfferT]:
    """The order of the offers planned with their pile: those perception scored (in its
    order, best grasp first), then the others with the most room for the fingers; flat
    before leaning in each (in the benchmark logs a fifth of the picks leaned and gave 3
    of the 6 grasps that closed on nothing; they placed about as often, 64 of 69)."""
    scored = sorted((c for c in candidates if c.scored), key=lambda c: c.leaning)
    return scored + [c for c in roomiest_first(candidates) if not c.scored]


def kept_first(
    candidates: Sequence[LyingT], kept: Mapping[int, np.ndarray], slot: int, radius: float
) -> list[LyingT]:
    """``candidates`` for ``slot`` with the pile dominoes kept for a safety gap's last slot
    (``kept``: slot → (x, y), the same domino within ``radius``): the one kept for ``slot``
    first, those kept for other slots left out. A gap's last slot goes in between two
    standing neighbours once the pile has thinned, where only holds that do not lean along
    the run can be placed, and what was left of the pile then often had none (S-curve of
    20: 17-23 offers refused or foreseen in that one slot, then pushes through the pile);
    the domino the planner placed there before the build is kept for it (``task.gaps``).
    Offered last elsewhere, each was taken by another slot whose other offers were refused
    (S-curve of 20, seed 0: all three, and two gaps then cost 27 and 33 s simulated)."""

    def kept_for(candidate: LyingT) -> int | None:
        spot = candidate.spot()
        return next((s for s, at in kept.items() if np.linalg.norm(spot - at) < radius), None)

    slots = [kept_for(c) for c in candidates]
    mine = [c for c, s in zip(candidates, slots, strict=True) if s == slot]
    return mine + [c for c, s in zip(candidates, slots, strict=True) if s is None]


def follow_kept(
    kept: MutableMapping[int, np.ndarray], spots: Sequence[np.ndarray], radius: float
) -> None:
    """Each of ``kept``'s spots moved to the nearest of ``spots`` (a new look's) within
    ``radius``: the same domino, nudged by the picks beside it, stays kept over the build."""
    if not len(spots):
        return
    seen = np.asarray(spots, dtype=float).reshape(-1, 2)
    for slot, at in kept.items():
        distances = np.linalg.norm(seen - at, axis=1)
        if distances.min() < radius:
            kept[slot] = seen[int(distances.argmin())]


def pile_cores(centre: np.ndarray, neighbours: Sequence[np.ndarray], shrink: float) -> np.ndarray:
    """Points (N×3, world) on the faces of each neighbour's box (4x4 poses) within
    CORE_RADIUS of ``centre`` (x, y), shrunk by ``shrink`` per side (to nothing at most):
    kept pile_point_clearance from them, the pads' path reaches at most ``shrink`` minus
    that clearance into a neighbour."""
    size = np.asarray(DOMINO_SIZE)
    core = np.maximum(size - 2.0 * shrink, 0.0)
    points = [
        OrientedBox(RigidTransform(pose), core).surface(CORE_STEP)
        for pose in neighbours
        if np.linalg.norm(pose[:2, 3] - centre) < CORE_RADIUS
    ]
    return np.concatenate(points) if points else np.zeros((0, 3))

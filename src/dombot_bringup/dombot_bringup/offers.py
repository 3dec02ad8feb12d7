"""Which pile dominoes the bring-up offers the planner, and in what order (no ROS).

Shared by the arm job and ``benchmarks/bench_pile_picks.py``, so that the benchmark
measures the ranking that runs.
"""

from __future__ import annotations

from collections.abc import Sequence
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

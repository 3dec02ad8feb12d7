"""Pushes that clear a slot of the run of a fallen domino no grasp reaches (no ROS).

A domino that fell between standing neighbours often leaves the fingers no room on
either side of it; left there it blocks its slot for good (two S-curve runs ended so).
The planner's sweep (/plan_strike with a sweep direction) pushes it low across the run
instead; here is which way, and how far, and which other lying dominoes it pushes along.
"""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from pydrake.math import RigidTransform

from dombot_bringup.footprints import footprints_meet
from dombot_bringup.layouts import DOMINO_THICKNESS, DOMINO_WIDTH, DominoPlacement
from dombot_description import domino_corners
from dombot_description.pusher import MAX_SWEEP_DISTANCE as MAX_SWEEP
from dombot_description.pusher import PADS_HALF, PUSHER_STANDOFF
from dombot_planner.request import dominoes_overlap, sweep_blocker


def sweep_pushes(
    debris: np.ndarray, placement: DominoPlacement, margin: float
) -> list[tuple[np.ndarray, float]]:
    """(direction, distance) pushes across the run at ``placement`` after which the fallen
    domino at ``debris`` (4×4 pose) lies ``margin`` beyond the run's side: towards the side
    its centre is on first (the shorter push), then the other; none longer than MAX_SWEEP."""
    across = np.array([-math.sin(placement.heading), math.cos(placement.heading), 0.0])
    offset = domino_corners(debris) - [placement.x, placement.y, 0.0]
    side = 1.0 if np.mean(offset @ across) >= 0.0 else -1.0
    pushes = []
    for direction in (side * across, -side * across):
        hindmost = (offset @ direction).min()
        distance = DOMINO_WIDTH / 2 + margin - hindmost
        if distance <= MAX_SWEEP:
            pushes.append((direction, distance))
    return pushes


def carried_along(
    debris: np.ndarray,
    lying: Sequence[np.ndarray],
    standing: Sequence[np.ndarray],
    direction: np.ndarray,
    distance: float,
    clearance: float,
    keep: float,
) -> list[int] | None:
    """The indices of the ``lying`` dominoes (4×4 poses) that the sweep of ``debris``
    ``distance`` along ``direction`` pushes along with it, as one blob: those whose
    footprint comes within ``clearance`` of the sweep's path (the pusher's place behind
    ``debris`` and the ground ``debris`` covers up to its end). None when one of them
    lies within ``keep`` of a ``standing`` domino, before or after the push, or would be
    pushed into one: dragged along, it may turn into the standing run. In a shingled row
    each domino lies on the next: with them as obstacles no pusher pose keeps its
    clearance (s_curve30 seed 2, arc cycle 4: every sweep of the row refused)."""
    direction = np.asarray(direction, dtype=float)[:2]
    corners = domino_corners(debris)[:, :2]
    behind = PUSHER_STANDOFF + 2 * PADS_HALF
    path = np.vstack([corners - behind * direction, corners + distance * direction])
    along = np.array([*direction, 0.0])
    upright = [RigidTransform(pose) for pose in standing]
    carried = []
    for n, pose in enumerate(lying):
        if not footprints_meet(path, domino_corners(pose)[:, :2], clearance):
            continue
        start = RigidTransform(pose)
        end = RigidTransform(start.rotation(), start.translation() + distance * along)
        for other in upright:
            if dominoes_overlap(start, other, -keep) or dominoes_overlap(end, other, -keep):
                return None
        if sweep_blocker(start, along, distance, upright) is not None:
            return None
        carried.append(n)
    return carried


def pushed_whole_way(debris: np.ndarray, pose: np.ndarray, direction: np.ndarray) -> bool:
    """Whether the domino lying at ``pose`` (one ``carried_along`` the sweep of ``debris``
    along ``direction``) is pushed the whole way with ``debris``: it overlaps the lane the
    sweep clears (``debris``'s extent across the push) by more than a domino's thickness
    and reaches ahead of the middle of the pads where the push starts (they push it, or
    land on it and drag it). One that only brushes the lane's side, or lies behind the
    pads, is not taken to move."""
    direction = np.asarray(direction, dtype=float)[:2]
    direction = direction / np.linalg.norm(direction)
    across = np.array([-direction[1], direction[0]])
    swept, lying = domino_corners(debris)[:, :2], domino_corners(pose)[:, :2]
    lane, extent = swept @ across, lying @ across
    overlap = min(lane.max(), extent.max()) - max(lane.min(), extent.min())
    pads = (swept @ direction).min() - PUSHER_STANDOFF - PADS_HALF
    return bool(overlap > DOMINO_THICKNESS and (lying @ direction).max() > pads)

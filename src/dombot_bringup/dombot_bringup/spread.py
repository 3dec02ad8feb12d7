"""Pushes that spread a crowded pile (no ROS).

When no pick plans with the pile's boxes or its cores, the dominoes lie too close for the
fingers. Picked ignoring the pile, 4 of 6 such picks closed on nothing (7500eb1). Instead
one of them is pushed out of the crowd with the planner's sweep (/plan_strike with a
sweep direction: the closed pads push it low along the table), and the pile is looked at
again. Here is which way and how far: where the pusher has room to come down behind it,
and the shortest push after which it lies clear of everything else seen.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.math import RigidTransform
from scipy.spatial import cKDTree

from dombot_bringup.debris import MAX_SWEEP
from dombot_description import DOMINO_SIZE, domino_corners
from dombot_description.grasp import OrientedBox

SPREAD_DIRECTIONS = 16  # tried around the circle
SPREAD_STEP = 0.01  # m between the push distances tried
MIN_SPREAD = 0.02  # m: the shortest push
OUTLINE_STEP = 0.003  # m between the points of a domino's faces
# The pusher (closed pads, ~16 × 16 mm, pointing down) comes down this far behind the
# pushed domino (the planner's strike_standoff plus half the pads), its tips at
# SWEEP_HEIGHT of the domino's vertical extent (the planner's sweep_height), and needs
# this much room around that spot above its tips (less PUSHER_BELOW: the planner's
# fine_obstacle_clearance): a domino the pushed one lies on is no obstacle to it. The
# planner checks all this exactly; here it only chooses what to ask for.
PUSHER_BEHIND = 0.018  # m
PUSHER_ROOM = 0.013  # m
PUSHER_BELOW = 0.002  # m
SWEEP_HEIGHT = 0.4
FINGERS_END = 0.005  # m beyond its ends that the fingers' room must reach


def surfaces(poses: Sequence[np.ndarray]) -> np.ndarray:
    """Points (N×3, world) on the faces of dominoes at ``poses`` (4×4)."""
    if not poses:
        return np.zeros((0, 3))
    size = np.asarray(DOMINO_SIZE)
    return np.concatenate(
        [OrientedBox(RigidTransform(pose), size).surface(OUTLINE_STEP) for pose in poses]
    )


def spread_pushes(
    target: np.ndarray,
    others: np.ndarray,
    centre: np.ndarray,
    radius: float,
    clearance: float,
) -> list[tuple[np.ndarray, float]]:
    """(direction, distance) pushes of the domino at ``target`` (4×4) after which, seen
    from above, no point of ``others`` (N×3: the faces of the dominoes around it, and
    points seen on none) lies within ``clearance`` of its long sides, where the fingers
    go (FINGERS_END beyond its ends), and its centre is within ``radius`` of ``centre``
    (x, y: where the cameras look); the shortest per direction, none longer than
    MAX_SWEEP, and only where the pusher has room to come down behind it. Shortest
    first, then those leading away from ``centre``."""
    corners = domino_corners(target)
    low, high = corners[:, 2].min(), corners[:, 2].max()
    above = others[others[:, 2] > low + SWEEP_HEIGHT * (high - low) - PUSHER_BELOW]
    pusher_tree = cKDTree(above[:, :2]) if len(above) else None
    start = target[:2, 3]
    length = target[:2, 0] / (np.linalg.norm(target[:2, 0]) or 1.0)  # body x, seen from above
    frame = np.array([length, [-length[1], length[0]]])  # rows: along, across
    extent = (corners[:, :2] - start) @ frame.T
    room = np.array([FINGERS_END, clearance])
    free_low, free_high = extent.min(axis=0) - room, extent.max(axis=0) + room
    seen = (others[:, :2] - start) @ frame.T  # relative to the start, in its frame
    outward = start - np.asarray(centre, dtype=float)
    outward = outward / (np.linalg.norm(outward) or 1.0)
    distances = np.arange(MIN_SPREAD, MAX_SWEEP + 1e-9, SPREAD_STEP)
    pushes = []
    for angle in np.linspace(0.0, 2.0 * np.pi, SPREAD_DIRECTIONS, endpoint=False):
        direction = np.array([np.cos(angle), np.sin(angle)])
        behind = start + ((corners[:, :2] - start) @ direction).min() * direction
        if not _room(pusher_tree, behind - PUSHER_BEHIND * direction, PUSHER_ROOM):
            continue
        for distance in distances:
            if np.linalg.norm(start + distance * direction - centre) > radius:
                break
            moved = seen - frame @ (distance * direction)
            inside = np.all((moved >= free_low) & (moved <= free_high), axis=1)
            if not inside.any():
                pushes.append((np.array([*direction, 0.0]), float(distance)))
                break
    return sorted(pushes, key=lambda push: (push[1], -push[0][:2] @ outward))


def _room(tree: cKDTree | None, point: np.ndarray, clearance: float) -> bool:
    """Whether ``point`` (x, y) is ``clearance`` from every point of the tree."""
    if tree is None:
        return True
    nearest, _ = tree.query(point, distance_upper_bound=clearance)
    return bool(np.isinf(nearest))

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
FOOTPRINT_STEP = 0.003  # m between the points of a domino's outline in plan view
# The pusher (closed pads, ~16 × 16 mm, pointing down) comes down this far behind the
# pushed domino (the planner's strike_standoff plus half the pads) and needs this much
# room around that spot; the planner checks it exactly, this only orders the offers.
PUSHER_BEHIND = 0.018  # m
PUSHER_ROOM = 0.013  # m


def plan_view(poses: Sequence[np.ndarray]) -> np.ndarray:
    """Points (N×2) on the outlines of dominoes at ``poses`` (4×4), seen from above."""
    if not poses:
        return np.zeros((0, 2))
    size = np.asarray(DOMINO_SIZE)
    surfaces = [OrientedBox(RigidTransform(pose), size).surface(FOOTPRINT_STEP) for pose in poses]
    return np.concatenate(surfaces)[:, :2]


def spread_pushes(
    target: np.ndarray,
    others: np.ndarray,
    centre: np.ndarray,
    radius: float,
    clearance: float,
) -> list[tuple[np.ndarray, float]]:
    """(direction, distance) pushes of the domino at ``target`` (4×4) after which its
    outline is ``clearance`` from every point of ``others`` (N×2: the outlines of the
    dominoes around it and points seen on none) and its centre within ``radius`` of
    ``centre`` (x, y: where the cameras look), the shortest per direction, none longer
    than MAX_SWEEP; only directions where the pusher has room behind it. Shortest first,
    then those leading away from ``centre``."""
    tree = cKDTree(others) if len(others) else None
    outline = plan_view([target])
    start = target[:2, 3]
    corners = domino_corners(target)[:, :2]
    outward = start - np.asarray(centre, dtype=float)
    outward = outward / (np.linalg.norm(outward) or 1.0)
    distances = np.arange(MIN_SPREAD, MAX_SWEEP + 1e-9, SPREAD_STEP)
    pushes = []
    for angle in np.linspace(0.0, 2.0 * np.pi, SPREAD_DIRECTIONS, endpoint=False):
        direction = np.array([np.cos(angle), np.sin(angle)])
        behind = start + ((corners - start) @ direction).min() * direction
        if not _room(tree, behind - PUSHER_BEHIND * direction, PUSHER_ROOM):
            continue
        for distance in distances:
            end = start + distance * direction
            if np.linalg.norm(end - centre) > radius:
                break
            if _room(tree, outline + distance * direction, clearance):
                pushes.append((np.array([*direction, 0.0]), float(distance)))
                break
    return sorted(pushes, key=lambda push: (push[1], -push[0][:2] @ outward))


def _room(tree: cKDTree | None, points: np.ndarray, clearance: float) -> bool:
    """Whether every one of ``points`` (N×2 or a single 2-vector) is ``clearance`` from
    the tree's points."""
    if tree is None:
        return True
    nearest, _ = tree.query(np.atleast_2d(points), distance_upper_bound=clearance)
    return bool(np.all(np.isinf(nearest)))

"""Pushes that spread a crowded pile (no ROS).

When no pick plans with the pile's boxes or its cores, the dominoes lie too close for the
fingers, and picked ignoring the pile most close on nothing. Instead one of them is
pushed out of the crowd with the planner's sweep (/plan_strike with a sweep direction:
the closed pads push it low along the table), and the pile is looked at again. Here is
which way and how far: where the pusher has room to come down behind it, and the
shortest push after which the fingers have room beside it. When no such push exists (a
jam: every push is blocked by a neighbour, or none frees the fingers within MAX_SWEEP),
``stir_pushes``: a fixed push through the neighbours, which move along
(docs/decisions/0007-spread-and-stir.md). A domino no grasp takes as it lies (on its edge,
upright, leaning, or flat out of reach) is pushed over or slid by ``lay_flat_pushes``.
"""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.math import RigidTransform
from scipy.spatial import cKDTree

from dombot_bringup.debris import MAX_SWEEP
from dombot_description import DOMINO_SIZE, domino_corners
from dombot_description.grasp import OrientedBox
from dombot_description.pusher import PADS_HALF, PUSHER_STANDOFF, SWEEP_HEIGHT
from dombot_planner.request import sweep_blocker
from dombot_planner.settings import PlannerSettings

SPREAD_DIRECTIONS = 16  # tried around the circle
SPREAD_STEP = 0.01  # m between the push distances tried
MIN_SPREAD = 0.02  # m: the shortest push
OUTLINE_STEP = 0.003  # m between the points of a domino's faces
# The pusher (closed pads pointing down) comes down PUSHER_BEHIND behind the pushed
# domino (the standoff the pads travel before they meet it, plus half the pads), its tips
# at SWEEP_HEIGHT of the domino's vertical extent, and needs PUSHER_ROOM around that spot
# above its tips (less the planner's fine_obstacle_clearance): a domino the pushed one
# lies on is no obstacle to it. The planner checks all this exactly; here it only
# chooses what to ask for.
PUSHER_BEHIND = PUSHER_STANDOFF + PADS_HALF  # m
PUSHER_ROOM = 0.013  # m
PUSHER_STEP = 0.005  # m between the pusher's spots checked along the push
PUSHER_BELOW = PlannerSettings().fine_obstacle_clearance  # m
FINGERS_END = 0.005  # m beyond its ends that the fingers' room must reach
# m a jammed domino is pushed through its neighbours: a missed grasp in a jam moved them
# 3-25 mm, after which the next pick planned
STIR_DISTANCE = 0.04
# m past its back face that a domino standing on its edge or end, or leaning, is pushed
# along its thickness axis: pushed so at SWEEP_HEIGHT in Drake, 4 of 4 (two on edge, two
# upright) tipped over and lay flat
TIP_DISTANCE = 0.02
# m a flat domino no grasp reaches (even ignoring its pile) is slid towards the pile's
# centre, where the arm reaches it leaning either way
SLIDE_DISTANCE = 0.03
FLAT_TILT = np.sin(np.radians(15.0))  # thickness axis this close to vertical: lying flat


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
    neighbours: Sequence[np.ndarray],
    points: np.ndarray,
    centre: np.ndarray,
    radius: float,
    clearance: float,
) -> list[tuple[np.ndarray, float]]:
    """(direction, distance) pushes of the domino at ``target`` (4×4) after which, seen
    from above, nothing of its ``neighbours`` (4×4 poses) or of ``points`` (N×3: seen on
    no domino) lies within ``clearance`` of its long sides, where the fingers go
    (FINGERS_END beyond its ends), and its centre is within ``radius`` of ``centre``
    (x, y: where the cameras look); the shortest per direction, none longer than
    MAX_SWEEP. Only pushes the planner can take: the domino's path meets no neighbour it
    does not touch already (``sweep_blocker``, the planner's own check), and the pusher
    has room to come down behind it and follow it. Shortest first, then those leading
    away from ``centre``."""
    others = np.vstack([surfaces(neighbours), points.reshape(-1, 3)])
    corners = domino_corners(target)
    pusher_tree = _pusher_obstacles(corners, others)
    start = target[:2, 3]
    length = target[:2, 0] / (np.linalg.norm(target[:2, 0]) or 1.0)  # body x, seen from above
    frame = np.array([length, [-length[1], length[0]]])  # rows: along, across
    extent = (corners[:, :2] - start) @ frame.T
    room = np.array([FINGERS_END, clearance])
    free_low, free_high = extent.min(axis=0) - room, extent.max(axis=0) + room
    seen = (others[:, :2] - start) @ frame.T  # relative to the start, in its frame
    outward = _outward(start, centre)
    pushes = []
    for angle in np.linspace(0.0, 2.0 * np.pi, SPREAD_DIRECTIONS, endpoint=False):
        direction = np.array([np.cos(angle), np.sin(angle)])
        distance = _shortest_clear(seen, frame @ direction, free_low, free_high)
        if distance is None or np.linalg.norm(start + distance * direction - centre) > radius:
            continue
        if not _pusher_has_room(pusher_tree, corners, direction, PUSHER_STANDOFF + distance):
            continue
        pushed = np.array([*direction, 0.0])
        near = [
            RigidTransform(n)
            for n in neighbours
            if np.linalg.norm(n[:2, 3] - start) < distance + DOMINO_SIZE[0]
        ]
        if sweep_blocker(RigidTransform(target), pushed, distance, near) is None:
            pushes.append((pushed, distance))
    return sorted(pushes, key=lambda push: (push[1], -push[0][:2] @ outward))


def stir_pushes(
    target: np.ndarray,
    neighbours: Sequence[np.ndarray],
    points: np.ndarray,
    centre: np.ndarray,
    radius: float,
) -> list[tuple[np.ndarray, float]]:
    """(direction, STIR_DISTANCE) pushes of the jammed domino at ``target`` (4×4) through
    its ``neighbours`` (4×4 poses; they are pushed along): only where the pusher has room
    to come down behind it (``points``, N×3, seen on no domino, count too), and its
    centre ends within ``radius`` of ``centre`` (x, y); those leading away from
    ``centre`` first, out of the jam. The planner is to keep clear of the run only."""
    others = np.vstack([surfaces(neighbours), points.reshape(-1, 3)])
    corners = domino_corners(target)
    pusher_tree = _pusher_obstacles(corners, others)
    start = target[:2, 3]
    outward = _outward(start, centre)
    pushes = []
    for angle in np.linspace(0.0, 2.0 * np.pi, SPREAD_DIRECTIONS, endpoint=False):
        direction = np.array([np.cos(angle), np.sin(angle)])
        end = start + STIR_DISTANCE * direction
        if np.linalg.norm(end - centre) > radius:
            continue
        if _pusher_has_room(pusher_tree, corners, direction, 0.0):  # it may push them
            pushes.append((np.array([*direction, 0.0]), STIR_DISTANCE))
    return sorted(pushes, key=lambda push: -push[0][:2] @ outward)


def lay_flat_pushes(target: np.ndarray, centre: np.ndarray) -> list[tuple[np.ndarray, float]]:
    """(direction, distance) pushes that may bring the domino at ``target`` (4×4) within
    a grasp's reach: standing on its edge or end, or leaning, it is pushed over along its
    thickness axis (horizontally, either way: towards the pile's ``centre`` (x, y) first)
    and lies flat; lying flat, it is slid towards ``centre`` (none when it lies there)."""
    start, centre = target[:2, 3], np.asarray(centre, dtype=float)
    inward = -_outward(start, centre)
    thickness = target[:2, 2]
    if np.linalg.norm(thickness) <= FLAT_TILT:
        if np.linalg.norm(centre - start) < MIN_SPREAD:
            return []
        return [(np.array([*inward, 0.0]), SLIDE_DISTANCE)]
    over = thickness / np.linalg.norm(thickness)
    pushes = [(np.array([*side * over, 0.0]), TIP_DISTANCE) for side in (1.0, -1.0)]
    return sorted(pushes, key=lambda push: -push[0][:2] @ inward)


def _outward(start: np.ndarray, centre: np.ndarray) -> np.ndarray:
    """Unit vector (x, y) from the pile's ``centre`` to ``start``: pushes along it lead
    out of the pile (zero at the centre itself)."""
    outward = start - np.asarray(centre, dtype=float)
    return outward / (np.linalg.norm(outward) or 1.0)


def _pusher_obstacles(corners: np.ndarray, others: np.ndarray) -> cKDTree | None:
    """What the pusher, its tips at SWEEP_HEIGHT of the domino with these ``corners``
    (8×3), could meet of ``others`` (N×3), seen from above: the points above its tips."""
    low, high = corners[:, 2].min(), corners[:, 2].max()
    above = others[others[:, 2] > low + SWEEP_HEIGHT * (high - low) - PUSHER_BELOW]
    return cKDTree(above[:, :2]) if len(above) else None


def _pusher_has_room(
    tree: cKDTree | None, corners: np.ndarray, direction: np.ndarray, reach: float
) -> bool:
    """Whether the pusher can come down PUSHER_BEHIND behind the domino (``corners``,
    8×3) pushed along ``direction`` (x, y, unit), and go on ``reach`` along it (0: only
    come down), without meeting anything of ``tree``."""
    start = corners[:, :2].mean(axis=0)
    behind = start + ((corners[:, :2] - start) @ direction).min() * direction
    pusher = behind - PUSHER_BEHIND * direction
    travel = np.arange(0.0, reach + 1e-9, PUSHER_STEP)
    return all(_room(tree, pusher + t * direction, PUSHER_ROOM) for t in travel)


def _shortest_clear(
    seen: np.ndarray, step: np.ndarray, free_low: np.ndarray, free_high: np.ndarray
) -> float | None:
    """The shortest of the push distances after which none of ``seen`` (N×2, in the
    domino's frame from its start) lies in its fingers' room [free_low, free_high], the
    domino moving ``step`` (its frame) per metre; None beyond MAX_SWEEP."""
    for distance in np.arange(MIN_SPREAD, MAX_SWEEP + 1e-9, SPREAD_STEP):
        moved = seen - distance * step
        if not np.any(np.all((moved >= free_low) & (moved <= free_high), axis=1)):
            return float(distance)
    return None


def _room(tree: cKDTree | None, point: np.ndarray, clearance: float) -> bool:
    """Whether ``point`` (x, y) is ``clearance`` from every point of the tree."""
    if tree is None:
        return True
    nearest, _ = tree.query(point, distance_upper_bound=clearance)
    return bool(np.isinf(nearest))

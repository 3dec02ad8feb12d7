"""Whether a grasp's pads pass the pile, or a TCP pose's pads keep clear of dominoes, told
from the TCP pose alone, before any IK (no ROS).

Where the pads are at a grasp, and the space they sweep down its approach line and closing
onto the domino, depend only on the TCP pose and the line, not on the arm configuration
that reaches it. A grasp whose pads meet the pile so fails at every IK solution: the
planner tells it before solving any (``request_planning.RequestPlanning``), and the
bring-up before it asks for a pick whose every grasp fails so (``foreseen_refusal``).
The same holds at a place or strike pose beside standing dominoes (``pads_near``).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import lru_cache

import numpy as np
from pydrake.math import RigidTransform

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import (
    BoxArray,
    Grasp,
    OrientedBox,
    gripper_geometry,
    nearest_distance,
)

# m: SceneGraph's penetration depth of two boxes is found to a tolerance (GJK/EPA)
DEPTH_MARGIN = 1e-4
SURFACE_STEP = 0.002  # m between the points on a pad's faces (pads_near)


def pads_in_pile(grasp: Grasp, pile: Sequence[RigidTransform], depth: float) -> bool:
    """Whether a pad at ``grasp``, open (pre-grasp) or closed on the domino, reaches more
    than ``depth`` (+ DEPTH_MARGIN) into a pile domino's box. Two boxes' penetration depth
    (the shortest move that parts them, which SceneGraph's signed distance gives and the
    planner's clearance rules judge) is their least overlap along the 15 separating-axis
    candidates, the face normals of their Minkowski difference among them
    (``OrientedBox.overlaps``): the test never fails a grasp that those rules pass."""
    if not len(pile):
        return False
    size = np.asarray(DOMINO_SIZE, dtype=float)
    boxes = BoxArray(
        np.array([pose.rotation().matrix() for pose in pile]),
        np.array([pose.translation() for pose in pile]),
        np.repeat(size[None], len(pile), 0),
    )
    domino_radius = float(np.linalg.norm(size)) / 2.0
    for pad in grasp.pad_boxes(grasp.pregrasp_opening) + grasp.pad_boxes():
        reach = domino_radius + float(np.linalg.norm(pad.size)) / 2.0
        near = np.linalg.norm(boxes.centres - pad.pose.translation(), axis=1) < reach
        nearby = BoxArray(boxes.rotations[near], boxes.centres[near], boxes.sizes[near])
        if near.any() and pad.overlapping(nearby, depth + DEPTH_MARGIN).any():
            return True
    return False


def pads_path_meets_points(
    grasp: Grasp, approach_distance: float, lift: np.ndarray, points: np.ndarray, clearance: float
) -> bool:
    """Whether the pads' path to ``grasp`` (open, down the approach line
    ``approach_distance`` long along ``lift``, then closing on the domino:
    ``Grasp.pad_paths``) comes within ``clearance`` of one of ``points`` (N×3, world)."""
    if not len(points):
        return False
    paths = grasp.pad_paths(approach_distance, lift)
    return nearest_distance(paths, points, cap=clearance) < clearance


def pads_near(
    tcp: RigidTransform, opening: float, dominoes: Sequence[RigidTransform], clearance: float
) -> bool:
    """Whether a pad ``opening`` apart at TCP pose ``tcp`` comes within ``clearance`` (less
    DEPTH_MARGIN, SceneGraph's tolerance) of one of the ``dominoes``' boxes. Told by points
    on the pads' faces, SURFACE_STEP apart: the nearest of them is at least as far as the
    pad itself, so the test fails no pose SceneGraph's signed distance would pass."""
    size = np.asarray(DOMINO_SIZE, dtype=float)
    domino_radius = float(np.linalg.norm(size)) / 2.0
    limit = clearance - DEPTH_MARGIN
    centres = np.array([pose.translation() for pose in dominoes]).reshape(-1, 3)
    for box, faces in pad_faces(opening):
        reach = domino_radius + float(np.linalg.norm(box.size)) / 2.0 + clearance
        near = np.linalg.norm(centres - tcp.multiply(box.pose.translation()), axis=1) < reach
        if not near.any():
            continue
        points = tcp.multiply(faces.T).T
        for k in np.flatnonzero(near):
            if OrientedBox(dominoes[k], size).signed_distance(points).min() < limit:
                return True
    return False


@lru_cache(maxsize=8)
def pad_faces(opening: float) -> tuple[tuple[OrientedBox, np.ndarray], ...]:
    """Each pad's box at ``opening`` and points on its faces (N×3), SURFACE_STEP apart or
    closer, in the TCP frame (a request's few openings are kept)."""
    return tuple(
        (box, box.surface(SURFACE_STEP)) for box in gripper_geometry().pad_boxes_in_tcp(opening)
    )

"""Strikes and sweeps the planner refuses whatever its IK finds, told without a plant (no ROS).

Where the pusher (the closed pads) stands at each strike pose depends on the request
alone (``strike.strike_pose`` for each of ``strike.pusher_rotations``), not on the arm
configuration that reaches it. A pusher whose pads come within ``coarse_clearance`` of
a standing domino's box there fails the descent's pads–standing clearance at every IK
solution: ``StrikePlanning`` then refuses that orientation ("in collision at the pose
(pads–standing)"), and when every orientation is so, the request
(PLACE_IN_COLLISION at strike). Together with the request's own checks
(``check_strike_request``: a sweep that pushes the domino into a standing one) that tells
a refusal before asking (``foreseen_strike_refusal``): the bring-up asks it before it
pushes a leaning pile domino over flat (docs/PLANNER.md, *Refusals told before planning*).
"""

from __future__ import annotations

from collections.abc import Sequence
from functools import cache

import numpy as np
from pydrake.math import RigidTransform

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import OrientedBox, gripper_geometry
from dombot_description.pusher import PUSHER_STANDOFF, SWEEP_HEIGHT
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.pads import DEPTH_MARGIN
from dombot_planner.request import StrikeRequest, check_strike_request
from dombot_planner.settings import PlannerSettings
from dombot_planner.strike import CLOSED, push_direction, pusher_rotations, strike_pose

SURFACE_STEP = 0.002  # m between the points on a pad's faces


def pusher_near_standing(
    tcp: RigidTransform, standing: Sequence[RigidTransform], clearance: float
) -> bool:
    """Whether a closed pad at TCP pose ``tcp`` comes within ``clearance`` (less
    DEPTH_MARGIN, SceneGraph's tolerance) of one of the ``standing`` dominoes' boxes. Told
    by points on the pads' faces, SURFACE_STEP apart: the nearest of them is at least as
    far as the pad itself, so the test fails no pose SceneGraph's signed distance would
    pass."""
    size = np.asarray(DOMINO_SIZE, dtype=float)
    domino_radius = float(np.linalg.norm(size)) / 2.0
    limit = clearance - DEPTH_MARGIN
    centres = np.array([pose.translation() for pose in standing]).reshape(-1, 3)
    for box, faces in zip(closed_pads(), pad_faces(), strict=True):
        reach = domino_radius + float(np.linalg.norm(box.size)) / 2.0 + clearance
        near = np.linalg.norm(centres - tcp.multiply(box.pose.translation()), axis=1) < reach
        if not near.any():
            continue
        points = tcp.multiply(faces.T).T
        for k in np.flatnonzero(near):
            if OrientedBox(standing[k], size).signed_distance(points).min() < limit:
                return True
    return False


@cache
def closed_pads() -> tuple[OrientedBox, ...]:
    """The closed pads' boxes in the TCP frame."""
    return tuple(gripper_geometry().pad_boxes_in_tcp(CLOSED))


@cache
def pad_faces() -> tuple[np.ndarray, ...]:
    """Points on each closed pad's faces (N×3, TCP frame), SURFACE_STEP apart or closer."""
    return tuple(box.surface(SURFACE_STEP) for box in closed_pads())


def foreseen_strike_refusal(
    request: StrikeRequest, settings: PlannerSettings
) -> PlanningError | None:
    """The refusal the planner will answer ``request`` with whatever its IK finds, or None
    when it may plan: the request's checks that need no table (``check_strike_request``),
    or the pusher within coarse_clearance of a standing domino at every strike pose
    (``pusher_near_standing``:
    PLACE_IN_COLLISION at strike)."""
    try:
        check_strike_request(request, settings)
    except PlanningError as error:
        return error
    direction = push_direction(request)
    height = settings.strike_height if request.sweep is None else SWEEP_HEIGHT
    poses = [
        strike_pose(request.domino_pose, rotation, direction, height, PUSHER_STANDOFF)
        for rotation in pusher_rotations(direction)
    ]
    clearance = settings.coarse_clearance  # the descent's pads–standing rule at the pose
    if not all(pusher_near_standing(pose, request.standing, clearance) for pose in poses):
        return None
    return PlanningError(
        ErrorCode.PLACE_IN_COLLISION,
        "strike",
        f"the pusher within coarse_clearance of a standing domino at every one of "
        f"{len(poses)} pusher orientations, before any IK",
    )

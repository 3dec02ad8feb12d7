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

from dombot_description.pusher import PUSHER_STANDOFF, SWEEP_HEIGHT
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.pads import pads_near
from dombot_planner.request import StrikeRequest, check_strike_request
from dombot_planner.settings import PlannerSettings
from dombot_planner.strike import CLOSED, push_direction, pusher_rotations, strike_pose


def foreseen_strike_refusal(
    request: StrikeRequest, settings: PlannerSettings
) -> PlanningError | None:
    """The refusal the planner will answer ``request`` with whatever its IK finds, or None
    when it may plan: the request's checks that need no table (``check_strike_request``),
    or the pusher within coarse_clearance of a standing domino at every strike pose
    (``pads.pads_near``, closed: PLACE_IN_COLLISION at strike)."""
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
    if not all(pads_near(pose, CLOSED, request.standing, clearance) for pose in poses):
        return None
    return PlanningError(
        ErrorCode.PLACE_IN_COLLISION,
        "strike",
        f"the pusher within coarse_clearance of a standing domino at every one of "
        f"{len(poses)} pusher orientations, before any IK",
    )

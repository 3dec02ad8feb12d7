"""A GRASP_UNREACHABLE told without planning: every grasp the planner would try fails
a test that needs no IK — the pads' against the pile, the wrist's reach (docs/PLANNER.md,
*Refusals told before planning*)."""

from __future__ import annotations

from collections import Counter

from pydrake.math import RigidTransform

from dombot_description.grasp import (
    Grasp,
)
from dombot_planner.arm_reach import WristReach
from dombot_planner.grasp_candidates import (
    finger_openings,
    lift_directions,
    pile_points,
    ranked_grasps,
    regrasp_grasp,
    regrasp_requests,
)
from dombot_planner.motion import LINE_WRIST_OUT, WRIST_OUT, reasons
from dombot_planner.pads import pads_in_pile, pads_path_meets_points
from dombot_planner.request import PickPlaceRequest, near_pick
from dombot_planner.settings import PlannerSettings

# why a grasp failed before any IK (the pads' place and path depend on the TCP pose alone)
PATH_MEETS_POINTS = "pads' path meets pile points"
PADS_IN_PILE = "pads beyond pile_nudge into a pile domino"


def foreseen_refusal(
    request: PickPlaceRequest, settings: PlannerSettings, reach: WristReach | None = None
) -> str:
    """Why the planner will refuse ``request`` with GRASP_UNREACHABLE whatever its IK finds,
    or "" when it may not: every grasp it would try, in every tier and in the regrasp's
    two picks, fails before any IK (``PATH_MEETS_POINTS``, ``PADS_IN_PILE``; given the
    planner's ``reach``, also ``WRIST_OUT`` and ``LINE_WRIST_OUT``: the tests of
    ``RequestPlanning._ends``). A few milliseconds a grasp, no IK: the bring-up asks
    before it sends a pick (docs/PLANNER.md, *Refusals told before planning*)."""
    request = near_pick(request)
    if request.holding:
        return ""
    grasps, (steeper, flatter) = ranked_grasps(request, settings)
    failures = Counter()
    if not grasps_fail(request, settings, grasps + steeper + flatter, reach, failures):
        return ""
    if settings.allow_regrasp:
        turn, pick_again = regrasp_requests(request)
        again, (steeper_again, _) = ranked_grasps(pick_again, settings)
        top = [regrasp_grasp(request.domino_pose)]
        if not (
            grasps_fail(turn, settings, top, reach)
            or grasps_fail(pick_again, settings, again + steeper_again, reach)
        ):
            return ""
    return f"every grasp fails before any IK ({reasons(failures)})"


def grasps_fail(
    request: PickPlaceRequest,
    settings: PlannerSettings,
    grasps: list[RigidTransform],
    reach: WristReach | None = None,
    failures: Counter | None = None,
) -> bool:
    """Whether every one of ``grasps`` of ``request`` fails a test that needs no IK: the
    pads' path or place against the pile, and given ``reach``, the wrist beyond it at the
    grasp or along every lift line the pads' path leaves (``failures`` counts why)."""
    failures = Counter() if failures is None else failures
    openings, points = finger_openings(request), pile_points(request)
    distance = settings.pick_approach_distance
    for pose in grasps:
        grasp = Grasp(pose, openings["closed"], openings["pregrasp"])
        lifts = [
            lift
            for lift in lift_directions(pose)
            if not pads_path_meets_points(
                grasp, distance, lift, points, settings.pile_point_clearance
            )
        ]
        if not lifts:
            failures[PATH_MEETS_POINTS] += 1
        elif not request.pads_into_pile and pads_in_pile(grasp, request.pile, settings.pile_nudge):
            failures[PADS_IN_PILE] += 1
        elif reach is not None and not reach.reaches(pose):
            failures[WRIST_OUT] += 1
        elif reach is not None and not any(reach.reaches(pose, distance * d) for d in lifts):
            failures[LINE_WRIST_OUT] += 1
        else:
            return False
    return True

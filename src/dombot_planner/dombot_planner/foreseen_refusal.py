"""A GRASP_UNREACHABLE told without planning: every grasp the planner would try fails
the pads' tests that need no IK (docs/PLANNER.md, *Refusals told before planning*)."""

from __future__ import annotations

from collections import Counter

from pydrake.math import RigidTransform

from dombot_description.grasp import (
    Grasp,
)
from dombot_planner.grasp_candidates import (
    finger_openings,
    lift_directions,
    pile_points,
    ranked_grasps,
    regrasp_grasp,
    regrasp_requests,
)
from dombot_planner.motion import reasons
from dombot_planner.pads import pads_in_pile, pads_path_meets_points
from dombot_planner.request import PickPlaceRequest, near_pick
from dombot_planner.settings import PlannerSettings

# why a grasp failed before any IK (the pads' place and path depend on the TCP pose alone)
PATH_MEETS_POINTS = "pads' path meets pile points"
PADS_IN_PILE = "pads beyond pile_nudge into a pile domino"


def foreseen_refusal(request: PickPlaceRequest, settings: PlannerSettings) -> str:
    """Why the planner will refuse ``request`` with GRASP_UNREACHABLE whatever its IK finds,
    or "" when it may not: every grasp it would try, in every tier and in the regrasp's
    two picks, fails before any IK (``PATH_MEETS_POINTS``, ``PADS_IN_PILE``; the tests of
    ``RequestPlanning._ends``). A few milliseconds a grasp, no plant: the bring-up asks
    before it sends a pick (docs/PLANNER.md, *Refusals told before planning*)."""
    request = near_pick(request)
    if request.holding:
        return ""
    grasps, (steeper, flatter) = ranked_grasps(request, settings)
    failures = Counter()
    if not pads_fail(request, settings, grasps + steeper + flatter, failures):
        return ""
    if settings.allow_regrasp:
        turn, pick_again = regrasp_requests(request)
        again, _ = ranked_grasps(pick_again, settings)
        top = [regrasp_grasp(request.domino_pose)]
        if not (pads_fail(turn, settings, top) or pads_fail(pick_again, settings, again)):
            return ""
    return f"every grasp's pads meet the pile before any IK ({reasons(failures)})"


def pads_fail(
    request: PickPlaceRequest,
    settings: PlannerSettings,
    grasps: list[RigidTransform],
    failures: Counter | None = None,
) -> bool:
    """Whether every one of ``grasps`` of ``request`` fails the pads' tests that need no
    IK (``failures`` counts why)."""
    failures = Counter() if failures is None else failures
    openings, points = finger_openings(request), pile_points(request)
    for pose in grasps:
        grasp = Grasp(pose, openings["closed"], openings["pregrasp"])
        lifts = lift_directions(pose)
        if all(
            pads_path_meets_points(
                grasp, settings.pick_approach_distance, lift, points, settings.pile_point_clearance
            )
            for lift in lifts
        ):
            failures[PATH_MEETS_POINTS] += 1
        elif not request.pads_into_pile and pads_in_pile(grasp, request.pile, settings.pile_nudge):
            failures[PADS_IN_PILE] += 1
        else:
            return False
    return True

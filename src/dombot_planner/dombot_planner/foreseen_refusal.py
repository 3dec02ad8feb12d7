"""A GRASP_UNREACHABLE told without planning: every grasp the planner would try fails
a test that needs no IK — the pads' against the pile, the wrist's reach, or (a turned
grasp's, or any in the regrasp's second pick) a hold with no place pose at the slot
(docs/PLANNER.md, *Refusals told before planning*)."""

from __future__ import annotations

from collections import Counter

from pydrake.math import RigidTransform

from dombot_description.grasp import Grasp, comes_from_above, domino_in_tcp, place_grasps
from dombot_planner.arm_reach import WristReach
from dombot_planner.grasp_candidates import (
    finger_openings,
    lift_directions,
    pile_points,
    ranked_grasps,
    regrasp_grasp,
    regrasp_requests,
)
from dombot_planner.motion import LINE_WRIST_OUT, UP, WRIST_OUT, reasons
from dombot_planner.pads import pads_in_pile, pads_near, pads_path_meets_points
from dombot_planner.request import PickPlaceRequest, near_pick
from dombot_planner.settings import PlannerSettings

# why a grasp failed before any IK (the pads' place and path depend on the TCP pose alone)
PATH_MEETS_POINTS = "pads' path meets pile points"
PADS_IN_PILE = "pads beyond pile_nudge into a pile domino"
NO_PLACE = "no place pose suits its hold (pads–standing or the wrist beyond reach, before IK)"


def foreseen_refusal(
    request: PickPlaceRequest, settings: PlannerSettings, reach: WristReach | None = None
) -> str:
    """Why the planner will refuse ``request`` with GRASP_UNREACHABLE whatever its IK finds,
    or "" when it may not: every grasp it would try, in every tier and in the regrasp's
    two picks, fails before any IK (``PATH_MEETS_POINTS``, ``PADS_IN_PILE``; given the
    planner's ``reach``, also ``WRIST_OUT`` and ``LINE_WRIST_OUT``: the tests of
    ``RequestPlanning._ends``), or is a turned grasp (steeper, flatter) whose hold has no
    place pose (``NO_PLACE``). In the regrasp's second pick a canonical grasp whose hold
    has none counts too: its refusal keeps the first pick's code. Turned grasps are all
    judged, the flatter ones too (tried once a grasp reached the domino). A few
    milliseconds a grasp, no IK: the bring-up asks before it sends a pick (docs/PLANNER.md,
    *Refusals told before planning*)."""
    request = near_pick(request)
    if request.holding:
        return ""
    grasps, (steeper, flatter) = ranked_grasps(request, settings)
    failures = Counter()
    if not (
        grasps_fail(request, settings, grasps, reach, failures)
        and grasps_fail(request, settings, steeper + flatter, reach, failures, placed=True)
    ):
        return ""
    if settings.allow_regrasp:
        turn, pick_again = regrasp_requests(request)
        again, (steeper_again, flatter_again) = ranked_grasps(pick_again, settings)
        top = [regrasp_grasp(request.domino_pose)]
        every = again + steeper_again + flatter_again
        if not (
            grasps_fail(turn, settings, top, reach)
            or grasps_fail(pick_again, settings, every, reach, placed=True)
        ):
            return ""
    return f"every grasp fails before any IK ({reasons(failures)})"


def grasps_fail(
    request: PickPlaceRequest,
    settings: PlannerSettings,
    grasps: list[RigidTransform],
    reach: WristReach | None = None,
    failures: Counter | None = None,
    placed: bool = False,
) -> bool:
    """Whether every one of ``grasps`` of ``request`` fails a test that needs no IK: the
    pads' path or place against the pile, and given ``reach``, the wrist beyond it at the
    grasp or along every lift line the pads' path leaves; with ``placed``, also a hold
    with no place pose (``no_place``; ``failures`` counts why)."""
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
        elif placed and no_place(request, settings, pose, reach):
            failures[NO_PLACE] += 1
        else:
            return False
    return True


def no_place(
    request: PickPlaceRequest,
    settings: PlannerSettings,
    grasp: RigidTransform,
    reach: WristReach | None = None,
) -> bool:
    """Whether the hold that ``grasp`` gives has no place pose the planner would pass at
    any IK solution: at each of the TCP poses that put the held domino at the release
    (``place_grasps``, those from above) a pad, closed (descent) or letting go
    (retreat), comes within fine_obstacle_clearance of a standing domino
    (``pads.pads_near``), or, given ``reach``, the wrist lies beyond it there or on the
    line up (``RequestPlanning._place_ends``). The domino's pose in the hand fixes the
    TCP at the place: a geometry query, no IK (a safety gap between two standing
    neighbours leaves a steeper grasp's hold none)."""
    held = domino_in_tcp(grasp, request.domino_pose)
    release = RigidTransform(settings.release_height * UP) @ request.place_pose
    openings = finger_openings(request)
    clearance, above = settings.fine_obstacle_clearance, settings.place_approach_distance * UP
    for pose in place_grasps(release, held):
        if not comes_from_above(pose):
            continue
        if reach is not None and not (reach.reaches(pose) and reach.reaches(pose, above)):
            continue
        if any(
            pads_near(pose, openings[opening], request.standing, clearance)
            for opening in ("closed", "release")
        ):
            continue
        return False
    return True

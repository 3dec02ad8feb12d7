"""Pick-and-place planning: coarse KTO moves, straight-line final approaches, TOPP-RA timing.

Plan of a request (docs/PLANNER.md has the picture):

1. *Ends.* For each grasp (the request's, or dombot_description.grasp's ranked list) solve
   IK at the grasp and a straight vertical line up to ``pick_approach_distance`` above it,
   IK-continued every ``waypoint_spacing``; check its clearances with the open fingers
   (approach) and with the closed fingers holding the domino (lift). Then the same for the
   place pose's symmetric equivalents (ranked so the gripper leans over the run's free
   side), checked holding the domino (descent) and with released fingers (retreat). The
   request's grasp, when given, is tried first. Pile dominoes (perceived around the one
   to pick) keep ``pile_clearance`` from the pads and ``pile_arm_clearance`` from gripper
   body and arm on the approach line, at the grasp and on the lift; when no grasp keeps
   the pads that clear, they may reach ``pile_nudge`` into a pile domino (pushing it
   aside); with the request's ``pads_into_pile`` as far as they like (only its
   ``pile_points`` then bound the pads' path). The picked domino may touch them.
2. *Coarse moves* by KinematicTrajectoryOptimization: start → above the grasp (open
   fingers), above the grasp → above the placement (holding the domino), seeded by the
   straight joint line, then by a raised via configuration, then by perturbed ones;
   every result is checked at dense samples before it is accepted. A start closer to
   something than a coarse move may begin (e.g. where a missed grasp left the arm) is
   left first by a straight line up (``RequestMotions.escape``).
3. *Timing:* every piece is retimed by TOPP-RA and pieces join at rest. Segments:
   open the gripper; approach and grasp (close); lift; transfer; descend (open); retreat.
"""

from __future__ import annotations

import math
from dataclasses import replace

from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.grasp_candidates import regrasp_grasp, regrasp_requests
from dombot_planner.motion import ArmPlanner, Deadline
from dombot_planner.pick_place_plan import PickPlacePlan
from dombot_planner.request import PickPlaceRequest, check_request, near_pick
from dombot_planner.request_planning import RequestPlanning
from dombot_planner.scene import (
    ARM,
    HELD,
    PADS,
    PILE,
    STANDING,
    TABLE,
    TARGET,
    ClearanceRules,
)
from dombot_planner.shared_work import SharedWork


def fallback_failed(error: PlanningError, fallback: PlanningError, how: str) -> PlanningError:
    """The error to raise when planning ``how`` after ``error`` failed too: the fallback's
    timeout as it is, else the first error (its code and stage) with both reasons."""
    if fallback.code == ErrorCode.TIMEOUT:
        return fallback
    return PlanningError(error.code, error.stage, f"{error.message}; {how} failed too ({fallback})")


class PickPlacePlanner(ArmPlanner):
    """Plans /plan_place requests; keeps shadow plants between requests (not thread-safe)."""

    def fine_rules(
        self, at_pick: bool, nudge: bool = False, pads_into_pile: bool = False
    ) -> ClearanceRules:
        """Within the lines only pads and the held domino come near the table and dominoes;
        the pads come pile_clearance near the pile (``nudge``: pile_nudge into it;
        ``pads_into_pile``: as far as they like), gripper body and arm pile_arm_clearance;
        at the pick the held domino may drag along the pile dominoes it lies among."""
        s = self.settings
        pads_pile = -s.pile_nudge if nudge else s.pile_clearance
        return self.relaxed_rules(
            {
                (PADS, TABLE): s.pad_table_clearance,
                (PADS, STANDING): s.fine_obstacle_clearance,
                (PADS, TARGET): s.fine_obstacle_clearance,
                (PADS, PILE): -math.inf if pads_into_pile else pads_pile,
                (ARM, PILE): s.pile_arm_clearance,
                (HELD, TABLE): -s.release_height - 1e-3,  # lies on the table at pick
                (HELD, STANDING): s.fine_obstacle_clearance,
                (HELD, PILE): -math.inf if at_pick else s.fine_obstacle_clearance,
            }
        )

    def check(self, request: PickPlaceRequest) -> None:
        """What can be said without planning; raises PlanningError."""
        check_request(request, self.settings, self.table)

    def plan(self, request: PickPlaceRequest) -> PickPlacePlan:
        """A plan for ``request``; raises PlanningError with a code and the failing stage."""
        self.check(request)
        request = near_pick(request)
        deadline = Deadline(
            request.time_budget or self.settings.default_time_budget, self.settings.budget_clock
        )
        shared = SharedWork(self)
        if request.holding:
            plan = RequestPlanning(self, request, deadline, shared).plan_held()
        else:
            try:
                plan = self._plan_around_pile(request, deadline, shared)
            except PlanningError as error:
                if not (error.code == ErrorCode.GRASP_UNREACHABLE and self.settings.allow_regrasp):
                    raise
                plan = self._plan_with_regrasp(request, deadline, shared, error)
        plan.planning_time = deadline.elapsed()
        return plan

    def _plan_around_pile(
        self, request: PickPlaceRequest, deadline: Deadline, shared: SharedWork
    ) -> PickPlacePlan:
        """Pads clear of the pile when a grasp allows it, else nudging it.

        In a heap few dominoes leave a pad's width free beside them; a pad that reaches a
        few millimetres into a neighbour's box pushes it aside (measured in
        docs/PLANNER_MEASURED.md), while a bump of the gripper body or arm stops the arm short of
        the grasp, so those keep their clearance either way.
        """
        try:
            return RequestPlanning(self, request, deadline, shared).plan()
        except PlanningError as error:
            nudge = self.settings.pile_nudge > 0.0 and request.pile and not request.pads_into_pile
            if error.code != ErrorCode.GRASP_UNREACHABLE or not nudge:
                raise
            try:
                plan = RequestPlanning(self, request, deadline, shared, nudge=True).plan()
            except PlanningError as nudge_error:
                nudging = "planning with the pads nudging the pile"
                raise fallback_failed(error, nudge_error, nudging) from None
            plan.nudged = True
            return plan

    def _plan_with_regrasp(
        self,
        request: PickPlaceRequest,
        deadline: Deadline,
        shared: SharedWork,
        error: PlanningError,
    ) -> PickPlacePlan:
        """Turn the domino a quarter turn in place with the top grasp, then pick it again.

        Where the domino lies along the radius close to the arm, no tilted grasp reaches it
        (the wrist would come closer to the shoulder than the elbow allows); lying across
        the radius it is reachable. A quarter turn is the only distinct one (a half turn is
        a symmetry of the box).
        """
        turn, pick_again = regrasp_requests(request)
        top = regrasp_grasp(request.domino_pose)
        try:
            first = RequestPlanning(self, turn, deadline, shared, grasps=[top]).plan()
            pick_again = replace(pick_again, start=first.final_positions())
            second = RequestPlanning(self, pick_again, deadline, shared).plan()
        except PlanningError as regrasp_error:
            raise fallback_failed(error, regrasp_error, "turning it first") from None
        for segment in first.segments:
            segment.label = f"regrasp_{segment.label}"
        return PickPlacePlan(
            first.segments + second.segments,
            grasp_pose=second.grasp_pose,
            release_pose=second.release_pose,
            held_in_tcp=second.held_in_tcp,
            place_approach=second.place_approach,
            kto_attempts={
                **{f"regrasp_{k}": v for k, v in first.kto_attempts.items()},
                **second.kto_attempts,
            },
            regrasped=True,
        )

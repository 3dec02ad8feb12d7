"""The planning of one /plan_place request in one tier: its pick and place ends, the
coarse moves between them and the segments they are assembled into."""

from __future__ import annotations

from collections import Counter
from collections.abc import Iterator
from typing import TYPE_CHECKING

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description.grasp import (
    Grasp,
    comes_from_above,
    domino_in_tcp,
    place_grasps,
)
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.foreseen_refusal import NO_PLACE, PADS_IN_PILE, PATH_MEETS_POINTS, no_place
from dombot_planner.grasp_candidates import (
    finger_openings,
    lift_directions,
    pile_points,
    ranked_grasps,
)
from dombot_planner.motion import LINE_WRIST_OUT, UP, Deadline, RequestMotions
from dombot_planner.pads import pads_in_pile, pads_path_meets_points
from dombot_planner.pick_place_plan import End, EndSearch, PickPlacePlan
from dombot_planner.plan_segments import GRIPPER_CLOSE, GRIPPER_OPEN, Segment
from dombot_planner.request import GRASP_REACH, PickPlaceRequest, invalid
from dombot_planner.scene import (
    HELD,
    OBSTACLES,
    PADS,
    ClearanceRules,
    Scene,
)
from dombot_planner.shared_work import SharedWork, poses_key
from dombot_planner.timing import TimedPath

if TYPE_CHECKING:
    from dombot_planner.planner import PickPlacePlanner

FREE_SIDE_RADIUS = 0.1  # m: standing dominoes this close decide the free side
# Where the pads and the held domino are depends only on the TCP pose: when one of these
# pairs is too close at an IK solution, it is at every other one.
TCP_FIXED_PAIRS = tuple(f"{moving}–{other}" for moving in (PADS, HELD) for other in OBSTACLES)


class RequestPlanning(RequestMotions):
    """The planning of one request: its scenes, random seeds, deadline and search record."""

    def __init__(
        self,
        planner: PickPlacePlanner,
        request: PickPlaceRequest,
        deadline: Deadline,
        shared: SharedWork,
        grasps: list[RigidTransform] | None = None,
        nudge: bool = False,
    ) -> None:
        """``shared``: the scenes and IK programs of the request's earlier tiers.
        ``grasps``: exactly these TCP poses to grasp with (the regrasp's top grasp);
        default: the request's grasp first, then the ranked canonical grasps. ``nudge``:
        the pads may reach pile_nudge into pile dominoes."""
        super().__init__(planner, request.start, deadline)
        self.request, self.shared = request, shared
        self.nudge = nudge
        given = grasps is not None
        self.grasps, self.turned = (
            (grasps, ([], [])) if given else ranked_grasps(request, self.settings)
        )
        self.openings = finger_openings(request)
        self.approach = self._scene("pregrasp", target=request.domino_pose)
        self.pile_points = pile_points(request)
        self.retreat = self._scene("release", target=request.place_pose)
        deadline.check("scene")  # building the scenes counts against the budget
        self.search = EndSearch()
        self.escape_line: np.ndarray | None = None  # out of a start close to something

    def _scene(self, opening: str, **dominoes) -> Scene:
        return self.shared.scene(self.openings[opening], self.request, **dominoes)

    def _grasps(self) -> Iterator[tuple[RigidTransform, bool]]:
        """Each grasp to try and whether it is a turned one: the ranked grasps, then (only
        once all of them failed, so they cost an ordinary request nothing) the turned ones.
        When a grasp reached the domino but no place suited its hold, the flatter ones come
        first: a steeper hold leans further over the neighbours at place. Otherwise the
        pick is what failed, and the steeper ones (reaching farther) come first; the
        flatter ones then only when the pads may nudge the pile, or when a steeper one
        reached it. With the pads clear of the pile they reached no pile domino that no
        canonical or steeper one did (68 recorded pile requests replayed, the same answers)
        but were 8 of the 20 grasps searched before every plan that nudges the pile;
        nudging, they found 2 of those 68 plans. A turned grasp whose hold has no place
        pose is not solved for (``_no_place``); that it might have reached the domino is
        enough for the flatter ones to follow."""
        yield from ((grasp, False) for grasp in self.grasps)
        steeper, flatter = self.turned
        if self.search.picks_found:
            yield from ((grasp, True) for grasp in flatter + steeper)
            return
        yield from ((grasp, True) for grasp in steeper)
        if self.nudge or self.search.picks_found or self.search.unplaced_turned:
            yield from ((grasp, True) for grasp in flatter)

    def plan(self) -> PickPlacePlan:
        self.check_start(self.approach)
        self.escape_line = self.escape(self.approach)
        connect_error = None
        for pick, place, transfer in self._ends():
            try:
                return self._connect(pick, place, transfer)
            except PlanningError as error:
                if error.code == ErrorCode.TIMEOUT:
                    raise
                connect_error = error  # try the next pair of ends
        raise connect_error or self.search.error()

    def plan_held(self) -> PickPlacePlan:
        """The carry of a domino already in the hand to the place, and the retreat.

        For a domino measured where it is held (e.g. it turned in the hand on the way and
        the fingers have not let go): the hold is what the start TCP and the measured pose
        say. The held pose is perceived (± 1 mm), so it may touch the table at the start
        (it stood on it); a start that close is left straight up first. Among the place
        poses the one turned least from the start's TCP comes first: the same side of the
        run as the hold had, without turning the wrist over.
        """
        request = self.request
        grasp = self.approach.tcp_pose(request.start)
        held = domino_in_tcp(grasp, request.domino_pose)
        reach = float(np.linalg.norm(held.translation()))
        if reach > GRASP_REACH:
            raise invalid(
                "validation",
                f"holding: domino_pose is {reach * 1000:.0f} mm from the TCP at the start "
                f"state (at most {GRASP_REACH * 1000:.0f} mm): it is not in the hand",
            )
        self.search.picks_found = 1  # held already: a failure is the place's, not a grasp's
        transfer = self._scene("closed", held_in_tcp=held)
        self.check_start(transfer, held_perceived=True)
        escape = self.escape(transfer)
        begin = request.start if escape is None else escape[-1]
        places = [p for p in place_grasps(self._release(), held) if comes_from_above(p)]
        places.sort(key=lambda pose: turn_angle(pose.rotation(), grasp.rotation()))
        connect_error = None
        for place in self._place_ends(places, transfer, [request.start]):
            attempts: dict[str, int] = {}
            try:
                to_place = self.coarse_move("transfer", transfer, begin, place.above, attempts)
            except PlanningError as error:
                if error.code == ErrorCode.TIMEOUT:
                    raise
                connect_error = error
                continue
            self.deadline.check("retiming")
            leave = [] if escape is None else [self.timed_line("escape", escape, transfer)]
            return PickPlacePlan(
                [
                    self._transfer_segment([*leave, to_place]),
                    self._place_segment(place, transfer),
                    self._retreat_segment(place),
                ],
                grasp_pose=grasp,
                release_pose=place.tcp_pose,
                held_in_tcp=held,
                place_approach=self.settings.place_approach_distance,
                kto_attempts=attempts,
            )
        raise connect_error or self.search.error()

    # ------------------------------------------------------------------ ends
    def _ends(self) -> Iterator[tuple[End, End, Scene]]:
        """Pick and place ends that pass their checks, best candidates first."""
        request = self.request
        release = self._release()
        free = self._free_direction()
        for grasp, turned in self._grasps():
            self.deadline.check("grasp")
            self.search.grasp_candidates += 1
            lifts = [d for d in lift_directions(grasp) if not self._pads_meet_pile_points(grasp, d)]
            if not lifts:
                self.search.grasp_failures[PATH_MEETS_POINTS] += 1
                continue
            # drawn before the pads' test, as when IK told it: the same seeds for the rest
            seeds = self.seeds([request.start], grasp.translation())
            if self._pads_in_pile(grasp):
                self.search.grasp_failures[PADS_IN_PILE] += 1
                continue
            if turned and self._no_place(grasp):
                self.search.grasp_failures[NO_PLACE] += 1
                self.search.unplaced_turned += 1
                continue
            held = domino_in_tcp(grasp, request.domino_pose)
            transfer = self._scene("closed", held_in_tcp=held)
            pick = self._end(
                grasp,
                self.settings.pick_approach_distance,
                lifts,
                [self.approach, transfer],
                self.planner.fine_rules(True, self.nudge, request.pads_into_pile),
                seeds,
                self.search.grasp_failures,
            )
            if pick is None:
                continue
            self.search.picks_found += 1
            self.search.turned_picks_found += turned
            places = [p for p in place_grasps(release, held, free) if comes_from_above(p)]
            for place in self._place_ends(places, transfer, [pick.line[0], request.start]):
                yield pick, place, transfer

    def _pads_meet_pile_points(self, grasp: RigidTransform, lift: np.ndarray) -> bool:
        """Whether the pads' path to ``grasp`` (down the approach line along ``lift``, then
        closing on the domino) comes within pile_point_clearance of a pile point: a domino
        seen but not detected, for which the scenes have no box (arc seed 6: one standing on
        its edge beside the picked one's long face stopped the fingers at 31 mm, twice).
        Kept for the request's later tiers (the same points, grasps and lifts)."""
        if not len(self.pile_points):
            return False
        key = ("pads' path", poses_key([self.request.domino_pose, grasp]), lift.tobytes())
        return self.shared.remember(key, lambda: self._pads_path_near_points(grasp, lift))

    def _pads_path_near_points(self, grasp: RigidTransform, lift: np.ndarray) -> bool:
        settings, openings = self.settings, self.openings
        return pads_path_meets_points(
            Grasp(grasp, openings["closed"], openings["pregrasp"]),
            settings.pick_approach_distance,
            lift,
            self.pile_points,
            settings.pile_point_clearance,
        )

    def _pads_in_pile(self, grasp: RigidTransform) -> bool:
        """Whether a pad at ``grasp`` reaches more than pile_nudge into a pile domino
        (``pads.pads_in_pile``): no IK solution passes the pads–pile rule of either tier
        then. Never with ``pads_into_pile``."""
        if self.request.pads_into_pile:
            return False
        openings = self.openings
        return pads_in_pile(
            Grasp(grasp, openings["closed"], openings["pregrasp"]),
            self.request.pile,
            self.settings.pile_nudge,
        )

    def _no_place(self, grasp: RigidTransform) -> bool:
        """Whether the hold ``grasp`` gives has no place pose that passes the tests of
        ``_place_ends`` before IK and the pads' clearance to the standing dominoes at
        the pose, which every IK solution shares (``foreseen_refusal.no_place``). Asked
        of turned grasps only: a canonical one reaching the domino makes a refusal
        PLACE_UNREACHABLE (the slot's, not the domino's), which only IK tells. Kept for
        the request's later tiers."""
        key = ("no place", poses_key([self.request.domino_pose, self.request.place_pose, grasp]))
        reach = self.planner.wrist_reach
        return self.shared.remember(
            key, lambda: no_place(self.request, self.settings, grasp, reach)
        )

    def _place_ends(
        self, places: list[RigidTransform], transfer: Scene, seeds: list[np.ndarray]
    ) -> Iterator[End]:
        """The place ends among ``places`` (TCP poses, best first) that pass their checks."""
        self.search.place_candidates = len(places)
        for place_pose in places:
            place = self._end(
                place_pose,
                self.settings.place_approach_distance,
                [UP],
                [transfer, self.retreat],
                self.planner.fine_rules(at_pick=False),
                self.seeds(seeds, place_pose.translation()),
                self.search.place_failures,
            )
            if place is not None:
                yield place

    def _release(self) -> RigidTransform:
        """The held domino's pose when the fingers open: release_height above the place."""
        return RigidTransform(self.settings.release_height * UP) @ self.request.place_pose

    def _free_direction(self) -> np.ndarray:
        """The side of the place pose (±its z) where standing dominoes are farthest."""
        forward = self.request.place_pose.rotation().matrix()[:, 2]
        centre = self.request.place_pose.translation()

        def nearest(sign: float) -> float:
            ahead = [
                np.linalg.norm(p.translation() - centre)
                for p in self.request.standing
                if sign * (p.translation() - centre) @ forward > 0
            ]
            return min([FREE_SIDE_RADIUS, *ahead])

        return forward if nearest(1.0) >= nearest(-1.0) else -forward

    def _end(
        self,
        tcp_pose: RigidTransform,
        distance: float,
        directions: list[np.ndarray],
        scenes: list[Scene],
        rules: ClearanceRules,
        seeds: list[np.ndarray],
        failures: Counter,
    ) -> End | None:
        """IK at ``tcp_pose`` and a straight line away from it, keeping ``rules`` in every
        scene.

        ``directions`` are tried in order for the line (those along which the wrist leaves
        the elbow's reach are not); ``failures`` counts why seeds failed.
        """
        reach = self.planner.wrist_reach
        if reach.reaches(tcp_pose):  # else clear_solutions says so
            directions = [d for d in directions if reach.reaches(tcp_pose, distance * d)]
            if not directions:
                failures[LINE_WRIST_OUT] += 1
                return None
        ik = self.shared.ik(scenes[0], tcp_pose.rotation())
        target = tcp_pose.translation()
        checks = [(scene, rules) for scene in scenes]
        top_rules = self.planner.line_end_rules()
        solutions = self.clear_solutions(ik, target, seeds, checks, failures, TCP_FIXED_PAIRS)
        for q in solutions:
            for direction in directions:
                line, why = self.clear_line(ik, q, target, distance * direction, checks, top_rules)
                if line is None:
                    failures[why] += 1
                else:
                    return End(tcp_pose, line)
        return None

    # ------------------------------------------------------------------ connect
    def _connect(self, pick: End, place: End, transfer: Scene) -> PickPlacePlan:
        """Coarse moves between the ends, retimed and assembled into segments."""
        attempts: dict[str, int] = {}
        start, escape = self.request.start, self.escape_line
        begin = start if escape is None else escape[-1]
        to_pick = self.coarse_move(
            "approach_grasp", self.approach, begin, pick.above, attempts, free=True
        )
        to_place = self.coarse_move("transfer", transfer, pick.above, place.above, attempts)
        self.deadline.check("retiming")
        openings, force = self.openings, self.settings.grip_force
        pieces = {
            "escape": (
                []
                if escape is None
                else [self.timed_line("escape", escape, self.approach, free=True)]
            ),
            "down_to_grasp": self.timed_line(
                "descend_to_grasp", pick.line[::-1], self.approach, free=True
            ),
            "lift": self.timed_line("lift", pick.line, transfer),
        }
        segments = [
            Segment(
                "open_gripper",
                [],
                openings["release"],
                GRIPPER_OPEN,
                openings["pregrasp"],
                start=start,
            ),
            Segment(
                "approach_grasp",
                [*pieces["escape"], to_pick, pieces["down_to_grasp"]],
                openings["pregrasp"],
                GRIPPER_CLOSE,
                0.0,
                force,
            ),
            Segment("lift", [pieces["lift"]], openings["closed"]),
            self._transfer_segment([to_place]),
            self._place_segment(place, transfer),
            self._retreat_segment(place),
        ]
        held_in_tcp = domino_in_tcp(pick.tcp_pose, self.request.domino_pose)
        return PickPlacePlan(
            segments,
            grasp_pose=pick.tcp_pose,
            release_pose=place.tcp_pose,
            held_in_tcp=held_in_tcp,
            place_approach=self.settings.place_approach_distance,
            kto_attempts=attempts,
        )

    def _transfer_segment(self, pieces: list[TimedPath]) -> Segment:
        """Carrying the held domino to above its place, clear of the run: the hold can be
        looked at there, and a domino turned in the hand carried again from there. After a
        pick it starts above the grasp (the lift is its own segment): run backwards, it
        takes a hold that can be neither placed nor carried again back over the pile."""
        return Segment("transfer", pieces, self.openings["closed"])

    def _place_segment(self, place: End, transfer: Scene) -> Segment:
        """Straight down onto the place, the fingers opening there."""
        openings = self.openings
        down = self.timed_line("descend_to_place", place.line[::-1], transfer)
        return Segment("place", [down], openings["closed"], GRIPPER_OPEN, openings["release"])

    def _retreat_segment(self, place: End) -> Segment:
        line = self.timed_line(
            "retreat", place.line, self.retreat, self.settings.retreat_speed, free=True
        )
        return Segment("retreat", [line], self.openings["release"])


def turn_angle(a: RotationMatrix, b: RotationMatrix) -> float:
    """The angle [rad] of the rotation between two orientations."""
    return float(a.InvertAndCompose(b).ToAngleAxis().angle())

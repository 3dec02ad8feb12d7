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
from collections import Counter
from collections.abc import Callable, Iterator
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import (
    FINGER_SWAP,
    GRASP_TILT,
    Grasp,
    OrientedBox,
    canonical_grasp,
    comes_from_above,
    domino_in_tcp,
    pick_grasps,
    place_grasps,
    pregrasp_opening,
    release_opening,
    top_grasp,
)
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.ik import PoseIK
from dombot_planner.motion import (
    GRIPPER_CLOSE,
    GRIPPER_OPEN,
    LINE_WRIST_OUT,
    UP,
    ArmPlanner,
    Deadline,
    Plan,
    RequestMotions,
    Segment,
    reasons,
)
from dombot_planner.pads import pads_in_pile, pads_path_meets_points
from dombot_planner.request import GRASP_REACH, PickPlaceRequest, check_request, invalid, near_pick
from dombot_planner.scene import (
    ARM,
    HELD,
    OBSTACLES,
    PADS,
    PILE,
    STANDING,
    TABLE,
    TARGET,
    ClearanceRules,
    Scene,
)
from dombot_planner.settings import PlannerSettings
from dombot_planner.timing import TimedPath

FREE_SIDE_RADIUS = 0.1  # m: standing dominoes this close decide the free side
OWN_POINTS = 0.003  # m: pile points this close to the picked domino's box are its own
# Where the pads and the held domino are depends only on the TCP pose: when one of these
# pairs is too close at an IK solution, it is at every other one.
TCP_FIXED_PAIRS = tuple(f"{moving}–{other}" for moving in (PADS, HELD) for other in OBSTACLES)
# why a grasp failed before any IK (the pads' place and path depend on the TCP pose alone)
PATH_MEETS_POINTS = "pads' path meets pile points"
PADS_IN_PILE = "pads beyond pile_nudge into a pile domino"


@dataclass(kw_only=True)
class PickPlacePlan(Plan):
    grasp_pose: RigidTransform  # TCP when the gripper closes
    release_pose: RigidTransform  # TCP when it opens
    held_in_tcp: RigidTransform  # the domino in the TCP frame while held
    place_approach: float  # m straight down from where "transfer" ends to the release pose
    regrasped: bool = False  # the domino was turned in place first (two picks)
    nudged: bool = False  # the pads reach into a pile domino's box (up to pile_nudge)

    @property
    def held_above_place(self) -> RigidTransform:
        """The held domino where "transfer" ends, straight above where it is let go."""
        return RigidTransform(self.place_approach * UP) @ self.release_pose @ self.held_in_tcp


def steeper_grasps(domino_pose: RigidTransform, limit: float) -> list[RigidTransform]:
    """The canonical grasps turned about their closing axis (the domino's width) through
    the TCP towards a vertical approach, by ``limit``/2 and ``limit``, where that also
    tilts them less from the domino's thickness axis than GRASP_TILT; best first, as
    dombot_description.grasp.pick_grasps ranks (most downward, then leaning outwards).

    Beyond ~0.6 m from the base the arm reaches a canonical grasp (63° from vertical on a
    flat domino) only leaning outwards, and on a domino leaning by τ about its width that
    one leans 63° + τ, bringing the gripper body down to the table; a steeper approach
    reaches it and keeps the gripper higher. The pads still close across the width on the
    same spot (the TCP stays) and, tilted less from the thickness axis, overlap more of
    the side faces (docs/PLANNER.md, grasp strategy); the domino is held turned by the
    same angle and the place poses follow from the hold (the gripper leans that much more
    there). The planner's checks decide the rest (pad tips to the table and the pile).
    """
    if limit <= 0.0:
        return []
    outward = domino_pose.translation() * [1.0, 1.0, 0.0]
    outward /= max(np.linalg.norm(outward), 1e-9)
    thickness = domino_pose.rotation().matrix()[:, 2]
    turned = []
    for grasp in pick_grasps(domino_pose):
        matrix = grasp.pose.rotation().matrix()
        # Turned by t about G y the approach is z cos t + x sin t: it points further down
        # for t of the sign opposite to x_z.
        sign = -1.0 if matrix[2, 0] >= 0.0 else 1.0
        for turn in (0.5 * limit, limit):
            pose = grasp.pose @ RigidTransform(RotationMatrix.MakeYRotation(sign * turn))
            approach = pose.rotation().matrix()[:, 2]
            if comes_from_above(pose) and abs(approach @ thickness) > math.cos(GRASP_TILT) + 1e-9:
                turned.append(pose)

    def score(pose: RigidTransform) -> float:
        approach = pose.rotation().matrix()[:, 2]
        horizontal = approach * [1.0, 1.0, 0.0]
        norm = np.linalg.norm(horizontal)
        return -approach[2] + (0.3 * float(horizontal @ outward) / norm if norm > 1e-9 else 0.0)

    return sorted(turned, key=lambda pose: -round(score(pose), 9))


def flatter_grasps(domino_pose: RigidTransform, turn: float, shift: float) -> list[RigidTransform]:
    """The canonical grasps turned about their closing axis through the TCP away from the
    domino's thickness axis and moved along its length towards the end the pads hold
    (``canonical_grasp(turn, shift)``), by half of ``turn`` and ``shift``, then by all of
    them, each ranked as pick_grasps ranks; none when both are 0.

    At place the gripper of such a hold stands more upright (27° from vertical less the
    turn) and its pads ride higher beside the neighbours' tops. Where a run curves, the
    neighbour on the inner side of the curve comes closer to the pads of the canonical
    hold leaning over it than fine_obstacle_clearance, and near the inner reach limit the
    hold leaning the other way needs the elbow beyond its limit (circle30 slot 20, 0.447 m
    from the base: 0.9 mm, and no IK). At pick the gripper lies flatter, its body and the
    wrist closer to the table (the planner's checks keep them clear), and the pads press
    a little less of the side faces (docs/PLANNER.md, grasp strategy).
    """
    if turn <= 0.0 and shift <= 0.0:
        return []
    return [
        grasp.pose
        for part in (0.5, 1.0)
        for grasp in pick_grasps(
            domino_pose, tcp_in_domino=canonical_grasp(part * turn, part * shift)
        )
    ]


def ranked_grasps(
    request: PickPlaceRequest, settings: PlannerSettings
) -> tuple[list[RigidTransform], tuple[list[RigidTransform], list[RigidTransform]]]:
    """The request's grasp and its finger-swapped twin (the same gripper placement),
    then dombot_description.grasp's ranked grasps; only those coming from above.

    A request's grasp (e.g. perception's, which cleared its point cloud, undetected
    dominoes included) is preferred, not required: the pile the planner knows is only
    what perception detected. Also returned, for when none of them can be used
    (``RequestPlanning._grasps``): the steeper grasps, turned towards a vertical approach,
    and the flatter ones, whose holds stand more upright at place.
    """
    domino, given = request.domino_pose, request.grasp_pose
    first = [] if given is None else [given, given @ FINGER_SWAP]

    def others(poses: list[RigidTransform]) -> list[RigidTransform]:
        return [
            g
            for g in poses
            if comes_from_above(g) and not any(g.IsNearlyEqualTo(f, 1e-6) for f in first)
        ]

    canonical = others([g.pose for g in pick_grasps(domino)])
    steeper = others(steeper_grasps(domino, settings.steeper_grasp_turn))
    flatter = others(
        flatter_grasps(domino, settings.flatter_grasp_turn, settings.flatter_grasp_shift)
    )
    return [g for g in first if comes_from_above(g)] + canonical, (steeper, flatter)


def finger_openings(request: PickPlaceRequest) -> dict[str, float]:
    """The finger openings of ``request``'s pick: approaching, closed on it, letting go."""
    closed = request.grasp_width or DOMINO_SIZE[1]
    return {
        "pregrasp": pregrasp_opening(closed),
        "closed": closed,
        "release": release_opening(closed),
    }


def pile_points(request: PickPlaceRequest) -> np.ndarray:
    """``request``'s pile points but those within OWN_POINTS of the domino to pick."""
    target = OrientedBox(request.domino_pose, np.asarray(DOMINO_SIZE))
    points = request.pile_points
    return points[target.signed_distance(points) > OWN_POINTS]


def regrasp_requests(request: PickPlaceRequest) -> tuple[PickPlaceRequest, PickPlaceRequest]:
    """The regrasp's two picks: the domino turned a quarter turn in place, then picked
    from there (the planner's grasps; its start: where the first ends)."""
    domino = request.domino_pose
    turned = RigidTransform(
        RotationMatrix.MakeZRotation(math.pi / 2) @ domino.rotation(), domino.translation()
    )
    return replace(request, place_pose=turned), replace(
        request, domino_pose=turned, grasp_pose=None
    )


def regrasp_grasp(domino: RigidTransform) -> RigidTransform:
    """The TCP pose that turns ``domino`` in place: the top grasp."""
    return pick_grasps(domino, tcp_in_domino=top_grasp())[0].pose


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


def fallback_failed(error: PlanningError, fallback: PlanningError, how: str) -> PlanningError:
    """The error to raise when planning ``how`` after ``error`` failed too: the fallback's
    timeout as it is, else the first error (its code and stage) with both reasons."""
    if fallback.code == ErrorCode.TIMEOUT:
        return fallback
    return PlanningError(error.code, error.stage, f"{error.message}; {how} failed too ({fallback})")


class SharedWork:
    """The scenes and IK programs of one /plan_place request, shared by its planning
    tiers (pads clear of the pile, pads nudging it, the regrasp's two picks).

    A refused request runs the grasp search up to three times; the tiers differ in a
    clearance rule or in a pose, not in the scenes they build or the IK they solve. A
    scene keeps its clearances per configuration, an IK program its solutions per
    (position, seed), and ``remember`` what else no tier changes (the pads' path against
    the pile points): pure functions of their inputs, so a later tier repeats what an
    earlier one computed (the same answers, the same random seeds) without the work: only
    what its changed rule or pose makes new is computed.
    """

    def __init__(self, planner: PickPlacePlanner) -> None:
        self.planner = planner
        self._scenes: dict[tuple, Scene] = {}
        self._iks: dict[tuple[int, bytes], PoseIK] = {}
        self._kept: dict[tuple, bool] = {}

    def scene(
        self,
        opening: float,
        request: PickPlaceRequest,
        target: RigidTransform | None = None,
        held_in_tcp: RigidTransform | None = None,
    ) -> Scene:
        """The scene of ``request``'s standing and pile dominoes at finger ``opening``."""
        key = (
            opening,
            poses_key(request.standing),
            poses_key(request.pile),
            poses_key([] if target is None else [target]),
            poses_key([] if held_in_tcp is None else [held_in_tcp]),
        )
        if key not in self._scenes:
            self._scenes[key] = Scene(
                self.planner.plants.get(opening),
                self.planner.scenario.tcp_frame,
                request.standing,
                pile=request.pile,
                target=target,
                held_in_tcp=held_in_tcp,
            )
        return self._scenes[key]

    def ik(self, scene: Scene, rotation: RotationMatrix) -> PoseIK:
        """The IK program for TCP poses of ``rotation`` in ``scene`` (one of ``scene()``'s)."""
        key = (id(scene), rotation.matrix().tobytes())
        if key not in self._iks:
            self._iks[key] = PoseIK(scene, rotation)
        return self._iks[key]

    def remember(self, key: tuple, compute: Callable[[], bool]) -> bool:
        """``compute()``, kept under ``key`` for the request's later tiers."""
        if key not in self._kept:
            self._kept[key] = compute()
        return self._kept[key]


def poses_key(poses) -> bytes:
    """Poses as bytes, to recognise the same list of them."""
    return b"".join(pose.GetAsMatrix4().tobytes() for pose in poses)


@dataclass
class End:
    """One end of the transfer: IK at the pose and the vertical line above it."""

    tcp_pose: RigidTransform
    line: np.ndarray  # waypoints from the pose (index 0) up to the approach height

    @property
    def above(self) -> np.ndarray:
        return self.line[-1]


def lift_directions(grasp: RigidTransform) -> list[np.ndarray]:
    """Straight up, else 45° up and towards where the approach points horizontally.

    A grasp leaning away from the arm base on the near side of the pile has the wrist
    so close to the shoulder that lifting straight up runs into the elbow limit; the
    tilted lift moves the wrist outwards instead (the open pads pass beside the domino).
    """
    horizontal = grasp.rotation().matrix()[:, 2] * [1.0, 1.0, 0.0]
    norm = np.linalg.norm(horizontal)
    if norm < 1e-6:
        return [UP]
    return [UP, (UP + horizontal / norm) / np.sqrt(2.0)]


@dataclass
class EndSearch:
    """What the search for pick and place ends tried: the error when nothing was found."""

    grasp_candidates: int = 0
    place_candidates: int = 0
    picks_found: int = 0
    turned_picks_found: int = 0  # of picks_found, with steeper or flatter grasps
    grasp_failures: Counter = field(default_factory=Counter)
    place_failures: Counter = field(default_factory=Counter)

    def error(self) -> PlanningError:
        """GRASP_UNREACHABLE also when only turned (steeper or flatter) grasps reached the
        domino and none of their holds could be placed: the regrasp (canonical grasps) may
        still work."""
        if self.picks_found == self.turned_picks_found:
            message = (
                f"no collision-free IK and approach line for any of {self.grasp_candidates} "
                f"grasps ({reasons(self.grasp_failures)})"
            )
            if self.turned_picks_found:
                message += (
                    f"; {self.turned_picks_found} turned grasps reach it, but no place pose "
                    f"suits their hold ({reasons(self.place_failures)})"
                )
            return PlanningError(ErrorCode.GRASP_UNREACHABLE, "grasp", message)
        return PlanningError(
            ErrorCode.PLACE_UNREACHABLE,
            "place",
            f"no collision-free IK and approach line for any of {self.place_candidates} "
            f"place poses ({reasons(self.place_failures)})",
        )


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
        docs/PLANNER.md), while a bump of the gripper body or arm stops the arm short of
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
        nudging, they found 2 of those 68 plans."""
        yield from ((grasp, False) for grasp in self.grasps)
        steeper, flatter = self.turned
        if self.search.picks_found:
            yield from ((grasp, True) for grasp in flatter + steeper)
            return
        yield from ((grasp, True) for grasp in steeper)
        if self.nudge or self.search.picks_found:
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
        to_pick = self.coarse_move("approach_grasp", self.approach, begin, pick.above, attempts)
        to_place = self.coarse_move("transfer", transfer, pick.above, place.above, attempts)
        self.deadline.check("retiming")
        openings, force = self.openings, self.settings.grip_force
        pieces = {
            "escape": [] if escape is None else [self.timed_line("escape", escape, self.approach)],
            "down_to_grasp": self.timed_line("descend_to_grasp", pick.line[::-1], self.approach),
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
        line = self.timed_line("retreat", place.line, self.retreat)
        return Segment("retreat", [line], self.openings["release"])


def turn_angle(a: RotationMatrix, b: RotationMatrix) -> float:
    """The angle [rad] of the rotation between two orientations."""
    return float(a.InvertAndCompose(b).ToAngleAxis().angle())

"""Pick-and-place and strike requests in plain Python types, and the checks every request
passes before any planning: finite numbers, unit quaternions, a known start state, a time
budget and obstacle lists no larger than the documented maxima, poses inside the workspace
(reach from the base, height, over the table top), a place pose (or the domino to strike)
that does not overlap the table or a standing domino, a domino to strike that stands
upright. ``near_pick`` drops the pile dominoes and points too far from the pick to matter,
so a big but valid request stays within its budget."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field, replace

import numpy as np
from pydrake.common.eigen_geometry import Quaternion
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description import DOMINO_SIZE, domino_corners, tilt_from_vertical
from dombot_description.grasp import OrientedBox, gripper_geometry, pregrasp_opening
from dombot_description.pusher import MAX_SWEEP_DISTANCE
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.settings import PlannerSettings

QUATERNION_TOLERANCE = 1e-3  # |q| must be 1 within this (docs/ARCHITECTURE.md)
JOINT_LIMIT_TOLERANCE = 1e-3  # rad a start state may sit beyond a limit (it is clipped)
REST_SPEED = 0.01  # rad/s: an arm whose joints all move slower than this is at rest
OVERLAP_TOLERANCE = 1e-4  # m two dominoes may overlap (touching faces)
TABLE_TOLERANCE = 5e-4  # m a place pose may reach into the table top
GRASP_REACH = 0.05  # m: a grasp TCP farther than this from its domino's centre is a mistake
UPRIGHT_TOLERANCE = math.radians(10.0)  # body x this close to vertical stands upright
MAX_PUSH_DISTANCE = 0.05  # m past the back face: farther reaches the next domino of a run
SWEEP_CHECK_STEP = 0.005  # m between the poses of a swept domino checked against the run
MAX_PUSH_SPEED = 0.5  # m/s: faster throws the domino instead of tipping it
# Request sizes (docs/PLANNER.md): larger requests are refused, not truncated. Every
# obstacle becomes Drake geometry of each request scene, so the counts bound the time spent
# before planning proper and the memory of a request.
MAX_TIME_BUDGET = 3600.0  # s: an hour never cuts a search short (tests, slow machines)
# (Drake registers them one by one, ~3 ms each on a loaded 2-core machine)
MAX_STANDING = 200  # standing_dominoes: more than a build area holds in a run
MAX_PILE_DOMINOES = 200  # pile_dominoes: the largest pile the simulator pours
MAX_PILE_POINTS = 50_000  # pile_points
# m (horizontal) from the domino to pick: pile dominoes and points farther away are dropped.
# The gripper body spans 15 cm and leans 60° at a grasp, and coarse moves pass low over the
# pile: the bring-up sends the detections within 0.25 m (offers.NEIGHBOUR_RADIUS, found
# where 8 cm missed dominoes the gripper met); this keeps a margin beyond that.
PILE_NEIGHBOURHOOD = 0.3


@dataclass(frozen=True)
class PickPlaceRequest:
    domino_pose: RigidTransform  # the domino to pick, body frame in world
    place_pose: RigidTransform  # where it must end up
    start: np.ndarray  # arm joint positions [rad]
    grasp_pose: RigidTransform | None = None  # TCP pose to try first; None: the ranked grasps
    grasp_width: float = 0.0  # finger opening closed on the domino [m]; 0: its width
    standing: tuple[RigidTransform, ...] = ()  # dominoes already placed
    pile: tuple[RigidTransform, ...] = ()  # other dominoes seen near the one to pick
    # seen points near it on no domino of ``pile`` (N×3, world): what perception saw but
    # could not fit a domino to
    pile_points: np.ndarray = field(default_factory=lambda: np.zeros((0, 3)))
    # the pads may reach into ``pile`` (only arm and gripper body keep clear of it; the
    # pile_points still bound the pads' path)
    pads_into_pile: bool = False
    time_budget: float = 0.0  # s; 0: the planner's default
    # The domino is in the hand already, at domino_pose (measured there), held where the
    # start puts the TCP: plan only the carry to place_pose and the retreat.
    holding: bool = False


@dataclass(frozen=True)
class StrikeRequest:
    domino_pose: RigidTransform  # the upright domino to push over (first of the run)
    # ... or, with ``sweep`` (a horizontal unit vector), a domino in any pose to push that
    # way across the table: debris lying where the run goes that no grasp reaches.
    start: np.ndarray  # arm joint positions [rad]
    finger_opening: float | None = None  # m at the start; None: unknown (closed first)
    standing: tuple[RigidTransform, ...] = ()  # the rest of the run
    push_distance: float = 0.0  # m past the back face; 0: the planner's default
    push_speed: float = 0.0  # m/s; 0: the planner's default
    time_budget: float = 0.0  # s; 0: the planner's default
    sweep: np.ndarray | None = None


def invalid(stage: str, message: str) -> PlanningError:
    return PlanningError(ErrorCode.INVALID_REQUEST, stage, message)


def pose_from(
    position: Sequence[float], quaternion_wxyz: Sequence[float], what: str
) -> RigidTransform:
    """A pose from message numbers; NaN, infinity or a non-unit quaternion is refused."""
    values = np.array([*position, *quaternion_wxyz], dtype=float)
    if not np.all(np.isfinite(values)):
        raise invalid("validation", f"{what} contains NaN or infinity")
    norm = float(np.linalg.norm(values[3:]))
    if abs(norm - 1.0) > QUATERNION_TOLERANCE:
        raise invalid("validation", f"{what} quaternion has norm {norm:.6f}, must be unit")
    rotation = RotationMatrix(Quaternion(values[3:] / norm))
    return RigidTransform(rotation, values[:3])


def arm_positions(
    names: Sequence[str],
    positions: Sequence[float],
    arm_joints: Sequence[str],
    lower: np.ndarray,
    upper: np.ndarray,
    what: str = "start_state",
    velocities: Sequence[float] = (),
    velocity_limits: np.ndarray | None = None,
) -> np.ndarray:
    """The arm's joint positions from a JointState's names and positions, checked; its
    velocities (may be empty) must be finite and within ``velocity_limits`` (the plan
    starts at rest, so their values are otherwise unused)."""
    if len(names) != len(positions):
        raise invalid("validation", f"{what} has {len(names)} names but {len(positions)} positions")
    repeated = sorted({name for name in names if names.count(name) > 1})
    if repeated:
        raise invalid("validation", f"{what} names {', '.join(repeated)} more than once")
    if velocities:
        check_velocities(names, velocities, arm_joints, velocity_limits, what)
    by_name = dict(zip(names, positions, strict=True))
    missing = [joint for joint in arm_joints if joint not in by_name]
    if missing:
        raise invalid("validation", f"{what} lacks joints {', '.join(missing)}")
    q = np.array([by_name[joint] for joint in arm_joints], dtype=float)
    if not np.all(np.isfinite(q)):
        raise invalid("validation", f"{what} contains NaN or infinity")
    outside = (q < lower - JOINT_LIMIT_TOLERANCE) | (q > upper + JOINT_LIMIT_TOLERANCE)
    if np.any(outside):
        joint = arm_joints[int(np.argmax(outside))]
        raise invalid("validation", f"{what}: {joint} is outside its joint limits")
    return np.clip(q, lower, upper)


def check_velocities(
    names: Sequence[str],
    velocities: Sequence[float],
    arm_joints: Sequence[str],
    limits: np.ndarray | None,
    what: str,
) -> None:
    if len(velocities) != len(names):
        raise invalid(
            "validation", f"{what} has {len(names)} names but {len(velocities)} velocities"
        )
    by_name = dict(zip(names, velocities, strict=True))
    for index, joint in enumerate(arm_joints):
        value = by_name.get(joint, 0.0)
        limit = math.inf if limits is None else limits[index]
        if not (math.isfinite(value) and abs(value) <= limit * (1 + JOINT_LIMIT_TOLERANCE)):
            raise invalid("validation", f"{what}: {joint} velocity {value} is beyond its limit")


def at_rest(names: Sequence[str], velocities: Sequence[float], arm_joints: Sequence[str]) -> bool:
    """Whether a JointState shows every arm joint slower than REST_SPEED (no velocities:
    taken as at rest). A plan starts at rest: from a state read while the arm still
    moves it starts off where the arm stops (0.65 rad/s decelerating at 8.5 rad/s² is
    25 mrad from it)."""
    if not velocities:
        return True
    by_name = dict(zip(names, velocities, strict=False))
    return all(abs(by_name.get(joint, 0.0)) < REST_SPEED for joint in arm_joints)


def finger_opening(
    names: Sequence[str], positions: Sequence[float], gripper_joints: Sequence[str]
) -> float | None:
    """The gripper opening [m] a JointState reports (sum of the fingers); None: not in it."""
    by_name = dict(zip(names, positions, strict=False))
    values = [by_name.get(joint) for joint in gripper_joints]
    if any(v is None or not math.isfinite(v) for v in values):
        return None
    return float(sum(values))


def check_budget(budget: float) -> None:
    if not (math.isfinite(budget) and 0 <= budget <= MAX_TIME_BUDGET):
        raise invalid(
            "validation", f"time_budget must be 0 (default) to {MAX_TIME_BUDGET} s, got {budget}"
        )


def check_sizes(**counts: tuple[int, int]) -> None:
    """Each named list's (length, maximum); a list longer than its maximum is refused."""
    for name, (count, most) in counts.items():
        if count > most:
            raise invalid("validation", f"{name} has {count} entries, at most {most} are served")


def near_pick(request: PickPlaceRequest) -> PickPlaceRequest:
    """``request`` without the pile dominoes and points farther than PILE_NEIGHBOURHOOD
    from the domino to pick, and without any pile when it is held already (unused)."""
    if request.holding:
        return replace(request, pile=(), pile_points=np.zeros((0, 3)))
    centre = request.domino_pose.translation()[:2]
    pile = tuple(
        pose
        for pose in request.pile
        if np.linalg.norm(pose.translation()[:2] - centre) <= PILE_NEIGHBOURHOOD
    )
    points = request.pile_points
    near = np.linalg.norm(points[:, :2] - centre, axis=1) <= PILE_NEIGHBOURHOOD
    return replace(request, pile=pile, pile_points=points[near])


def check_request(
    request: PickPlaceRequest, settings: PlannerSettings, table: TableTop | None = None
) -> None:
    """Everything that can be said about a request without planning; raises PlanningError."""
    check_budget(request.time_budget)
    check_sizes(
        standing_dominoes=(len(request.standing), MAX_STANDING),
        pile_dominoes=(len(request.pile), MAX_PILE_DOMINOES),
        pile_points=(len(request.pile_points), MAX_PILE_POINTS),
    )
    width = request.grasp_width
    stroke = gripper_geometry().max_opening
    if not (math.isfinite(width) and width >= 0.0 and pregrasp_opening(width) <= stroke):
        raise invalid(
            "validation",
            f"grasp_width must be 0 (auto) or leave room to pre-grasp within the {stroke} m "
            f"stroke, got {width}",
        )
    for what, pose in (("domino_pose", request.domino_pose), ("place_pose", request.place_pose)):
        check_workspace(pose, what, settings, table)
    points = request.pile_points
    if points.ndim != 2 or points.shape[1] != 3 or not np.all(np.isfinite(points)):
        raise invalid("validation", "pile_points must be finite 3-D points")
    if request.grasp_pose is not None and not request.holding:
        reach = np.linalg.norm(request.grasp_pose.translation() - request.domino_pose.translation())
        if reach > GRASP_REACH:
            raise invalid(
                "validation", f"grasp_pose is {reach * 1000:.0f} mm from the domino's centre"
            )
    check_place_is_free(request.place_pose, request.standing)


def check_strike_request(
    request: StrikeRequest, settings: PlannerSettings, table: TableTop | None = None
) -> None:
    """Everything that can be said about a strike or sweep request without planning."""
    check_budget(request.time_budget)
    check_sizes(standing_dominoes=(len(request.standing), MAX_STANDING))
    sweep = request.sweep is not None
    longest = MAX_SWEEP_DISTANCE if sweep else MAX_PUSH_DISTANCE
    for name, value, most in (
        ("push_distance", request.push_distance, longest),
        ("push_speed", request.push_speed, MAX_PUSH_SPEED),
    ):
        if not (math.isfinite(value) and 0.0 <= value <= most):
            raise invalid("validation", f"{name} must be 0 (default) to {most}, got {value}")
    check_workspace(request.domino_pose, "domino_pose", settings, table)
    if sweep:
        check_sweep(request, request.push_distance or settings.push_distance)
        return
    tilt = tilt_from_vertical(request.domino_pose.rotation().matrix())
    if tilt > UPRIGHT_TOLERANCE:
        raise invalid(
            "validation",
            f"domino_pose is not upright: its body x is {math.degrees(tilt):.0f}° from vertical "
            f"(at most {math.degrees(UPRIGHT_TOLERANCE):.0f}°); to push a fallen domino aside, "
            "give a sweep direction",
        )
    check_place_is_free(request.domino_pose, request.standing, "domino_pose")


def check_sweep(request: StrikeRequest, distance: float) -> None:
    """A horizontal unit direction, and a path on which the swept domino meets no standing
    domino it does not touch already (debris often leans on its neighbours)."""
    direction = np.asarray(request.sweep, dtype=float)
    if direction.shape != (3,) or not np.all(np.isfinite(direction)):
        raise invalid("validation", f"sweep_direction must be 3 finite numbers, got {direction}")
    if abs(np.linalg.norm(direction) - 1.0) > QUATERNION_TOLERANCE or abs(direction[2]) > 1e-3:
        raise invalid(
            "validation", f"sweep_direction must be a horizontal unit vector, got {direction}"
        )
    blocker = sweep_blocker(request.domino_pose, direction, distance, request.standing)
    if blocker is not None:
        i, travel = blocker
        x, y = request.standing[i].translation()[:2]
        raise PlanningError(
            ErrorCode.PLACE_IN_COLLISION,
            "validation",
            f"sweeping domino_pose {travel * 1000:.0f} mm along "
            f"({direction[0]:.2f}, {direction[1]:.2f}) pushes it into "
            f"standing_dominoes[{i}] at ({x:.3f}, {y:.3f}) m",
        )


def sweep_blocker(
    start: RigidTransform,
    direction: np.ndarray,
    distance: float,
    standing: Sequence[RigidTransform],
) -> tuple[int, float] | None:
    """The index of the first of ``standing`` that the domino at ``start``, pushed
    ``distance`` along ``direction`` (a horizontal unit 3-vector), meets without touching
    it already, and how far it had gone; None when its path is free."""
    touching = {i for i, other in enumerate(standing) if dominoes_overlap(start, other, 0.0)}
    steps = max(1, math.ceil(distance / SWEEP_CHECK_STEP))
    for travel in np.linspace(0.0, distance, steps + 1)[1:]:
        moved = RigidTransform(start.rotation(), start.translation() + travel * direction)
        for i, other in enumerate(standing):
            if i not in touching and dominoes_overlap(moved, other, OVERLAP_TOLERANCE):
                return i, float(travel)
    return None


@dataclass(frozen=True)
class TableTop:
    """The table top's extent in world x and y [m] (scene.table_top reads it from the cell)."""

    x: tuple[float, float]
    y: tuple[float, float]

    def holds(self, x: float, y: float) -> bool:
        """A domino centre at (x, y) at least half a domino length inside the edges."""
        inset = DOMINO_SIZE[0] / 2
        return (
            self.x[0] + inset <= x <= self.x[1] - inset
            and self.y[0] + inset <= y <= self.y[1] - inset
        )


def check_workspace(
    pose: RigidTransform, what: str, settings: PlannerSettings, table: TableTop | None = None
) -> None:
    """Within reach of the base axis, at a domino's height, and over the table top."""
    x, y, z = pose.translation()
    reach, (low, high) = math.hypot(x, y), settings.workspace_reach
    z_low, z_high = settings.workspace_height
    on_table = table is None or table.holds(x, y)
    if not (low <= reach <= high and z_low <= z <= z_high and on_table):
        over = "" if table is None else f", over the table top x {table.x} y {table.y} m"
        raise PlanningError(
            ErrorCode.OUTSIDE_WORKSPACE,
            "validation",
            f"{what} at ({x:.3f}, {y:.3f}, {z:.3f}) m is outside the workspace "
            f"(reach {low}–{high} m from the arm base axis, height {z_low}–{z_high} m{over})",
        )


def box_corners(pose: RigidTransform) -> np.ndarray:
    return domino_corners(pose.GetAsMatrix4())


def dominoes_overlap(a: RigidTransform, b: RigidTransform, tolerance: float) -> bool:
    """Separating-axis test of two domino boxes; overlaps shallower than ``tolerance`` pass."""
    size = np.array(DOMINO_SIZE)
    return OrientedBox(a, size).overlaps(OrientedBox(b, size), tolerance)


def check_place_is_free(
    place: RigidTransform, standing: Sequence[RigidTransform], what: str = "place_pose"
) -> None:
    lowest = box_corners(place)[:, 2].min()
    if lowest < -TABLE_TOLERANCE:
        raise PlanningError(
            ErrorCode.PLACE_IN_COLLISION,
            "validation",
            f"{what} reaches {-lowest * 1000:.1f} mm into the table",
        )
    for index, other in enumerate(standing):
        if dominoes_overlap(place, other, OVERLAP_TOLERANCE):
            x, y = other.translation()[:2]
            raise PlanningError(
                ErrorCode.PLACE_IN_COLLISION,
                "validation",
                f"{what} overlaps standing_dominoes[{index}] at ({x:.3f}, {y:.3f}) m",
            )

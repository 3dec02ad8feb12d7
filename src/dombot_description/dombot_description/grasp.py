"""How the gripper holds a domino: the one grasp definition for planner, perception and bring-up.

Conventions (see also docs/ARCHITECTURE.md and docs/PLANNER.md):

* Domino body frame D: origin at the centre, x along the 48 mm length, y along the 24 mm
  width, z along the 7.5 mm thickness.
* Gripper TCP frame G (``wsg_tcp``): z = approach (out of the fingers), fingers close
  along y, origin between the pads 9 mm in from their tips.
* The canonical grasp X_DG closes the fingers across the domino's *width* (G y = D y) and
  tilts the approach by ``GRASP_TILT`` = 63° from the domino's −z axis towards its +x axis,
  with the TCP at ``TCP_IN_DOMINO`` = (−19, 0, 9.25) mm. Why: a flat domino (D z up) is
  picked with the gripper leaning 63° from vertical and stood up (D x down) with it leaning
  27° from vertical; the sum must be 90° because the domino turns 90° about its y axis
  between pile and run. 45°/45° puts the pads onto the neighbours of a gap in a run; at 63°
  the pads stay 1.8 mm above the table at pick, ≥ 3.5 mm from neighbours standing 28.8 mm
  away on both sides at place, and the gripper body ≥ 14 mm above the table (measured with
  Drake geometry queries in tests/description/test_grasp.py).
* The pads grip the domino's side faces near its −x end; at place that end is the top.
* A domino is a box: its pose is only defined up to ``SYMMETRIES`` {I, Rx(π), Ry(π),
  Rz(π)}; the gripper is symmetric under a half turn about its approach axis
  (``FINGER_SWAP``: the fingers trade places, joint 7 differs by π). A grasp is
  X_WG = X_WD · S · X_DG · F for S in SYMMETRIES and F in {I, FINGER_SWAP}. The finger
  swap chosen at pick persists to the place (the held domino turns with the wrist), so the
  place candidates are X_WP · S · X_DG · F with the same F.

Gripper dimensions are read from ``models/wsg50.urdf`` so they have one source of truth.
"""

from __future__ import annotations

import math
import xml.etree.ElementTree as ET
from collections.abc import Sequence
from dataclasses import dataclass
from functools import cache

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description import DOMINO_SIZE, PACKAGE_DIR

GRASP_TILT = math.radians(63.0)
TCP_IN_DOMINO = np.array([-0.019, 0.0, 0.00925])  # m, in the domino frame
TOP_GRASP_HEIGHT = 0.007  # m: TCP above the centre in the top grasp (pad tips 1.75 mm up)
PREGRASP_CLEARANCE = 0.008  # m per side between open pads and the domino at pick
RELEASE_CLEARANCE = 0.005  # m per side when the fingers let go at place
SYMMETRIES = (
    RotationMatrix(),
    RotationMatrix.MakeXRotation(math.pi),
    RotationMatrix.MakeYRotation(math.pi),
    RotationMatrix.MakeZRotation(math.pi),
)
FINGER_SWAP = RigidTransform(RotationMatrix.MakeZRotation(math.pi))
# An approach with less downward component than this comes from below the domino: not usable.
MIN_DOWNWARD_APPROACH = 0.05
# A box swept obliquely to its axes is covered by pieces this long: each overhangs the
# true swept volume by less than it (the planner keeps pads 1.5 mm from pile points).
SWEEP_STEP = 0.002  # m
NEAREST_GROUP = 8  # boxes in a row bounded by one box in nearest_distance
# m: more than the rounding difference of a point's coordinates in a box's frame computed
# as (p - c) R or as p R - c R (~1e-15 m within a few metres of the origin)
ROUNDING = 1e-9
WSG_URDF = PACKAGE_DIR / "models" / "wsg50.urdf"


@dataclass(frozen=True)
class OrientedBox:
    """A box of ``size`` (full edge lengths) whose centre frame is ``pose`` in world."""

    pose: RigidTransform
    size: np.ndarray

    def signed_distance(self, points: np.ndarray) -> np.ndarray:
        """Signed distance of each row of ``points`` (N×3, world) to the box: < 0 inside."""
        local = (np.asarray(points, dtype=float) - self.pose.translation()) @ (
            self.pose.rotation().matrix()
        )
        return excess_signed_distance(np.abs(local) - self.size / 2.0)

    def surface(self, step: float) -> np.ndarray:
        """Points on the six faces (N×3, world), ``step`` apart or closer (corners included)."""
        half, faces = self.size / 2.0, []
        for axis in range(3):
            others = [a for a in range(3) if a != axis]
            counts = [math.ceil(2.0 * half[a] / step) + 1 for a in others]
            grids = [np.linspace(-half[a], half[a], n) for a, n in zip(others, counts, strict=True)]
            u, v = (g.ravel() for g in np.meshgrid(*grids, indexing="ij"))
            for sign in (-1.0, 1.0):
                local = np.zeros((u.size, 3))
                local[:, others[0]], local[:, others[1]], local[:, axis] = u, v, sign * half[axis]
                faces.append(local)
        rotation = self.pose.rotation().matrix()
        return np.concatenate(faces) @ rotation.T + self.pose.translation()

    def overlaps(self, other: OrientedBox, tolerance: float = 0.0) -> bool:
        """Separating-axis test of two boxes; overlaps shallower than ``tolerance`` (along
        the separating axes) pass."""
        return bool(self.overlapping(BoxArray.of([other]), tolerance)[0])

    def overlapping(self, others: BoxArray, tolerance: float = 0.0) -> np.ndarray:
        """``overlaps`` against each of ``others`` at once (k booleans): the 15 candidate
        axes of every pair in numpy, where a loop per box and axis cost the planner ~10 %
        of its CPU (pads.pads_in_pile)."""
        axes_a = self.pose.rotation().matrix()  # columns: the box's axes in world
        rows_a = np.broadcast_to(axes_a.T, (len(others), 3, 3))
        rows_b = np.swapaxes(others.rotations, 1, 2)
        crosses = np.cross(rows_a[:, :, None, :], rows_b[:, None, :, :]).reshape(-1, 9, 3)
        candidates = np.concatenate([rows_a, rows_b, crosses], axis=1)  # k×15×3
        norms = np.linalg.norm(candidates, axis=2)
        usable = norms >= 1e-9
        candidates = candidates / np.where(usable, norms, 1.0)[..., None]
        reach = np.abs(candidates @ axes_a) @ (self.size / 2.0) + np.einsum(
            "kcj,kj->kc", np.abs(candidates @ others.rotations), others.sizes / 2.0
        )
        offset = np.einsum("kci,ki->kc", candidates, others.centres - self.pose.translation())
        separated = usable & (np.abs(offset) >= reach - tolerance)
        return ~separated.any(axis=1)

    def swept(self, translation: np.ndarray) -> OrientedBox:
        """The box of the same orientation covering this one moved along ``translation``
        (world): exactly the swept volume when the move is along one of its axes."""
        rotation = self.pose.rotation().matrix()
        local = rotation.T @ np.asarray(translation, dtype=float)
        center = self.pose.translation() + np.asarray(translation, dtype=float) / 2.0
        return OrientedBox(RigidTransform(self.pose.rotation(), center), self.size + np.abs(local))

    def sweep(self, translation: np.ndarray, step: float = SWEEP_STEP) -> list[OrientedBox]:
        """Boxes covering this one moved along ``translation`` (world): ``swept`` when the
        move is along one of its axes, else pieces at most ``step`` long (a pad tilted 63°
        swept straight up in one box would cover its neighbours' space too)."""
        return self.sweep_array(translation, step).boxes()

    def sweep_array(self, translation: np.ndarray, step: float = SWEEP_STEP) -> BoxArray:
        """``sweep`` as arrays."""
        translation = np.asarray(translation, dtype=float)
        length = float(np.linalg.norm(translation))
        local = np.sort(np.abs(self.pose.rotation().matrix().T @ translation))
        pieces = 1
        if length > 0.0 and local[1] > 1e-9 * length:
            pieces = math.ceil(length / step)
        part = translation / pieces
        first = self.swept(part)  # the others are copies of it, moved along
        centres = first.pose.translation() + np.arange(pieces)[:, None] * part
        return BoxArray.rows(first.pose.rotation().matrix(), centres, first.size)


@dataclass(frozen=True)
class BoxArray:
    """Boxes as arrays (k×3×3 rotations, k×3 centres, k×3 full sizes; world): what
    ``nearest_distance`` reads, without a RigidTransform to make and unpack per box."""

    rotations: np.ndarray
    centres: np.ndarray
    sizes: np.ndarray

    @classmethod
    def of(cls, boxes: Sequence[OrientedBox]) -> BoxArray:
        return cls(
            np.array([box.pose.rotation().matrix() for box in boxes]).reshape(-1, 3, 3),
            np.array([box.pose.translation() for box in boxes]).reshape(-1, 3),
            np.array([box.size for box in boxes], dtype=float).reshape(-1, 3),
        )

    @classmethod
    def rows(cls, rotation: np.ndarray, centres: np.ndarray, size: np.ndarray) -> BoxArray:
        """Boxes of one ``rotation`` and ``size`` at ``centres``."""
        count = len(centres)
        return cls(np.repeat(rotation[None], count, 0), centres, np.repeat(size[None], count, 0))

    @classmethod
    def concatenate(cls, parts: Sequence[BoxArray]) -> BoxArray:
        return cls(
            np.concatenate([part.rotations for part in parts]),
            np.concatenate([part.centres for part in parts]),
            np.concatenate([part.sizes for part in parts]),
        )

    def __len__(self) -> int:
        return len(self.centres)

    def boxes(self) -> list[OrientedBox]:
        return [
            OrientedBox(RigidTransform(RotationMatrix(rotation), centre), size)
            for rotation, centre, size in zip(self.rotations, self.centres, self.sizes, strict=True)
        ]


def nearest_distance(
    boxes: Sequence[OrientedBox] | BoxArray, points: np.ndarray, cap: float = math.inf
) -> float:
    """The smallest signed distance from any of ``points`` (N×3) to any of ``boxes``, or
    ``cap`` when that is smaller (inf: no points or boxes).

    Exact, but measured only where bounds leave it in question: none farther than ``cap``
    from the boxes' common axis-aligned bounds. In the frame of each rotation the boxes are
    axis-aligned; each chain of overlapping boxes in order (a pad's path), then each run of
    NEAREST_GROUP boxes of a chain, is bounded by one box; the point deepest in each bound
    gives an upper bound on the answer, and only the points whose bound is below it are
    measured to the boxes. The nearest are measured again as ``OrientedBox.signed_distance``
    does: the answer is the same to the last bit. (Measured box by box to every scene point,
    perception's grasp scoring took 4-5 s a pile; bounded by spheres around runs, 0.1 s.)"""
    points = np.asarray(points, dtype=float).reshape(-1, 3)
    boxes = boxes if isinstance(boxes, BoxArray) else BoxArray.of(boxes)
    if not len(points) or not len(boxes):
        return cap
    halves = boxes.sizes / 2.0
    if math.isfinite(cap):
        reach = np.einsum("kij,kj->ki", np.abs(boxes.rotations), halves)
        low = (boxes.centres - reach).min(axis=0) - cap
        high = (boxes.centres + reach).max(axis=0) + cap
        inside = (points >= low) & (points <= high)
        points = points[inside[:, 0] & inside[:, 1] & inside[:, 2]]
        if not len(points):
            return cap
    frames, rest, flat = [], np.arange(len(boxes)), boxes.rotations.reshape(-1, 9)
    while len(rest):  # the boxes of each rotation (a grasp's pad paths share one)
        same = np.all(flat[rest] == flat[rest[0]], axis=1)
        frames.append(rest[same])
        rest = rest[~same]
    bound, found = cap, []
    for members in frames:
        bound, values, indices, box = _near_pairs(
            boxes.rotations[members[0]], boxes.centres[members], halves[members], points, bound
        )
        found.append((values, indices, members[box]))
    values, indices, box = (np.concatenate(parts) for parts in zip(*found, strict=True))
    if not len(values):
        return cap
    # each value is within ROUNDING of the exact one: the nearest pair is among these
    chosen = values <= values.min() + 2.0 * ROUNDING
    indices, box = indices[chosen], box[chosen]
    local = (points[indices] - boxes.centres[box])[:, None, :] @ boxes.rotations[box]
    exact = excess_signed_distance(np.abs(local[:, 0, :]) - halves[box])
    return min(cap, float(exact.min()))


def _near_pairs(
    rotation: np.ndarray, centres: np.ndarray, halves: np.ndarray, points: np.ndarray, bound: float
) -> tuple[float, np.ndarray, np.ndarray, np.ndarray]:
    """For boxes of one ``rotation``: a tighter upper ``bound`` on the nearest distance, and
    the (point, box) pairs that may be nearer than it, with their signed distances measured
    in the rotation's frame (within ROUNDING of ``OrientedBox.signed_distance``).

    Two levels of bounds: each chain of overlapping boxes (a pad's path), then each run
    of NEAREST_GROUP boxes of a chain, on the points the first level leaves."""
    local, centres = points @ rotation, centres @ rotation
    low, high = centres - halves, centres + halves
    apart = np.any((low[1:] > high[:-1]) | (high[1:] < low[:-1]), axis=1)
    chains = np.flatnonzero(np.concatenate([[True], apart]))
    lower = _lower_bounds(local, low, high, chains)
    bound = _upper_bound(local, lower, centres, halves, bound)
    near = np.flatnonzero(lower.min(axis=0) < bound)
    local = local[near]
    ends = np.append(chains[1:], len(centres))
    runs = np.concatenate(
        [np.arange(a, b, NEAREST_GROUP) for a, b in zip(chains, ends, strict=True)]
    )
    lower = _lower_bounds(local, low, high, runs)
    bound = _upper_bound(local, lower, centres, halves, bound)
    run, point = np.nonzero(lower < bound)
    # each run's boxes, the last repeated up to NEAREST_GROUP (a repeat changes no minimum)
    run_end = np.append(runs[1:], len(centres))[run]
    box = np.minimum(runs[run, None] + np.arange(NEAREST_GROUP), run_end[:, None] - 1)
    values = excess_signed_distance(np.abs(local[point, None] - centres[box]) - halves[box])
    return bound, values.ravel(), np.repeat(near[point], NEAREST_GROUP), box.ravel()


def _lower_bounds(
    local: np.ndarray, low: np.ndarray, high: np.ndarray, starts: np.ndarray
) -> np.ndarray:
    """groups × points: less than the signed distance of each point to any box (axis-aligned,
    corners ``low``, ``high``) of each group of consecutive boxes from ``starts``: the
    largest excess along one axis over the group's bounds."""
    low, high = np.minimum.reduceat(low, starts), np.maximum.reduceat(high, starts)
    excess = np.abs(local - ((low + high) / 2.0)[:, None]) - ((high - low) / 2.0)[:, None]
    return np.maximum(np.maximum(excess[..., 0], excess[..., 1]), excess[..., 2]) - ROUNDING


def _upper_bound(
    local: np.ndarray, lower: np.ndarray, centres: np.ndarray, halves: np.ndarray, bound: float
) -> float:
    """``bound``, or less: the signed distance of the point deepest in each group's bounds
    to the nearest box (no point: ``bound``)."""
    if not len(local):
        return bound
    deepest = local[lower.argmin(axis=1)]
    nearest = excess_signed_distance(np.abs(deepest[:, None] - centres) - halves).min()
    return min(bound, float(nearest) + ROUNDING)


def excess_signed_distance(excess: np.ndarray) -> np.ndarray:
    """Signed distance to a box (< 0 inside) from each point's excess |local| - half size
    (...×3):
    written per component, as numpy reduces an axis of 3 ten times slower."""
    x, y, z = excess[..., 0], excess[..., 1], excess[..., 2]
    ox, oy, oz = np.maximum(x, 0.0), np.maximum(y, 0.0), np.maximum(z, 0.0)
    outside = np.sqrt(ox * ox + oy * oy + oz * oz)
    return outside + np.minimum(np.maximum(np.maximum(x, y), z), 0.0)


@dataclass(frozen=True)
class GripperGeometry:
    """The gripper's collision boxes and TCP, in the ``wsg_body`` frame (from the URDF)."""

    body_center: np.ndarray
    body_size: np.ndarray
    pad_center: np.ndarray  # left pad centre in its finger frame; the right pad mirrors y
    pad_size: np.ndarray
    tcp_offset: np.ndarray  # wsg_tcp origin in wsg_body
    max_opening: float

    def pad_boxes_in_tcp(self, opening: float) -> list[OrientedBox]:
        """Left and right pad boxes in the TCP frame when the fingers are ``opening`` apart."""
        boxes = []
        for side in (1.0, -1.0):
            center = self.pad_center * np.array([1.0, side, 1.0]) + [0.0, side * opening / 2, 0.0]
            boxes.append(OrientedBox(RigidTransform(center - self.tcp_offset), self.pad_size))
        return boxes

    def body_box_in_tcp(self) -> OrientedBox:
        return OrientedBox(RigidTransform(self.body_center - self.tcp_offset), self.body_size)


def _floats(text: str) -> np.ndarray:
    return np.array([float(value) for value in text.split()])


@cache
def gripper_geometry() -> GripperGeometry:
    """Parse the WSG URDF once: body and left pad collision boxes, TCP joint, finger stroke."""
    root = ET.parse(WSG_URDF).getroot()

    def collision_box(link: str) -> tuple[np.ndarray, np.ndarray]:
        collision = root.find(f"link[@name='{link}']/collision")
        return _floats(collision.find("origin").get("xyz")), _floats(
            collision.find("geometry/box").get("size")
        )

    body_center, body_size = collision_box("wsg_body")
    pad_center, pad_size = collision_box("wsg_left_finger")
    tcp = _floats(root.find("joint[@name='wsg_tcp_joint']/origin").get("xyz"))
    stroke = float(root.find("joint[@name='wsg_left_finger_joint']/limit").get("upper"))
    return GripperGeometry(body_center, body_size, pad_center, pad_size, tcp, 2.0 * stroke)


def canonical_grasp(turn: float = 0.0, shift: float = 0.0) -> RigidTransform:
    """X_DG: the TCP in the domino frame for the canonical tilted grasp.

    ``turn`` [rad] turns it about the closing axis through the TCP, tilting the approach
    that much further from the domino's thickness axis (at place the gripper stands that
    much more upright); ``shift`` [m] moves the TCP along the domino's length towards the
    end the pads hold (at place they ride that much higher)."""
    tilt = GRASP_TILT + turn
    approach = np.array([math.sin(tilt), 0.0, -math.cos(tilt)])
    closing = np.array([0.0, 1.0, 0.0])
    rotation = np.column_stack([np.cross(closing, approach), closing, approach])
    return RigidTransform(RotationMatrix(rotation), TCP_IN_DOMINO - [shift, 0.0, 0.0])


def pregrasp_opening(width: float) -> float:
    """Finger opening while approaching a domino ``width`` wide: PREGRASP_CLEARANCE per side."""
    return width + 2.0 * PREGRASP_CLEARANCE


def release_opening(width: float) -> float:
    """Finger opening that lets go of a domino ``width`` wide: RELEASE_CLEARANCE per side."""
    return width + 2.0 * RELEASE_CLEARANCE


CANONICAL_GRASP = canonical_grasp()  # made once: perception ranks the grasps of every domino


@cache
def _pad_boxes_in_tcp(opening: float) -> tuple[OrientedBox, ...]:
    """``GripperGeometry.pad_boxes_in_tcp``, made once per opening (a few are used)."""
    return tuple(gripper_geometry().pad_boxes_in_tcp(opening))


def top_grasp() -> RigidTransform:
    """X_DG of the regrasp: straight down onto a flat domino, fingers across its width.

    It cannot stand a domino up (the gripper would be horizontal at place); the planner
    uses it only to turn a domino that lies where no tilted grasp reaches (docs/PLANNER.md).
    """
    rotation = np.column_stack([[-1.0, 0.0, 0.0], [0.0, 1.0, 0.0], [0.0, 0.0, -1.0]])
    return RigidTransform(RotationMatrix(rotation), [0.0, 0.0, TOP_GRASP_HEIGHT])


@dataclass(frozen=True)
class Grasp:
    """One way to hold a domino: TCP pose in world and the finger openings it needs."""

    pose: RigidTransform  # X_WG of wsg_tcp
    closed_opening: float  # m, finger opening when closed on the domino (its width)
    pregrasp_opening: float  # m, opening while approaching it

    @property
    def approach(self) -> np.ndarray:
        """Unit approach direction (TCP z) in world."""
        return self.pose.rotation().matrix()[:, 2]

    @property
    def release_opening(self) -> float:
        """Opening that lets go of the domino at place."""
        return release_opening(self.closed_opening)

    def pad_boxes(self, opening: float | None = None) -> list[OrientedBox]:
        """Where the two pads are in world at ``opening`` (default: closed on the domino)."""
        opening = self.closed_opening if opening is None else opening
        return [OrientedBox(self.pose @ box.pose, box.size) for box in _pad_boxes_in_tcp(opening)]

    def pad_paths(
        self, approach_distance: float, retreat: np.ndarray | None = None
    ) -> list[OrientedBox]:
        """The space each pad passes through: open, on the approach line from
        ``approach_distance`` along ``retreat`` (world unit vector from the grasp back to the
        pre-grasp; default up the TCP axis) down to the grasp, and its stroke from the
        pre-grasp opening onto the domino (a domino tucked beside the picked one's long face
        stops the finger there: arc seed 6 missed twice so, the fingers stalled at 31 mm on a
        domino standing on its edge)."""
        return self.pad_path_array(approach_distance, retreat).boxes()

    def pad_path_array(
        self, approach_distance: float, retreat: np.ndarray | None = None
    ) -> BoxArray:
        """``pad_paths`` as arrays (for ``nearest_distance``)."""
        retreat = -self.approach if retreat is None else np.asarray(retreat, dtype=float)
        paths = []
        for open_pad, closed_pad in zip(
            self.pad_boxes(self.pregrasp_opening), self.pad_boxes(), strict=True
        ):
            stroke = open_pad.swept(closed_pad.pose.translation() - open_pad.pose.translation())
            paths += [
                open_pad.sweep_array(retreat * approach_distance),
                BoxArray.rows(
                    stroke.pose.rotation().matrix(), stroke.pose.translation()[None], stroke.size
                ),
            ]
        return BoxArray.concatenate(paths)


def comes_from_above(tcp_pose: RigidTransform) -> bool:
    """False when the approach points up: the gripper would come from under the domino."""
    return bool(tcp_pose.rotation().matrix()[2, 2] < -MIN_DOWNWARD_APPROACH)


def equivalent_grasps(
    domino_pose: RigidTransform,
    size: tuple[float, float, float] = DOMINO_SIZE,
    tcp_in_domino: RigidTransform | None = None,
) -> list[Grasp]:
    """All 8 grasps holding a domino at ``domino_pose`` (S, then F), unranked.

    ``tcp_in_domino``: the grasp X_DG (default: the canonical tilted grasp).
    """
    width = float(size[1])
    tcp_in_domino = CANONICAL_GRASP if tcp_in_domino is None else tcp_in_domino
    return [
        Grasp(
            domino_pose @ RigidTransform(symmetry) @ tcp_in_domino @ swap,
            width,
            pregrasp_opening(width),
        )
        for swap in (RigidTransform(), FINGER_SWAP)
        for symmetry in SYMMETRIES
    ]


def _horizontal_unit(vector: np.ndarray) -> np.ndarray:
    flat = np.array([vector[0], vector[1], 0.0])
    norm = np.linalg.norm(flat)
    return flat / norm if norm > 1e-9 else flat


def _approach(tcp_pose: RigidTransform) -> np.ndarray:
    return tcp_pose.rotation().matrix()[:, 2]


def pick_grasps(
    domino_pose: RigidTransform,
    size: tuple[float, float, float] = DOMINO_SIZE,
    base_xy: tuple[float, float] = (0.0, 0.0),
    tcp_in_domino: RigidTransform | None = None,
) -> list[Grasp]:
    """The grasps of a domino lying at ``domino_pose``, best first.

    Ranking: the most downward approach first (grasps from below come last); among equals
    the gripper leaning so that its approach points away from the arm base (``base_xy``),
    the arm's natural reach; unswapped fingers before swapped ones (stable sort).
    """
    outward = _horizontal_unit(domino_pose.translation() - np.array([*base_xy, 0.0]))

    def score(grasp: Grasp) -> float:
        approach = grasp.approach
        return -approach[2] + 0.3 * float(_horizontal_unit(approach) @ outward)

    grasps = equivalent_grasps(domino_pose, size, tcp_in_domino)
    return sorted(grasps, key=lambda grasp: -round(score(grasp), 9))


def domino_in_tcp(grasp_pose: RigidTransform, domino_pose: RigidTransform) -> RigidTransform:
    """X_GD: where a domino grasped at ``grasp_pose`` sits in the TCP frame while held."""
    return grasp_pose.inverse() @ domino_pose


def place_grasps(
    place_pose: RigidTransform,
    held_in_tcp: RigidTransform,
    free_direction: np.ndarray | None = None,
) -> list[RigidTransform]:
    """TCP poses that put a domino held at ``held_in_tcp`` at ``place_pose``, best first.

    One pose per domino symmetry.

    The most downward approach first (for the canonical grasp and an upright domino: the
    one standing the domino on the end far from the pads); among equals the gripper body
    leaning over ``free_direction`` (default: the domino's +z, where the next domino of a
    run built in order will stand, so no neighbour stands there yet).
    """
    free = place_pose.rotation().matrix()[:, 2] if free_direction is None else free_direction
    free = _horizontal_unit(np.asarray(free, dtype=float))
    poses = [
        place_pose @ RigidTransform(symmetry) @ held_in_tcp.inverse() for symmetry in SYMMETRIES
    ]

    def score(tcp_pose: RigidTransform) -> float:
        approach = _approach(tcp_pose)
        return -approach[2] + 0.3 * float(-_horizontal_unit(approach) @ free)

    return sorted(poses, key=lambda pose: -round(score(pose), 9))


def upright_pose(x: float, y: float, heading: float, base_height: float = 0.0) -> RigidTransform:
    """A domino standing on ``base_height`` (body x up), toppling towards ``heading`` (body z).

    Same convention as dombot_bringup.layouts: x = up, z = run tangent, y = z × x.
    """
    tangent = np.array([math.cos(heading), math.sin(heading), 0.0])
    up = np.array([0.0, 0.0, 1.0])
    rotation = RotationMatrix(np.column_stack([up, np.cross(tangent, up), tangent]))
    return RigidTransform(rotation, [x, y, base_height + DOMINO_SIZE[0] / 2.0])


def flat_pose(x: float, y: float, yaw: float, base_height: float = 0.0) -> RigidTransform:
    """A domino lying on its largest face (body z up) on ``base_height``, turned by ``yaw``."""
    return RigidTransform(
        RotationMatrix.MakeZRotation(yaw), [x, y, base_height + DOMINO_SIZE[2] / 2.0]
    )

"""The grasps a /plan_place request tries, best first: the request's own, the canonical
ones, the steeper and the flatter ones; the lines they lift along, the finger
openings, the pile points the pads keep clear of, and the regrasp's two picks."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import (
    FINGER_SWAP,
    GRASP_TILT,
    OrientedBox,
    canonical_grasp,
    comes_from_above,
    pick_grasps,
    pregrasp_opening,
    release_opening,
    top_grasp,
)
from dombot_planner.motion import UP
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings

OWN_POINTS = 0.003  # m: pile points this close to the picked domino's box are its own


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

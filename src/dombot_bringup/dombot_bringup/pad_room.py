"""Whether the fingers have room to place each domino of a layout beside those built
before it, told before anything moves (no ROS, no IK).

A spiral of 35 mm pitch had three slots of its outer turn refused during the build: every
place pose put the pads into the inner turn's standing dominoes. The test is the
planner's own (``foreseen_refusal.no_place``: the pads at every place pose a hold gives,
closed and letting go, against the standing dominoes), for every grasp it would try on a
flat domino; the planner's other dominoes (pile, the rest of the run) are not asked.
"""

from __future__ import annotations

import numpy as np
from pydrake.math import RigidTransform
from scipy.spatial import cKDTree

from dombot_bringup.layouts import DominoPlacement
from dombot_bringup.task.geometry import placement_pose
from dombot_planner.foreseen_refusal import no_place
from dombot_planner.grasp_candidates import ranked_grasps
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings

NEAR = 0.07  # m between centres: farther apart, the pads placing one cannot reach the other


def crowded_slots(
    placements: list[DominoPlacement], settings: PlannerSettings | None = None
) -> dict[int, list[int]]:
    """Slot index → the slots built before it, not next to it along the run, within NEAR
    of it, when no grasp of a flat domino gives it a place pose whose pads keep clear of
    them all standing: the slot is refused once they stand."""
    settings = PlannerSettings() if settings is None else settings
    targets = [RigidTransform(placement_pose(p)) for p in placements]
    tree = cKDTree(np.array([[p.x, p.y] for p in placements]))
    crowded = {}
    for j, target in enumerate(targets):
        before = sorted(
            i for i in tree.query_ball_point(target.translation()[:2], NEAR) if i < j - 1
        )
        if before and no_room(target, [targets[i] for i in before], settings):
            crowded[j] = before
    return crowded


def no_room(
    place: RigidTransform, standing: list[RigidTransform], settings: PlannerSettings
) -> bool:
    """Whether every grasp of a flat domino has no place pose at ``place`` with the pads
    clear of the dominoes ``standing``."""
    flat = RigidTransform()  # its thickness axis up
    request = PickPlaceRequest(flat, place, np.zeros(7), standing=tuple(standing))
    grasps, (steeper, flatter) = ranked_grasps(request, settings)
    return all(no_place(request, settings, grasp) for grasp in [*grasps, *steeper, *flatter])


def crowded_words(crowded: dict[int, list[int]]) -> list[str]:
    """One line a crowded slot, for the log: the dominoes beside it that take the fingers'
    room (those not its run neighbours, when there are any: a spiral's inner turn)."""
    lines = []
    for j, before in crowded.items():
        named = [i for i in before if j - i > 2] or before
        beside = ("dominoes " if len(named) > 1 else "domino ") + ", ".join(
            str(i + 1) for i in named
        )
        lines.append(
            f"domino {j + 1} has no room for the fingers beside {beside} standing: "
            "expect it refused (space the run wider there)"
        )
    return lines

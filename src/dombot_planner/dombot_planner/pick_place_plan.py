"""The plan of a /plan_place request, the ends it is planned between (``End``) and how
their search went (``EndSearch``)."""

from __future__ import annotations

from collections import Counter
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform

from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.motion import UP, reasons
from dombot_planner.plan_segments import Plan


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


@dataclass
class End:
    """One end of the transfer: IK at the pose and the vertical line above it."""

    tcp_pose: RigidTransform
    line: np.ndarray  # waypoints from the pose (index 0) up to the approach height

    @property
    def above(self) -> np.ndarray:
        return self.line[-1]


@dataclass
class EndSearch:
    """What the search for pick and place ends tried: the error when nothing was found."""

    grasp_candidates: int = 0
    place_candidates: int = 0
    picks_found: int = 0
    turned_picks_found: int = 0  # of picks_found, with steeper or flatter grasps
    unplaced_turned: int = 0  # turned grasps not solved for: their hold has no place pose
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

"""The scenes and IK programs one /plan_place request's planning tiers share."""

from __future__ import annotations

from collections.abc import Callable

from pydrake.math import RigidTransform, RotationMatrix

from dombot_planner.ik import PoseIK
from dombot_planner.motion import ArmPlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.scene import (
    Scene,
)


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

    def __init__(self, planner: ArmPlanner) -> None:
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
                query_distance=self.planner.query_distance,
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

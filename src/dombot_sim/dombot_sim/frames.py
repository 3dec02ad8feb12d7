"""The cell's tf tree from the Drake plant: each link relative to its parent link.

robot_state_publisher's convention: one transform per joint of the kinematic tree,
parent link → child link, named by the models' link names; welded (fixed) joints are
static, the others move with the state. The cameras' optical frames (REP 103 optical:
z forward, x right, y down) come from the scenario and the dominoes' body frames from
the plant, both relative to ``world``. ROS-free: ``sim_node`` converts these to
``tf2_msgs/TFMessage``.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Frame, ModelInstanceIndex
from pydrake.systems.framework import Context

from dombot_description.scenario import CameraSpec

WORLD = "world"


@dataclass(frozen=True)
class FrameTransform:
    """The pose X_PC of frame ``child`` in frame ``parent``."""

    parent: str
    child: str
    X_PC: RigidTransform


def optical_frame(camera: str) -> str:
    return f"{camera}_optical"


class LinkTree:
    """The joints whose child link belongs to ``models``: their parent and child links."""

    def __init__(self, plant: MultibodyPlant, models: Sequence[ModelInstanceIndex]) -> None:
        self._plant = plant
        self._fixed: list[tuple[Frame, Frame]] = []
        self._moving: list[tuple[Frame, Frame]] = []
        for index in plant.GetJointIndices():
            joint = plant.get_joint(index)
            if joint.child_body().model_instance() not in models:
                continue
            pair = (joint.parent_body().body_frame(), joint.child_body().body_frame())
            (self._fixed if joint.num_positions() == 0 else self._moving).append(pair)

    def fixed(self, context: Context) -> list[FrameTransform]:
        """Welds: constant, for /tf_static (the arm base and table in world, flange → gripper)."""
        return self._transforms(self._fixed, context)

    def moving(self, context: Context) -> list[FrameTransform]:
        """Joints with positions: the state's transforms, for /tf."""
        return self._transforms(self._moving, context)

    def _transforms(
        self, pairs: list[tuple[Frame, Frame]], context: Context
    ) -> list[FrameTransform]:
        return [
            FrameTransform(
                _link_name(parent),
                _link_name(child),
                self._plant.CalcRelativeTransform(context, parent, child),
            )
            for parent, child in pairs
        ]


def _link_name(frame: Frame) -> str:
    """The link's name; Drake's world body is ``world`` (REP 105's world frame)."""
    return frame.body().name()


def camera_transforms(cameras: Sequence[CameraSpec]) -> list[FrameTransform]:
    """world → ``camera_N_optical`` for each scenario camera (its pose is the optical frame)."""
    return [
        FrameTransform(WORLD, optical_frame(spec.name), RigidTransform(spec.pose()))
        for spec in cameras
    ]

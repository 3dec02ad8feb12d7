"""RGB-D cameras from the scenario: Drake RgbdSensor systems rendered by VTK (headless).

Each camera renders colour (rgb8), depth aligned to colour (float32 metres) and a label
image; the label image is what perception's training and evaluation use as ground truth.

The cameras look at a ``RenderScene``: a copy of the cell that is never stepped, posed
from the simulated plant's positions only when a frame is rendered. A render engine in
the simulated SceneGraph would be handed every geometry's pose at every physics step
(Drake updates all engines' poses with the proximity engine's), which cost half again as
much as the step of a sleeping pile; the cameras render a few times a simulated second.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (
    ClippingRange,
    ColorRenderCamera,
    DepthRange,
    DepthRenderCamera,
    MakeRenderEngineVtk,
    RenderCameraCore,
    RenderEngineVtkParams,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import Context, DiagramBuilder
from pydrake.systems.sensors import CameraInfo, RgbdSensor

from dombot_description.cell import add_cell, add_dominoes
from dombot_description.scenario import CameraSpec, Scenario

RENDERER = "dombot_vtk"
NEAR_CLIP = 0.01  # m, colour camera


@dataclass(frozen=True)
class CameraFrame:
    """One rendered frame set of one camera (images share the pixel grid)."""

    name: str
    time: float  # simulated seconds
    rgb: np.ndarray  # (H, W, 3) uint8
    depth: np.ndarray  # (H, W) float32 metres; NaN where there is no return
    label: np.ndarray | None  # (H, W) int32: domino index, or -1; None when not rendered
    K: np.ndarray  # 3x3 pinhole intrinsics
    X_WC: np.ndarray  # 4x4 pose of the optical frame (z forward, x right, y down) in world


def cameras_due(
    now: float,
    next_frame: Mapping[str, float],
    audience: Mapping[str, Sequence[int]],
    last_audience: Mapping[str, Sequence[int]],
) -> list[str]:
    """The cameras to render at simulated time ``now``, rendered on demand: those with a
    subscriber on any of their topics (``audience``: subscribers per topic) whose frame is
    due by ``next_frame``, and those one of whose topics gained a subscriber since the
    last tick (``last_audience``). A reader's topics match one at a time: a frame sent
    while only its colour topic had matched never reached its depth reader, which then
    waited a whole camera period for the next."""
    due = []
    for name, counts in audience.items():
        before = last_audience.get(name) or (0,) * len(counts)
        joined = any(count > old for count, old in zip(counts, before, strict=True))
        if any(counts) and (now >= next_frame[name] or joined):
            due.append(name)
    return due


def add_renderer(scene_graph: SceneGraph) -> None:
    if not scene_graph.HasRenderer(RENDERER):
        scene_graph.AddRenderer(RENDERER, MakeRenderEngineVtk(RenderEngineVtkParams()))


def add_camera(builder: DiagramBuilder, scene_graph: SceneGraph, spec: CameraSpec) -> RgbdSensor:
    """An RgbdSensor fixed at the scenario's pose; its body frame is the optical frame."""
    matrix = spec.intrinsics  # rendered with exactly the matrix perception is told about
    intrinsics = CameraInfo(
        spec.width, spec.height, matrix[0, 0], matrix[1, 1], matrix[0, 2], matrix[1, 2]
    )
    near, far = spec.depth_range
    core = RenderCameraCore(
        RENDERER, intrinsics, ClippingRange(NEAR_CLIP, far + 1.0), RigidTransform()
    )
    depth_core = RenderCameraCore(RENDERER, intrinsics, ClippingRange(near, far), RigidTransform())
    sensor = RgbdSensor(
        parent_id=scene_graph.world_frame_id(),
        X_PB=RigidTransform(spec.pose()),
        color_camera=ColorRenderCamera(core, False),
        depth_camera=DepthRenderCamera(depth_core, DepthRange(near, far)),
    )
    sensor.set_name(spec.name)
    builder.AddSystem(sensor)
    builder.Connect(scene_graph.get_query_output_port(), sensor.query_object_input_port())
    return sensor


def label_lookup(label_to_domino: dict[int, int]) -> np.ndarray:
    """Table from Drake render label (0..32767, reserved values included) to domino index or -1."""
    table = np.full(32768, -1, dtype=np.int32)
    for render_label, domino in label_to_domino.items():
        table[render_label] = domino
    return table


def render(
    sensor: RgbdSensor, spec: CameraSpec, context: Context, lookup: np.ndarray, labels: bool
) -> CameraFrame:
    """Evaluate the sensor's image ports at ``context`` (the sensor's own context).

    The label image costs a third render pass; only ground-truth users ask for it.
    """
    rgba = sensor.color_image_output_port().Eval(context).data
    depth = np.array(sensor.depth_image_32F_output_port().Eval(context).data[:, :, 0], copy=True)
    depth[~np.isfinite(depth) | (depth <= 0.0)] = np.nan
    label = None
    if labels:
        raw_label = sensor.label_image_output_port().Eval(context).data[:, :, 0]
        label = lookup[np.clip(raw_label, 0, lookup.size - 1)]
    return CameraFrame(
        name=spec.name,
        time=context.get_time(),
        rgb=np.array(rgba[:, :, :3], copy=True),
        depth=depth.astype(np.float32),
        label=label,
        K=spec.intrinsics,
        X_WC=spec.pose(),
    )


class RenderScene:
    """The scenario's cameras on a posed, never stepped copy of the cell.

    Built like the simulated plant (the same models in the same order), so its positions
    vector is the simulated plant's and a domino's render label is its body index there.
    """

    def __init__(
        self, scenario: Scenario, domino_count: int, domino_size: tuple[float, float, float]
    ) -> None:
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        add_cell(plant, scenario)
        dominoes = add_dominoes(plant, domino_count, domino_size)
        plant.Finalize()
        add_renderer(scene_graph)
        self._sensors = {
            spec.name: (add_camera(builder, scene_graph, spec), spec) for spec in scenario.cameras
        }
        self._diagram = builder.Build()
        self._root = self._diagram.CreateDefaultContext()
        self._plant = plant
        self._plant_context = plant.GetMyMutableContextFromRoot(self._root)
        self._lookup = label_lookup(
            {
                int(plant.GetBodyByName("domino", model).index()): index
                for index, model in enumerate(dominoes)
            }
        )

    @property
    def camera_names(self) -> tuple[str, ...]:
        return tuple(self._sensors)

    def render(
        self, positions: np.ndarray, time: float, names: Sequence[str] | None, labels: bool
    ) -> dict[str, CameraFrame]:
        """The named cameras' frames (all: None) with the cell at ``positions`` (the
        simulated plant's q) at simulated ``time``."""
        self._root.SetTime(time)
        self._plant.SetPositions(self._plant_context, positions)
        frames = {}
        for name in names or self._sensors:
            sensor, spec = self._sensors[name]
            context = sensor.GetMyContextFromRoot(self._root)
            frames[name] = render(sensor, spec, context, self._lookup, labels)
        return frames

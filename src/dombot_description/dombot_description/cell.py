"""Build the DOM-BOT cell into a Drake MultibodyPlant from the scenario.

The simulator and the planner call these same functions, so both see the same
arm, gripper, table and cameras. The planner's shadow plant is the same cell with
the finger joints replaced by welds at the grasp width and the standing dominoes
as anchored boxes; it has no loose dominoes.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import Box, SceneGraph
from pydrake.math import RigidTransform
from pydrake.multibody.parsing import LoadModelDirectives, Parser, ProcessModelDirectives
from pydrake.multibody.plant import CoulombFriction, MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex
from pydrake.systems.framework import DiagramBuilder

from dombot_description import DOMINO_MASS, DOMINO_SIZE, PACKAGE_DIR
from dombot_description.scenario import Scenario

DOMINO_FILE = PACKAGE_DIR / "models" / "domino.sdf"
OBSTACLE_FRICTION = CoulombFriction(0.5, 0.4)


@dataclass(frozen=True)
class CellModels:
    arm: ModelInstanceIndex
    gripper: ModelInstanceIndex
    table: ModelInstanceIndex


def make_parser(plant: MultibodyPlant) -> Parser:
    """A parser that resolves package://dombot_description without ROS."""
    parser = Parser(plant)
    if not parser.package_map().Contains("dombot_description"):
        parser.package_map().Add("dombot_description", str(PACKAGE_DIR))
    return parser


def add_cell(plant: MultibodyPlant, scenario: Scenario) -> CellModels:
    """Arm welded to the world, gripper on its flange, table; from the scenario's directives."""
    parser = make_parser(plant)
    directives = LoadModelDirectives(str(scenario.directives_path))
    ProcessModelDirectives(directives, plant, parser)
    return CellModels(
        arm=plant.GetModelInstanceByName("iiwa"),
        gripper=plant.GetModelInstanceByName("wsg"),
        table=plant.GetModelInstanceByName("table"),
    )


def add_dominoes(
    plant: MultibodyPlant, count: int, size: tuple[float, float, float] = DOMINO_SIZE
) -> list[ModelInstanceIndex]:
    """``count`` free dominoes named domino_0 … (bodies named 'domino'), ``size`` (length,
    width, thickness) at the model's density and contact properties."""
    parser = make_parser(plant)
    parser.SetAutoRenaming(True)
    text = _domino_model(size)
    instances = []
    for index in range(count):
        instance = parser.AddModelsFromString(
            text.replace('name="domino">', f'name="domino_{index}">', 1), "sdf"
        )[0]
        instances.append(instance)
    return instances


def _domino_model(size: tuple[float, float, float]) -> str:
    """domino.sdf, resized: same density, the box's inertia."""
    text = DOMINO_FILE.read_text()
    if tuple(size) == DOMINO_SIZE:
        return text
    mass = DOMINO_MASS * float(np.prod(size) / np.prod(DOMINO_SIZE))
    x, y, z = size
    inertia = mass / 12.0 * np.array([y * y + z * z, x * x + z * z, x * x + y * y])
    box = " ".join(f"{v:g}" for v in size)
    text = text.replace(" ".join(f"{v:g}" for v in DOMINO_SIZE), box)
    text = text.replace(f"<mass>{DOMINO_MASS:g}</mass>", f"<mass>{mass:.6g}</mass>")
    start, end = text.index("<ixx>"), text.index("<ixy>")
    diagonal = "".join(f"<i{a}{a}>{v:.6g}</i{a}{a}>" for a, v in zip("xyz", inertia, strict=True))
    return text[:start] + diagonal + "\n          " + text[end:]


def weld_fingers(plant: MultibodyPlant, scenario: Scenario, opening: float) -> None:
    """Replace the finger joints by welds holding the fingers ``opening`` metres apart."""
    if not 0.0 <= opening <= 0.11:
        raise ValueError(f"finger opening must be within the 0–0.11 m stroke, got {opening}")
    for name in scenario.gripper_joints:
        joint = plant.GetJointByName(name)
        parent, child = joint.frame_on_parent(), joint.frame_on_child()
        offset = opening / 2.0 * np.asarray(joint.translation_axis())
        for actuator_index in plant.GetJointActuatorIndices():
            if plant.get_joint_actuator(actuator_index).joint().index() == joint.index():
                plant.RemoveJointActuator(plant.get_joint_actuator(actuator_index))
        plant.RemoveJoint(joint)
        plant.WeldFrames(parent, child, RigidTransform(offset))


def add_standing_obstacles(plant: MultibodyPlant, poses: Sequence[RigidTransform]) -> None:
    """Dominoes already placed, as anchored collision boxes (domino body frames in world)."""
    for index, pose in enumerate(poses):
        plant.RegisterCollisionGeometry(
            plant.world_body(),
            pose,
            Box(*DOMINO_SIZE),
            f"standing_domino_{index}",
            OBSTACLE_FRICTION,
        )


@dataclass
class ShadowPlant:
    builder_diagram: object
    plant: MultibodyPlant
    scene_graph: SceneGraph
    models: CellModels


def add_plant_and_scene_graph(
    builder: DiagramBuilder, time_step: float
) -> tuple[MultibodyPlant, SceneGraph]:
    """What AddMultibodyPlantSceneGraph does (names included), wired here: pydrake's
    binding of it leaks native memory with every diagram built and dropped, ~0.3 MB per
    shadow plant (likely Drake issue 24529, fixed after 1.52.1), and the planner builds
    three for every request with a grasp width it has not kept (docs/RELIABILITY.md,
    "Memory")."""
    plant = builder.AddSystem(MultibodyPlant(time_step))
    plant.set_name("plant")
    scene_graph = builder.AddSystem(SceneGraph())
    scene_graph.set_name("scene_graph")
    plant.RegisterAsSourceForSceneGraph(scene_graph)
    builder.Connect(
        plant.get_geometry_pose_output_port(),
        scene_graph.get_source_pose_port(plant.get_source_id()),
    )
    builder.Connect(scene_graph.get_query_output_port(), plant.get_geometry_query_input_port())
    return plant, scene_graph


def build_shadow_plant(
    scenario: Scenario, grasp_opening: float, obstacle_poses: Sequence[RigidTransform] = ()
) -> ShadowPlant:
    """The planner's plant: the arm's 7 joints only, fingers welded, obstacles anchored."""
    builder = DiagramBuilder()
    plant, scene_graph = add_plant_and_scene_graph(builder, time_step=0.0)
    models = add_cell(plant, scenario)
    weld_fingers(plant, scenario, grasp_opening)
    add_standing_obstacles(plant, obstacle_poses)
    plant.Finalize()
    return ShadowPlant(builder.Build(), plant, scene_graph, models)

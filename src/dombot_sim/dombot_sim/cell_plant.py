"""The cell's MultibodyPlant in a diagram: its contact model, the cell and the dominoes
(``dombot_description.cell``), the arm's PD gains and the self-collisions nobody needs to
look for, and which model instance owns each entry of its state."""

from __future__ import annotations

from collections.abc import Sequence

import numpy as np
from pydrake.geometry import CollisionFilterDeclaration, SceneGraph
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, MultibodyPlant
from pydrake.multibody.tree import ModelInstanceIndex, PdControllerGains
from pydrake.systems.framework import DiagramBuilder

from dombot_description.cell import CellModels, add_cell, add_dominoes
from dombot_description.scenario import Scenario
from dombot_sim.world_config import CONTACT_APPROXIMATIONS, CONTACT_MODELS, WorldConfig


def add_cell_plant(
    builder: DiagramBuilder, config: WorldConfig, scenario: Scenario, capacity: int
) -> tuple[MultibodyPlant, SceneGraph, CellModels, list[ModelInstanceIndex]]:
    """The finalized plant of the cell with ``capacity`` dominoes, its scene graph, the
    cell's model instances and the dominoes'."""
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=config.time_step)
    plant.set_discrete_contact_approximation(CONTACT_APPROXIMATIONS[config.contact_approximation])
    plant.set_contact_model(CONTACT_MODELS[config.contact_model])
    # live output ports: a sampled plant also computes and stores every step's contact
    # results, reaction forces and accelerations, which nothing here reads; ~15 % of a
    # step with a domino in the pads, the states bit-identical (docs/SIM.md, *Stepping*).
    # ``WorldRobot.joint_state`` then computes the efforts itself (``_efforts``)
    plant.SetUseSampledOutputPorts(False)
    models = add_cell(plant, scenario)
    domino_models = add_dominoes(plant, capacity, config.domino_size)
    # GetJointActuatorIndices(model_instance) is empty before Finalize: filter all of them.
    for actuator_index in plant.GetJointActuatorIndices():
        actuator = plant.get_mutable_joint_actuator(actuator_index)
        if actuator.model_instance() != models.arm:
            continue
        joint = scenario.arm_joints.index(actuator.joint().name())
        actuator.set_controller_gains(
            PdControllerGains(
                p=config.arm_gains.stiffness[joint], d=config.arm_gains.damping[joint]
            )
        )
    plant.Finalize()
    _filter_arm_self_collisions(plant, scene_graph, models, scenario.gripper_joints)
    return plant, scene_graph, models, domino_models


def _filter_arm_self_collisions(
    plant: MultibodyPlant, scene_graph: SceneGraph, models: CellModels, fingers: Sequence[str]
) -> None:
    """No contact between the arm's links and the gripper body: the planner keeps the arm
    clear of itself (its shadow plant checks these pairs), so the simulator need not look
    for them at every step. The fingers still meet the arm, and everything meets the
    table and the dominoes."""
    finger_bodies = {plant.GetJointByName(name).child_body().index() for name in fingers}
    chain = [
        plant.get_body(b)
        for model in (models.arm, models.gripper)
        for b in plant.GetBodyIndices(model)
        if b not in finger_bodies
    ]
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeWithin(plant.CollectRegisteredGeometries(chain))
    )


def state_owners(plant: MultibodyPlant) -> np.ndarray:
    """Per entry of the plant's state [q; v]: the model instance it belongs to."""
    names = plant.GetStateNames(add_model_instance_prefix=True)
    instances = sorted(
        (
            plant.GetModelInstanceName(ModelInstanceIndex(i))
            for i in range(plant.num_model_instances())
        ),
        key=len,
        reverse=True,
    )
    return np.array([next(m for m in instances if name.startswith(m + "_")) for name in names])

"""Sleeping must survive FCL's signed-distance failures on nearly touching boxes."""

from __future__ import annotations

import numpy as np
from pydrake.geometry import Box, ProximityProperties
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.multibody.tree import SpatialInertia
from pydrake.systems.framework import DiagramBuilder

from dombot_description import DOMINO_SIZE
from dombot_sim.sleeping import SleepManager, SleepSettings

# Two flat dominoes side by side on the table, logged when FCL threw
# "validateNearestFeatureOfPolytopeBeingEdge(): The origin is outside of the polytope"
# and ended a benchmark run (S-curve, seed 5).
FCL_FAILURE_POSES = (
    np.array(
        [
            [-0.96664204015952770455, -0.25613115038242878496, 7.4641065523101003927e-13],
            [0.25613115038242878496, -0.96664204015952770455, 3.0042679801831457508e-12],
            [-4.7974695252091511664e-14, 3.0952307493321998432e-12, 1.0],
        ]
    ),
    np.array(
        [
            [0.96434947575008944654, 0.26463198714540869805, -1.3633467847067572873e-12],
            [-0.26463198714540869805, 0.96434947575008944654, -3.2751566557304633664e-12],
            [4.480315430790679112e-13, 3.5191807727583409423e-12, 1.0],
        ]
    ),
)
FCL_FAILURE_POSITIONS = (
    (0.51812047436157271374, -0.22229977390390565084, 0.0037499848315237917055),
    (0.50597804548483260589, -0.24407357607333327043, 0.0037499848315166164556),
)


def test_a_pair_fcl_cannot_measure_counts_as_touching_and_wakes_the_sleeper() -> None:
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.001)
    size = tuple(float(x) for x in DOMINO_SIZE)
    bodies = []
    for name in ("sleeper", "mover"):
        instance = plant.AddModelInstance(name)  # one floating joint each, as in the cell
        body = plant.AddRigidBody(name, instance, SpatialInertia.SolidBoxWithMass(0.01, *size))
        plant.RegisterCollisionGeometry(
            body, RigidTransform(), Box(*size), name, ProximityProperties()
        )
        bodies.append(body)
    plant.Finalize()
    root = builder.Build().CreateDefaultContext()
    plant_context = plant.GetMyMutableContextFromRoot(root)
    for body, rotation, position in zip(
        bodies, FCL_FAILURE_POSES, FCL_FAILURE_POSITIONS, strict=True
    ):
        plant.SetFreeBodyPose(
            plant_context, body, RigidTransform(RotationMatrix(rotation), position)
        )
    manager = SleepManager(plant, scene_graph, bodies, [], [], SleepSettings())
    manager.sleep(root, [0])
    plant.SetFreeBodySpatialVelocity(
        plant_context, bodies[1], SpatialVelocity(np.zeros(3), [0.05, 0.0, 0.0])
    )

    manager.update(root)

    assert manager.distance_fallbacks == 1  # the bulk query threw, as logged
    assert not manager.asleep[0]  # the moving neighbour was found pair by pair

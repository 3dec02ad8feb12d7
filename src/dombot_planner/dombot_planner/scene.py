"""Shadow plants and per-request scenes.

A shadow plant (dombot_description.cell.build_shadow_plant: the arm's 7 joints, fingers
welded) is built once per finger opening and kept. Each request gets scenes: fresh
contexts of those plants into which this request's standing dominoes, the target domino
and the held domino are registered as geometry (SceneGraph's context-modifying
RegisterGeometry), so nothing is rebuilt per request. Every collision geometry belongs to
a class, so clearances are judged per pair of classes: the arm, the pads and the held
domino move; the table, standing dominoes, the target domino and the pile dominoes
around it stay.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.geometry import (
    Box,
    CollisionFilterDeclaration,
    GeometryId,
    GeometryInstance,
    GeometrySet,
    ProximityProperties,
)
from pydrake.math import RigidTransform
from pydrake.multibody.tree import BodyIndex
from pydrake.systems.framework import Context

from dombot_description import DOMINO_SIZE
from dombot_description.cell import ShadowPlant, build_shadow_plant
from dombot_description.scenario import Scenario
from dombot_planner.request import TableTop

ARM, PADS, HELD = "arm", "pads", "held"  # moving classes (ARM includes the gripper body)
TABLE, STANDING, TARGET, PILE, SELF = "table", "standing", "target", "pile", "self"
MOVING = (ARM, PADS, HELD)
OBSTACLES = (TABLE, STANDING, TARGET, PILE)
FINGER_BODIES = ("wsg_left_finger", "wsg_right_finger")
QUERY_DISTANCE = 0.05  # m: pairs farther apart than this are reported as this far (default)


class ShadowPlants:
    """build_shadow_plant results kept per finger opening (0.1 mm resolution), the
    KEPT_PLANTS used last: requests with many different grasp widths must not make the
    node keep a plant for each."""

    KEPT_PLANTS = 8  # a domino width needs 3 (pre-grasp, closed, release), a strike 1

    def __init__(self, scenario: Scenario) -> None:
        self.scenario = scenario
        self._plants: dict[int, ShadowPlant] = {}

    def get(self, opening: float) -> ShadowPlant:
        key = round(opening * 1e4)
        plant = self._plants.pop(key, None) or build_shadow_plant(self.scenario, key / 1e4)
        self._plants[key] = plant  # the newest last
        while len(self._plants) > self.KEPT_PLANTS:
            del self._plants[next(iter(self._plants))]
        return plant


def table_top(shadow: ShadowPlant) -> TableTop:
    """The x-y extent of the table model's collision boxes in world (the workspace check)."""
    plant, inspector = shadow.plant, shadow.scene_graph.model_inspector()
    context = plant.CreateDefaultContext()
    corners = []
    for index in plant.GetBodyIndices(plant.GetModelInstanceByName("table")):
        body = plant.get_body(index)
        body_pose = plant.EvalBodyPoseInWorld(context, body)
        for geometry in plant.GetCollisionGeometriesForBody(body):
            shape = inspector.GetShape(geometry)
            if isinstance(shape, Box):
                half = np.array([shape.width(), shape.depth(), shape.height()]) / 2
                signs = np.array(np.meshgrid(*[[-1, 1]] * 3)).reshape(3, -1)
                local = (signs * half[:, None]).T
                corners.append((body_pose @ inspector.GetPoseInFrame(geometry)).multiply(local.T).T)
    points = np.vstack(corners)
    low, high = points.min(axis=0), points.max(axis=0)
    return TableTop(x=(float(low[0]), float(high[0])), y=(float(low[1]), float(high[1])))


@dataclass(frozen=True)
class ClearanceRules:
    """Minimum signed distance [m] per (moving class, obstacle class or SELF)."""

    minimum: dict[tuple[str, str], float]

    def violations(self, clearance: dict[tuple[str, str], float]) -> list[str]:
        return [
            f"{moving}–{other} {distance * 1000:.1f} mm < {self.minimum[moving, other] * 1000:.1f}"
            for (moving, other), distance in clearance.items()
            if distance < self.minimum.get((moving, other), -math.inf)
        ]


class Scene:
    """One context of a shadow plant holding this request's dominoes.

    ``standing``: dominoes already placed; ``target``: the domino being picked (approach)
    or just placed (retreat); ``held_in_tcp``: the held domino's pose in the TCP frame;
    ``pile``: the other dominoes perceived around the one being picked;
    ``query_distance``: pairs farther apart are reported this far (``ArmPlanner.query_distance``:
    the geometry engine's cost grows with the pairs it must measure).
    """

    def __init__(
        self,
        shadow: ShadowPlant,
        tcp_frame: str,
        standing: Sequence[RigidTransform] = (),
        target: RigidTransform | None = None,
        held_in_tcp: RigidTransform | None = None,
        pile: Sequence[RigidTransform] = (),
        query_distance: float = QUERY_DISTANCE,
    ) -> None:
        self.shadow = shadow
        self.query_distance = query_distance
        self.plant = shadow.plant
        self.scene_graph = shadow.scene_graph
        self.tcp = self.plant.GetFrameByName(tcp_frame)
        self._dominoes = (tuple(standing), target, held_in_tcp, tuple(pile))
        self._contexts: tuple[Context, Context, Context] | None = None
        self._clearances: dict[bytes, dict[tuple[str, str], float]] = {}
        self._pair_keys: dict[tuple[GeometryId, GeometryId], tuple[str, str]] = {}

    @property
    def root_context(self) -> Context:
        return self._built()[0]

    @property
    def plant_context(self) -> Context:
        return self._built()[1]

    @property
    def graph_context(self) -> Context:
        return self._built()[2]

    def _built(self) -> tuple[Context, Context, Context]:
        """The contexts (root, plant, scene graph), the dominoes registered on first use: a
        grasp's scene holding the domino is needed only once a configuration clears the
        approach scene, which most grasps of a refused request never do."""
        if self._contexts is not None:
            return self._contexts
        root = self.shadow.builder_diagram.CreateDefaultContext()
        self._contexts = (
            root,
            self.plant.GetMyMutableContextFromRoot(root),
            self.scene_graph.GetMyMutableContextFromRoot(root),
        )
        standing, target, held_in_tcp, pile = self._dominoes
        self.classes = self._robot_and_table_classes()
        world = self.scene_graph.world_frame_id()
        added = [self._register(pose, world, STANDING) for pose in standing]
        added += [self._register(pose, world, PILE) for pose in pile]
        if target is not None:
            added.append(self._register(target, world, TARGET))
        self._filter_against_welded(added, self.plant.world_body())
        if held_in_tcp is not None:
            gripper = self.plant.GetBodyByName("wsg_body")
            body_in_tcp = self.plant.CalcRelativeTransform(
                self.plant_context, self.tcp, gripper.body_frame()
            )
            frame = self.plant.GetBodyFrameIdOrThrow(gripper.index())
            held = self._register(body_in_tcp.inverse() @ held_in_tcp, frame, HELD)
            self._filter_against_welded([held], gripper)
        return self._contexts

    def _robot_and_table_classes(self) -> dict[GeometryId, str]:
        classes = {}
        for body_index in range(self.plant.num_bodies()):
            body = self.plant.get_body(BodyIndex(body_index))
            instance = self.plant.GetModelInstanceName(body.model_instance())
            if instance == "table":
                name = TABLE
            elif body.name() in FINGER_BODIES:
                name = PADS
            else:
                name = ARM
            for geometry in self.plant.GetCollisionGeometriesForBody(body):
                classes[geometry] = name
        return classes

    def _register(self, pose: RigidTransform, frame, kind: str) -> GeometryId:
        instance = GeometryInstance(pose, Box(*DOMINO_SIZE), f"{kind}_{len(self.classes)}")
        instance.set_proximity_properties(ProximityProperties())
        geometry = self.scene_graph.RegisterGeometry(
            self.graph_context, self.plant.get_source_id(), frame, instance
        )
        self.classes[geometry] = kind
        return geometry

    def _filter_against_welded(self, geometries: list[GeometryId], body) -> None:
        """Never test new geometry against bodies welded to ``body`` (table; gripper, pads)."""
        if not geometries:
            return
        welded = [
            geometry
            for other in self.plant.GetBodiesWeldedTo(body)
            for geometry in self.plant.GetCollisionGeometriesForBody(other)
        ]
        self.scene_graph.collision_filter_manager(self.graph_context).Apply(
            CollisionFilterDeclaration().ExcludeWithin(GeometrySet(geometries + welded))
        )

    def set_positions(self, q: np.ndarray) -> None:
        self.plant.SetPositions(self.plant_context, q)

    def tcp_pose(self, q: np.ndarray) -> RigidTransform:
        self.set_positions(q)
        return self.tcp.CalcPoseInWorld(self.plant_context)

    def clearance(self, q: np.ndarray) -> dict[tuple[str, str], float]:
        """Smallest signed distance per (moving class, obstacle class or SELF) at ``q``.

        Pairs farther apart than ``query_distance`` are reported as that far. Kept per
        ``q``: the planning tiers of a request share their scenes (shared_work.SharedWork) and
        ask again for the configurations the tier before them checked.
        """
        key = np.asarray(q, dtype=float).tobytes()
        if key not in self._clearances:
            self._clearances[key] = self._clearance(q)
        return dict(self._clearances[key])

    def _clearance(self, q: np.ndarray) -> dict[tuple[str, str], float]:
        self.set_positions(q)
        query = self.scene_graph.get_query_output_port().Eval(self.graph_context)
        result = {}
        keys = self._pair_keys
        for pair in query.ComputeSignedDistancePairwiseClosestPoints(self.query_distance):
            ids = (pair.id_A, pair.id_B)
            key = keys.get(ids)
            if key is None:
                key = keys[ids] = self._pair_key(self.classes[ids[0]], self.classes[ids[1]])
            result[key] = min(result.get(key, self.query_distance), pair.distance)
        return result

    @staticmethod
    def _pair_key(a: str, b: str) -> tuple[str, str]:
        if a in MOVING and b in MOVING:
            return (min(a, b, key=MOVING.index), SELF)
        return (a, b) if a in MOVING else (b, a)

    def minimum_distance(self, q: np.ndarray) -> float:
        """The smallest distance over all pairs (what a MinimumDistance constraint sees)."""
        return min(self.clearance(q).values(), default=self.query_distance)

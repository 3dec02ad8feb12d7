"""Put dominoes at rest to sleep, and wake them when something moves near them.

A settled pile of compliant (hydroelastic) dominoes costs as much to simulate as a
falling one: every contact patch is recomputed each step although nothing moves.
Physics engines for games and robotics solve this with *sleeping*; Drake has none, so
this module adds it with two Drake mechanisms:

* a sleeping domino's floating joint is **locked** (its velocity is zero and it leaves
  the dynamics), and
* collisions among sleeping dominoes and the table are **filtered** (a transient
  collision-filter declaration on the SceneGraph context), so their contact patches are
  not computed at all.

A domino falls asleep once it has stayed within ``rest_motion`` metres (any point of it)
of where it was for ``rest_time`` seconds while no moving body would wake it (below) and
no robot part touches it (within ``wake_margin``). A displacement window, not an
instantaneous speed, decides: a slowly tipping domino keeps moving away from its anchor
and stays awake, while sub-millimetre contact jitter does not keep a whole pile awake.

A body *moves* when some point of it is faster than ``moving_speed``. A sleeper wakes when
a moving body (an awake domino, the arm or the gripper) could reach it by the next check:
when it is within ``wake_margin`` plus ``wake_lead`` times the speed of the body's point
nearest to it (at most ``wake_distance``; for a domino the bound of ``point_speed``). The
check runs every ``check_period`` of simulated time (the distance query is the expensive
part); the lead is three periods, so a body closing in at up to three times its speed at
this check still finds the sleeper awake at the next, and the margin covers a body
starting from rest. A finger creeping past the pile at 0.1 m/s wakes only
what it comes within 3.2 mm of, a domino sliding at 2 cm/s what it comes within 2.2 mm
of: each awake pile domino costs contact patches with its neighbours at every step, and
with a fixed 10 mm one slow domino kept re-waking every neighbour 10 mm around it
(``waking_by_distance`` keeps that rule for pours, so a seed's pile stays the same).
Contacts between an awake body and a sleeping one are always computed, so a sleeper is a
solid support until it wakes.
"""

from __future__ import annotations

import itertools
from collections.abc import Iterator, Sequence
from contextlib import contextmanager
from dataclasses import dataclass
from typing import NamedTuple

import numpy as np
from pydrake.geometry import (
    CollisionFilterDeclaration,
    GeometryId,
    GeometrySet,
    QueryObject,
    SceneGraph,
)
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import Body
from pydrake.systems.framework import Context

from dombot_description import DOMINO_SIZE
from dombot_sim.pile import BOUNDING_RADIUS

CORNERS = 0.5 * np.array(list(itertools.product((-1.0, 1.0), repeat=3))) * DOMINO_SIZE  # body


class ClosePair(NamedTuple):
    """Two geometries within the wake distance: their signed distance and closest points,
    each in its own geometry's frame."""

    id_a: GeometryId
    id_b: GeometryId
    distance: float
    point_a: np.ndarray
    point_b: np.ndarray


@dataclass(frozen=True)
class SleepSettings:
    enabled: bool = True
    rest_motion: float = 5e-4  # m any point may move during the rest window
    rest_time: float = 0.25  # s
    moving_speed: float = 0.005  # m/s of a body's fastest point (bounding radius)
    wake_distance: float = 0.010  # m: the farthest a moving body wakes a sleeper
    wake_margin: float = 0.002  # m: a moving body this close wakes it whatever its speed
    wake_lead: float = 0.012  # s of the nearest point's travel added to the margin
    check_period: float = 0.004  # s simulated between neighbourhood checks

    def wake_reach(self, speed: float) -> float:
        """How near a body whose nearest point moves at ``speed`` [m/s] wakes a sleeper
        (-inf: it does not move)."""
        if speed <= self.moving_speed:
            return -np.inf
        return min(self.wake_margin + speed * self.wake_lead, self.wake_distance)


class SleepManager:
    """Tracks which dominoes sleep; call ``update`` between simulator steps."""

    def __init__(
        self,
        plant: MultibodyPlant,
        scene_graph: SceneGraph,
        dominoes: Sequence[Body],
        robot_bodies: Sequence[Body],
        static_bodies: Sequence[Body],
        settings: SleepSettings,
    ) -> None:
        self._plant = plant
        self._scene_graph = scene_graph
        self._dominoes = list(dominoes)
        self._joints = [_floating_joint(plant, body) for body in self._dominoes]
        self._settings = settings
        self.enabled = settings.enabled
        self._static_ids = [
            g for b in static_bodies for g in plant.GetCollisionGeometriesForBody(b)
        ]
        self._owner: dict[object, tuple[str, int]] = {}
        for index, body in enumerate(self._dominoes):
            for geometry in plant.GetCollisionGeometriesForBody(body):
                self._owner[geometry] = ("domino", index)
        self._robot = list(robot_bodies)
        for index, body in enumerate(self._robot):
            for geometry in plant.GetCollisionGeometriesForBody(body):
                self._owner[geometry] = ("robot", index)
        self._asleep = np.zeros(len(self._dominoes), dtype=bool)
        # awake ones that rested at the last check with nothing moving near: held in the
        # fingers of a still hand (no robot part may touch a sleeper: ``wake_margin``)
        self._resting_awake = np.zeros(len(self._dominoes), dtype=bool)
        self._anchor: list[RigidTransform | None] = [None] * len(self._dominoes)
        self._anchor_time = np.zeros(len(self._dominoes))
        self._filter_id = None
        self._next_check = -np.inf
        self.distance_fallbacks = 0  # checks answered pair by pair after an FCL error
        self._by_distance = False  # ``waking_by_distance``

    @property
    def settings(self) -> SleepSettings:
        return self._settings

    @property
    def asleep(self) -> np.ndarray:
        """Boolean per domino (a copy)."""
        return self._asleep.copy()

    def sleep(self, root: Context, indices: Sequence[int]) -> None:
        """Put these dominoes to sleep now (e.g. parked ones), whatever their motion."""
        plant_context = self._plant.GetMyMutableContextFromRoot(root)
        for index in indices:
            self._set_asleep(plant_context, index, True)
        self._refresh_filter(root)

    def wake(self, root: Context, indices: Sequence[int]) -> None:
        """Wake these dominoes now (e.g. before moving them by hand)."""
        plant_context = self._plant.GetMyMutableContextFromRoot(root)
        for index in indices:
            if self._asleep[index]:
                self._set_asleep(plant_context, index, False)
        self._refresh_filter(root)

    def wake_all(self, root: Context) -> None:
        """Wake every sleeper and restart the check schedule: a new scene is then judged at
        the same steps whenever it starts, so a seeded pour settles the same way."""
        self.wake(root, [int(i) for i in np.flatnonzero(self._asleep)])
        self._next_check = -np.inf

    @property
    def next_check(self) -> float:
        """Simulated time of the next neighbourhood check (inf: sleeping is off)."""
        return self._next_check if self.enabled else np.inf

    def update(self, root: Context) -> None:
        """After a simulator step: wake sleepers near moving bodies, put resting ones to sleep."""
        now = root.get_time()
        if not self.enabled or now < self._next_check:
            return
        self._next_check = now + self._settings.check_period - 1e-9
        plant_context = self._plant.GetMyMutableContextFromRoot(root)
        speeds = self._domino_speeds(plant_context)
        near_moving, near_robot = self._neighbourhood(root, plant_context, speeds)
        changed = False
        for index in np.flatnonzero(self._asleep & near_moving):
            self._set_asleep(plant_context, int(index), False)
            changed = True
        resting = self._resting(plant_context, now) & ~self._asleep & ~near_moving
        for index in np.flatnonzero(resting & ~near_robot):
            self._set_asleep(plant_context, int(index), True)
            changed = True
        self._resting_awake = resting & near_robot
        if changed:
            self._refresh_filter(root)

    def all_asleep(self, indices: Sequence[int]) -> bool:
        return bool(np.all(self._asleep[list(indices)]))

    def all_at_rest(self, indices: Sequence[int]) -> bool:
        """Is each of these asleep, or awake only for a robot part touching it and rested
        (``rest_motion`` over ``rest_time``) at the last check with nothing moving near?"""
        chosen = list(indices)
        return bool(np.all(self._asleep[chosen] | self._resting_awake[chosen]))

    def resting_awake(self) -> list[int]:
        """The awake dominoes at rest at the last check (``all_at_rest``)."""
        return [int(i) for i in np.flatnonzero(self._resting_awake & ~self._asleep)]

    def moving(self, root: Context, indices: Sequence[int]) -> bool:
        """Is any of these dominoes moving (see ``moving_speed``)?"""
        plant_context = self._plant.GetMyContextFromRoot(root)
        return any(
            self.point_speed(plant_context, self._dominoes[i]) > self._settings.moving_speed
            for i in indices
        )

    def point_speed(self, plant_context: Context, body: Body) -> float:
        """Upper bound of the speed of any point of a domino-sized body [m/s]."""
        velocity = body.EvalSpatialVelocityInWorld(plant_context)
        return float(
            np.linalg.norm(velocity.translational())
            + np.linalg.norm(velocity.rotational()) * BOUNDING_RADIUS
        )

    def _domino_speeds(self, plant_context: Context) -> np.ndarray:
        """Per domino: the speed bound of ``point_speed`` (zero asleep)."""
        speeds = np.zeros(len(self._dominoes))
        for index in np.flatnonzero(~self._asleep):
            speeds[index] = self.point_speed(plant_context, self._dominoes[index])
        return speeds

    def _robot_point_speed(self, plant_context: Context, index: int, point: np.ndarray) -> float:
        """Speed [m/s] of the robot body's point at ``point`` (world)."""
        body = self._robot[index]
        velocity = body.EvalSpatialVelocityInWorld(plant_context)
        lever = point - body.EvalPoseInWorld(plant_context).translation()
        moved = velocity.translational() + np.cross(velocity.rotational(), lever)
        return float(np.linalg.norm(moved))

    def _resting(self, plant_context: Context, now: float) -> np.ndarray:
        """Per awake domino: has it stayed near its anchor pose for the rest time?

        The anchor moves to the current pose whenever the domino leaves its neighbourhood.
        """
        resting = np.zeros(len(self._dominoes), dtype=bool)
        for index in np.flatnonzero(~self._asleep):
            pose = self._dominoes[index].EvalPoseInWorld(plant_context)
            anchor = self._anchor[index]
            if anchor is None or displacement(anchor, pose) > self._settings.rest_motion:
                self._anchor[index] = pose
                self._anchor_time[index] = now
            resting[index] = now - self._anchor_time[index] >= self._settings.rest_time
        return resting

    def _neighbourhood(
        self, root: Context, plant_context: Context, domino_speeds: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray]:
        """Per domino: could a moving body reach it by the next check
        (``SleepSettings.wake_reach``)? does a robot body touch it (within the margin)?

        A robot body's speed is that of its point nearest to the domino, evaluated only
        for robot bodies within the wake distance of a domino.
        """
        settings = self._settings
        near_moving = np.zeros(len(self._dominoes), dtype=bool)
        near_robot = np.zeros(len(self._dominoes), dtype=bool)
        query = self._scene_graph.get_query_output_port().Eval(
            self._scene_graph.GetMyContextFromRoot(root)
        )
        for pair in self._close_pairs(query):
            for this_id, other_id, point in (
                (pair.id_a, pair.id_b, pair.point_b),
                (pair.id_b, pair.id_a, pair.point_a),
            ):
                this, other = self._owner.get(this_id), self._owner.get(other_id)
                if this is None or this[0] != "domino" or other is None:
                    continue
                kind, index = other
                if kind == "robot":
                    near_robot[this[1]] |= pair.distance <= settings.wake_margin
                    at = query.GetPoseInWorld(other_id) @ point
                    speed = self._robot_point_speed(plant_context, index, at)
                else:
                    speed = domino_speeds[index]
                near_moving[this[1]] |= pair.distance <= self._wake_reach(speed)
        return near_moving, near_robot

    def _wake_reach(self, speed: float) -> float:
        if self._by_distance:
            moving = speed > self._settings.moving_speed
            return self._settings.wake_distance if moving else -np.inf
        return self._settings.wake_reach(speed)

    @contextmanager
    def waking_by_distance(self) -> Iterator[None]:
        """Inside this block a moving body wakes every sleeper within ``wake_distance``,
        whatever its speed: pours settle into the piles seeded before the speed rule
        (which the perception and bring-up benchmarks know)."""
        self._by_distance = True
        try:
            yield
        finally:
            self._by_distance = False

    def _close_pairs(self, query: QueryObject) -> list[ClosePair]:
        """Unfiltered geometry pairs within the wake distance.

        FCL's box-box signed distance throws for some nearly touching boxes
        (fcl#390, drake#18704: "origin is outside of the polytope"); one such pair must
        not end the simulation, so then every pair is asked on its own and one that
        throws counts as touching at the geometries' origins (it only happens within
        ~1e-14 m of contact).
        """
        limit = self._settings.wake_distance
        try:
            return [
                ClosePair(p.id_A, p.id_B, p.distance, p.p_ACa, p.p_BCb)
                for p in query.ComputeSignedDistancePairwiseClosestPoints(limit)
            ]
        except RuntimeError:
            self.distance_fallbacks += 1
        inspector = query.inspector()
        ids = list(self._owner)
        close = []
        for i, id_a in enumerate(ids):
            for id_b in ids[i + 1 :]:
                kinds = {self._owner[id_a][0], self._owner[id_b][0]}
                if "domino" not in kinds or inspector.CollisionFiltered(id_a, id_b):
                    continue
                try:
                    p = query.ComputeSignedDistancePairClosestPoints(id_a, id_b)
                    pair = ClosePair(id_a, id_b, p.distance, p.p_ACa, p.p_BCb)
                except RuntimeError:
                    pair = ClosePair(id_a, id_b, 0.0, np.zeros(3), np.zeros(3))
                if pair.distance <= limit:
                    close.append(pair)
        return close

    def _set_asleep(self, plant_context: Context, index: int, asleep: bool) -> None:
        joint = self._joints[index]
        if asleep:
            joint.Lock(plant_context)
            joint.set_angular_velocity(plant_context, np.zeros(3))
            joint.set_translational_velocity(plant_context, np.zeros(3))
        else:
            joint.Unlock(plant_context)
        self._asleep[index] = asleep
        self._resting_awake[index] = False
        self._anchor[index] = None

    @contextmanager
    def filters_lifted(self, root: Context) -> Iterator[None]:
        """Inside this block geometry queries see every pair, sleeping ones included."""
        self._remove_filter(root)
        try:
            yield
        finally:
            self._refresh_filter(root)

    def _remove_filter(self, root: Context) -> None:
        if self._filter_id is not None:
            manager = self._scene_graph.collision_filter_manager(
                self._scene_graph.GetMyMutableContextFromRoot(root)
            )
            manager.RemoveDeclaration(self._filter_id)
            self._filter_id = None

    def _refresh_filter(self, root: Context) -> None:
        self._remove_filter(root)
        manager = self._scene_graph.collision_filter_manager(
            self._scene_graph.GetMyMutableContextFromRoot(root)
        )
        sleeping = [
            geometry
            for index in np.flatnonzero(self._asleep)
            for geometry in self._plant.GetCollisionGeometriesForBody(self._dominoes[index])
        ]
        if sleeping:
            declaration = CollisionFilterDeclaration().ExcludeWithin(
                GeometrySet(sleeping + self._static_ids)
            )
            self._filter_id = manager.ApplyTransient(declaration)


def displacement(a: RigidTransform, b: RigidTransform) -> float:
    """How far any point of a domino moved between poses ``a`` and ``b``: exactly, as a
    point's displacement is affine in the point, so over the box it is largest at a corner.

    The bound used before (centre shift + angle x bounding radius) overstated a rocking
    domino's motion by 60 %: one lying on its 7.5 mm face and rocking +-0.5 deg about its
    long axis (a limit cycle of the contact solver: one domino, seed 204) moved its
    corners at most 0.44 mm, the bound said 0.70, over ``rest_motion``, and it never slept.
    """
    turned = b.rotation().matrix() - a.rotation().matrix()
    moved = CORNERS @ turned.T + (b.translation() - a.translation())
    return float(np.linalg.norm(moved, axis=1).max())


def _floating_joint(plant: MultibodyPlant, body: Body):
    """The floating joint Drake gave a free body (one per domino model instance)."""
    (index,) = plant.GetJointIndices(body.model_instance())
    return plant.get_joint(index)

"""Independent checks of planned trajectories (pick-and-place, strike), as executed.

It shares nothing with the optimizer but the scenario: a separate plant built like the
simulator's (dombot_description.cell.add_cell with real finger joints, every domino a
free body), joint samples densified by linear interpolation, Drake distance queries per
sample. Which samples belong to a final approach or retreat is decided geometrically: the
TCP holds the orientation of the pose where the gripper closes or opens, within the
approach distance of it (coarse moves turn the hand; the straight lines do not); so is an
escape from the start: the first samples, while the TCP holds the start's orientation
within the escape distance of where it started. Reported:
smallest clearance per phase and pair of body classes, the grasp and place pose errors,
joint position/velocity/acceleration limit use, and jumps between segments. A strike's
phases are its segments (approach, push, retreat); measured besides: where the fingertips
are when the push begins, how far the pads travel past first contact and how fast.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder

from dombot_description.cell import add_cell, add_dominoes
from dombot_description.grasp import (
    SYMMETRIES,
    canonical_grasp,
    equivalent_grasps,
    top_grasp,
)
from dombot_description.scenario import Scenario
from dombot_planner.plan_segments import GRIPPER_CLOSE as CLOSE
from dombot_planner.plan_segments import GRIPPER_OPEN as OPEN
from dombot_planner.plan_segments import SampledSegment
from dombot_planner.request import box_corners

MAX_INTERPOLATION_STEP = 0.003  # rad per joint between checked configurations
LINE_TOLERANCE = 1e-3  # m beyond the approach distance still counted as a final line
ORIENTATION_TOLERANCE = 1e-3  # rad: the lines keep the target orientation exactly
ESCAPE_REACH = 0.08  # m: samples holding the start orientation this close to it escape
QUERY_DISTANCE = 0.05  # m
DROP_HEIGHT = 0.002  # m: a domino released this close above the table falls onto it


@dataclass
class Check:
    clearance: dict[tuple[str, str, str], float] = field(default_factory=dict)  # phase, a, b
    grasp_error: tuple[float, float] = (math.inf, math.inf)  # m, rad
    place_error: tuple[float, float] = (math.inf, math.inf)  # m, rad (nearest symmetry)
    position_limit_excess: float = 0.0  # rad beyond the limits
    velocity_use: float = 0.0  # max |v| / limit
    acceleration_use: float = 0.0  # max |a| / limit
    largest_jump: float = 0.0  # rad between a segment's end and the next one's start
    samples: int = 0

    def min_clearance(self, phase: str, moving: str, obstacle: str) -> float:
        return self.clearance.get((phase, moving, obstacle), QUERY_DISTANCE)


@dataclass
class StrikeCheck(Check):
    fingertip_height: float = math.nan  # m above the struck domino's base when the push starts
    push_past_contact: float = math.nan  # m the TCP travels after the pads first touch it
    contact_speed: float = math.nan  # m/s of the TCP at first contact


def dropped_onto_table(pose: RigidTransform) -> RigidTransform:
    """Where a domino let go at ``pose`` comes to rest: straight down onto the table top
    when its lowest corner is at most DROP_HEIGHT above it (the release height)."""
    lowest = box_corners(pose)[:, 2].min()
    if 0.0 < lowest <= DROP_HEIGHT:
        return RigidTransform(pose.rotation(), pose.translation() - [0.0, 0.0, lowest])
    return pose


def defined_grasps(domino_pose: RigidTransform) -> list[RigidTransform]:
    """Every grasp dombot_description.grasp defines for a domino at ``domino_pose``."""
    return [
        grasp.pose
        for tcp_in_domino in (canonical_grasp(), top_grasp())
        for grasp in equivalent_grasps(domino_pose, tcp_in_domino=tcp_in_domino)
    ]


def pose_error(actual: RigidTransform, wanted: RigidTransform) -> tuple[float, float]:
    angle = (actual.rotation().inverse() @ wanted.rotation()).ToAngleAxis().angle()
    return float(np.linalg.norm(actual.translation() - wanted.translation())), float(angle)


def nearest_error(
    actual: RigidTransform, candidates: Sequence[RigidTransform]
) -> tuple[float, float]:
    """Pose error to the closest candidate (by position error + 0.01 m per radian)."""
    return min((pose_error(actual, c) for c in candidates), key=lambda e: e[0] + 0.01 * e[1])


class CellChecker:
    """A plant built like the simulator's: the cell with real finger joints and the
    request's dominoes as free bodies, the first one the domino the request is about
    ("target"), the last ``pile_count`` ones the pile around it ("pile"), the others
    "standing"."""

    def __init__(
        self,
        scenario: Scenario,
        dominoes: Sequence[RigidTransform],
        acceleration_limit: float,
        pile_count: int = 0,
        free_acceleration: Sequence[float] | None = None,
    ) -> None:
        builder = DiagramBuilder()
        self.plant, self.scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        self.models = add_cell(self.plant, scenario)
        self.dominoes = add_dominoes(self.plant, len(dominoes))
        self.plant.Finalize()
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()
        self.plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        self.graph_context = self.scene_graph.GetMyContextFromRoot(self.context)
        self.tcp = self.plant.GetFrameByName(scenario.tcp_frame)
        self.fingers = [self.plant.GetJointByName(name) for name in scenario.gripper_joints]
        self.domino_bodies = [self.plant.GetBodyByName("domino", m) for m in self.dominoes]
        for body, pose in zip(self.domino_bodies, dominoes, strict=True):
            self.plant.SetFreeBodyPose(self.plant_context, body, pose)
        self.lower = self.plant.GetPositionLowerLimits()[: len(scenario.arm_joints)]
        self.upper = self.plant.GetPositionUpperLimits()[: len(scenario.arm_joints)]
        self.velocity = self.plant.GetVelocityUpperLimits()[: len(scenario.arm_joints)]
        self.acceleration = acceleration_limit
        # per joint, with no domino in the hand (PlannerSettings.free_acceleration_limits)
        self.free_acceleration = np.maximum(
            acceleration_limit,
            acceleration_limit if free_acceleration is None else free_acceleration,
        )
        self.classes = self._classes(len(dominoes) - pile_count)

    def _classes(self, first_pile: int) -> dict:
        inspector = self.scene_graph.model_inspector()
        pile = {body.index() for body in self.domino_bodies[first_pile:]}
        classes = {}
        for geometry in inspector.GetAllGeometryIds():
            body = self.plant.GetBodyFromFrameId(inspector.GetFrameId(geometry))
            if body is None:
                continue
            model = self.plant.GetModelInstanceName(body.model_instance())
            if body.name() in ("wsg_left_finger", "wsg_right_finger"):
                classes[geometry] = "pads"
            elif model in ("iiwa", "wsg"):
                classes[geometry] = "arm"
            elif model == "table":
                classes[geometry] = "table"
            elif body.index() == self.domino_bodies[0].index():
                classes[geometry] = "target"
            elif body.index() in pile:
                classes[geometry] = "pile"
            else:
                classes[geometry] = "standing"
        return classes

    def tcp_pose(self, q: np.ndarray) -> RigidTransform:
        self.plant.SetPositions(self.plant_context, self.models.arm, q)
        return self.tcp.CalcPoseInWorld(self.plant_context)

    def set_fingers(self, opening: float) -> None:
        for joint in self.fingers:
            joint.set_translation(self.plant_context, opening / 2.0)

    def _check_limits_and_joins(self, segments, start, result: Check, holding=None) -> None:
        """Position, velocity and acceleration limit use, and jumps between segments;
        ``holding`` (per segment, default all): a segment without a domino in the hand is
        judged by the free acceleration limits."""
        previous = np.asarray(start, dtype=float)
        holding = [True] * len(segments) if holding is None else holding
        for segment, held in zip(segments, holding, strict=True):
            q = segment.positions
            result.largest_jump = max(result.largest_jump, float(np.max(np.abs(q[0] - previous))))
            previous = q[-1]
            excess = np.maximum(self.lower - q, q - self.upper).max()
            result.position_limit_excess = max(result.position_limit_excess, float(excess))
            velocity = np.max(np.abs(segment.velocities) / self.velocity)
            result.velocity_use = max(result.velocity_use, float(velocity))
            limit = self.acceleration if held else self.free_acceleration
            acceleration = np.max(np.abs(segment.accelerations) / limit)
            result.acceleration_use = max(result.acceleration_use, float(acceleration))

    @staticmethod
    def _densified(positions: np.ndarray) -> np.ndarray:
        if len(positions) < 2:
            return positions
        steps = np.ceil(np.max(np.abs(np.diff(positions, axis=0)), axis=1) / MAX_INTERPOLATION_STEP)
        dense = [positions[:1]]
        for a, b, count in zip(positions[:-1], positions[1:], steps.astype(int), strict=True):
            fractions = np.linspace(0.0, 1.0, max(count, 1) + 1)[1:, None]
            dense.append(a + fractions * (b - a))
        return np.vstack(dense)

    def _record(self, result: Check, phase: str, holding: bool) -> None:
        query = self.scene_graph.get_query_output_port().Eval(self.graph_context)
        for pair in query.ComputeSignedDistancePairwiseClosestPoints(QUERY_DISTANCE):
            a, b = self.classes[pair.id_A], self.classes[pair.id_B]
            key = self._key(a, b, holding)
            if key is None:
                continue
            full = (phase, *key)
            result.clearance[full] = min(result.clearance.get(full, QUERY_DISTANCE), pair.distance)

    @staticmethod
    def _key(a: str, b: str, holding: bool) -> tuple[str, str] | None:
        """(moving, obstacle) for a pair; the picked domino moves only while held."""
        moving = {"arm", "pads"} | ({"target"} if holding else set())
        if a in moving and b in moving:
            if {a, b} == {"pads", "target"} or a == b == "pads":  # holding; closed fingers
                return None
            return (min(a, b), "self")
        if b in moving:
            a, b = b, a
        if a not in moving:
            return None
        return ("held" if a == "target" else a, b)


class TrajectoryChecker(CellChecker):
    """The check plant for one pick-and-place: the cell, the picked, standing and pile
    dominoes."""

    def __init__(
        self,
        scenario: Scenario,
        domino_pose: RigidTransform,
        place_pose: RigidTransform,
        standing: Sequence[RigidTransform],
        acceleration_limit: float,
        closed_width: float,
        pile: Sequence[RigidTransform] = (),
        free_acceleration: Sequence[float] | None = None,
    ) -> None:
        super().__init__(
            scenario,
            [domino_pose, *standing, *pile],
            acceleration_limit,
            len(pile),
            free_acceleration,
        )
        self.domino_pose, self.place_pose = domino_pose, place_pose
        self.closed_width = closed_width

    def check(
        self,
        segments: Sequence[SampledSegment],
        start: np.ndarray,
        approach_distances: tuple[float, float],
        grasps_for: Callable[[RigidTransform], Sequence[RigidTransform]] | None = None,
    ) -> Check:
        """Check executed ``segments`` from ``start``.

        ``approach_distances``: (pick, place) lengths of the final lines;
        ``grasps_for(domino_pose)`` lists the acceptable TCP poses to grasp a domino lying
        there (default: the canonical tilted or the top grasp, any symmetry).
        """
        grasps_for = grasps_for or defined_grasps
        result = Check()
        states, lines, grasp_errors, releases = self._follow_domino(
            segments, grasps_for, approach_distances
        )
        holding = [held_in_tcp is not None for _, held_in_tcp, _ in states]
        self._check_limits_and_joins(segments, start, result, holding)
        result.grasp_error = max(grasp_errors, key=lambda e: e[0] + 0.01 * e[1])
        symmetric = [self.place_pose @ RigidTransform(s) for s in SYMMETRIES]
        result.place_error = nearest_error(releases[-1], symmetric)
        escaping = Escape(self.tcp_pose(start))
        for segment, (resting, held_in_tcp, opening) in zip(segments, states, strict=True):
            for q in self._densified(segment.positions):
                tcp = self.tcp_pose(q)
                self._set_scene(resting if held_in_tcp is None else tcp @ held_in_tcp, opening)
                if escaping.goes_on(tcp):
                    phase = "escape"
                elif any(_near_target(tcp, t, d) for t, d in lines):
                    phase = "fine"
                else:
                    phase = "coarse"
                self._record(result, phase, holding=held_in_tcp is not None)
                result.samples += 1
        return result

    def _follow_domino(self, segments, grasps_for, approach_distances):
        """Per segment: where the domino rests (or how it is held) and the finger opening.

        Also the TCP poses of the final lines, the grasp errors and the release poses, all
        from the executed configurations at the gripper events.
        """
        resting, held_in_tcp = self.domino_pose, None
        opening = next(s.gripper_position for s in segments if s.gripper_after == OPEN)
        states, lines, grasp_errors, releases = [], [], [], []
        for segment in segments:
            states.append((resting, held_in_tcp, opening))
            tcp = self.tcp_pose(segment.positions[-1])
            if segment.gripper_after == CLOSE:
                grasp_errors.append(nearest_error(tcp, grasps_for(resting)))
                held_in_tcp, resting = tcp.inverse() @ resting, None
                opening = self.closed_width  # the fingers stop on the domino
                lines.append((tcp, approach_distances[0]))
            elif segment.gripper_after == OPEN:
                opening = segment.gripper_position
                if held_in_tcp is not None:
                    releases.append(tcp @ held_in_tcp)
                    resting, held_in_tcp = dropped_onto_table(releases[-1]), None
                    lines.append((tcp, approach_distances[1]))
        return states, lines, grasp_errors, releases

    def _set_scene(self, pose: RigidTransform, opening: float) -> None:
        """The picked domino at ``pose``; fingers ``opening`` apart."""
        self.plant.SetFreeBodyPose(self.plant_context, self.domino_bodies[0], pose)
        self.set_fingers(opening)


class Escape:
    """Recognises an escape: the samples from the start on while the TCP holds the start's
    orientation within ESCAPE_REACH of it; once it turns or goes farther, it is over."""

    def __init__(self, start: RigidTransform) -> None:
        self.start = start
        self.over = False

    def goes_on(self, tcp: RigidTransform) -> bool:
        if not self.over:
            self.over = not _near_target(tcp, self.start, ESCAPE_REACH)
        return not self.over


def _near_target(tcp: RigidTransform, target: RigidTransform, distance: float) -> bool:
    """The TCP holds the target's orientation within ``distance`` of it: a final line."""
    position, angle = pose_error(tcp, target)
    return position <= distance + LINE_TOLERANCE and angle <= ORIENTATION_TOLERANCE


class StrikeChecker(CellChecker):
    """The check plant for one strike: the cell, the struck domino and the rest of the run.

    Phases are the segments' labels (and "escape"); the dominoes stay where they stood
    (after the push the struck one has gone forward, so its clearances in the retreat mean
    nothing).
    """

    def __init__(
        self,
        scenario: Scenario,
        domino_pose: RigidTransform,
        standing: Sequence[RigidTransform],
        acceleration_limit: float,
    ) -> None:
        super().__init__(scenario, [domino_pose, *standing], acceleration_limit)
        self.domino_pose = domino_pose

    def check(
        self, segments: Sequence[SampledSegment], start: np.ndarray, start_opening: float
    ) -> StrikeCheck:
        """Check executed ``segments`` from ``start`` with the fingers ``start_opening`` apart."""
        result = StrikeCheck()
        self._check_limits_and_joins(segments, start, result)
        opening = start_opening
        escaping = Escape(self.tcp_pose(start))
        for segment in segments:
            self.set_fingers(opening)
            for q in self._densified(segment.positions):
                phase = "escape" if escaping.goes_on(self.tcp_pose(q)) else segment.label
                self._record(result, phase, holding=False)
                result.samples += 1
            if segment.gripper_after in (OPEN, CLOSE):
                opening = segment.gripper_position
            if segment.label == "push":
                self._measure_push(segment, result)
        return result

    def _measure_push(self, push: SampledSegment, result: StrikeCheck) -> None:
        self.tcp_pose(push.positions[0])
        base = box_corners(self.domino_pose)[:, 2].min()
        result.fingertip_height = self._lowest_pad_point() - base
        tcp = np.array([self.tcp_pose(q).translation() for q in push.positions])
        distance = np.array([self._pads_to_target(q) for q in push.positions])
        touching = np.flatnonzero(distance <= 0.0)
        if len(touching) == 0 or touching[0] == 0:
            return
        i = touching[0]  # first contact between samples i - 1 and i: interpolate
        fraction = distance[i - 1] / (distance[i - 1] - distance[i])
        contact = tcp[i - 1] + fraction * (tcp[i] - tcp[i - 1])
        result.push_past_contact = float(np.linalg.norm(tcp[-1] - contact))
        travel = np.linalg.norm(tcp[i] - tcp[i - 1])
        result.contact_speed = float(travel / (push.times[i] - push.times[i - 1]))

    def _pads_to_target(self, q: np.ndarray) -> float:
        self.tcp_pose(q)
        query = self.scene_graph.get_query_output_port().Eval(self.graph_context)
        return min(
            (
                pair.distance
                for pair in query.ComputeSignedDistancePairwiseClosestPoints(QUERY_DISTANCE)
                if {self.classes[pair.id_A], self.classes[pair.id_B]} == {"pads", "target"}
            ),
            default=QUERY_DISTANCE,
        )

    def _lowest_pad_point(self) -> float:
        """Height of the lowest corner of the pad collision boxes (their world poses)."""
        inspector = self.scene_graph.model_inspector()
        query = self.scene_graph.get_query_output_port().Eval(self.graph_context)
        signs = np.array([[i, j, k] for i in (-1, 1) for j in (-1, 1) for k in (-1, 1)])
        lowest = math.inf
        for geometry, kind in self.classes.items():
            if kind != "pads":
                continue
            box = inspector.GetShape(geometry)
            half = np.array([box.width(), box.depth(), box.height()]) / 2
            corners = query.GetPoseInWorld(geometry) @ (signs * half).T
            lowest = min(lowest, float(corners[2].min()))
        return lowest

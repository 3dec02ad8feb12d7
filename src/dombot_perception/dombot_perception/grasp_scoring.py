"""Rank dominoes by how well the gripper can pick them, as a builder would choose.

The grasp itself is ``dombot_description.grasp`` (the one definition the planner
executes): ``pick_grasps`` lists the ways to hold a domino, best first. For each
domino, each candidate grasp is checked against everything the cameras saw, and
the domino's score combines:

* flatness: how parallel its largest face is to the table (the paper's only term);
* clearance: the free space around the finger pads' path (open, swept back along the
  approach, then closing onto the domino) against every other seen point and the
  table: the fingers must fit beside the domino's long faces and close on it without
  touching a neighbour; below ``min_clearance`` (a predicted collision) the term is 0;
* uncovered: no other domino lies on top of it (points above its top face);
* height: higher in the pile is better (nothing under it can pin it, and picking it
  does not disturb the rest); 0.5 for the lowest, 1 for the highest, so it only ranks;
* reach: the grasp comes from above and its TCP lies within the arm's reach.

The score is a weighted geometric mean of the terms, so any term at zero (a finger
would hit a neighbour, a domino lies on it) makes the domino unpickable however flat
it is. A grasp is *predicted to succeed* when clearance, coverage and reach pass
their thresholds; ``predicted_success`` says so.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field

import numpy as np
from pydrake.math import RigidTransform

from dombot_description.grasp import Grasp, comes_from_above, nearest_distance, pick_grasps
from dombot_perception.domino_model import HALF_SIZE, box_signed_distance, dot3
from dombot_perception.frames import Detection

# m: clearance reported when no point is nearer: the score saturates at good_clearance,
# and the bring-up's roomiest first needs no finer order among those with this much room
FREE_SPACE = 0.015
NEIGHBOURHOOD = 0.12  # m around a domino's centre: farther points cannot touch its grasp
VERTICAL = np.array([0.0, 0.0, 1.0])  # the planner's first approach line, down to the grasp
TERMS = ("flatness", "clearance", "uncovered", "height", "reach")


@dataclass(frozen=True)
class GraspScoringConfig:
    weights: dict[str, float] = field(
        default_factory=lambda: {
            "flatness": 1.0,
            "clearance": 2.0,
            "uncovered": 1.0,
            "height": 0.5,
            "reach": 1.0,
        }
    )
    good_clearance: float = 0.004  # m: clearance term saturates at 1 here
    min_clearance: float = 0.0015  # m: less is a predicted collision (pose error budget)
    approach_distance: float = 0.05  # m: pads sweep this far back along the approach line
    min_table_clearance: float = 0.0  # m: pads lower than this above the table: infeasible
    own_surface: float = 0.002  # m: points this close to the domino's box are its own
    cover_height: float = 0.002  # m above the top face: a point there lies on the domino
    max_cover_points: int = 15  # points on top that make the domino count as covered
    reach: tuple[float, float] = (0.35, 0.80)  # m: TCP distance from the base axis
    reach_falloff: float = 0.05  # m outside the reach where the term drops to 0
    base_xy: tuple[float, float] = (0.0, 0.0)


@dataclass(frozen=True)
class GraspChoice:
    grasp: Grasp
    clearance: float


def score_detections(
    detections: list[Detection], scene_points: np.ndarray, config: GraspScoringConfig
) -> list[Detection]:
    """Fill each detection's grasp, clearance and score; return them best first."""
    if not detections:
        return []
    tops = np.array([_top_height(d.X_WD) for d in detections])
    span = tops.max() - tops.min()
    for detection, top in zip(detections, tops, strict=True):
        obstacles, local = _obstacles(detection.X_WD, scene_points, config.own_surface)
        choice = best_grasp(detection.X_WD, obstacles, config)
        covered = _points_on_top(detection.X_WD, obstacles, local, config.cover_height)
        terms = {
            "flatness": abs(detection.X_WD[2, 2]),
            "clearance": clearance_term(choice.clearance, config),
            "uncovered": float(np.clip(1.0 - covered / config.max_cover_points, 0.0, 1.0)),
            "height": 0.5 + 0.5 * float((top - tops.min()) / span) if span > 1e-6 else 1.0,
            "reach": _reach_term(choice.grasp, config),
        }
        detection.grasp_pose = choice.grasp.pose.GetAsMatrix4()
        detection.grasp_width = choice.grasp.pregrasp_opening
        detection.clearance = choice.clearance
        detection.score_terms = terms
        detection.score = weighted_geometric_mean(terms, config.weights)
    return sorted(detections, key=lambda d: -d.score)


def clearance_term(clearance: float, config: GraspScoringConfig) -> float:
    """0 below ``min_clearance`` (a predicted collision leaves the domino unscored, offered
    after those with room), else rising to 1 at ``good_clearance``."""
    if clearance < config.min_clearance:
        return 0.0
    return float(np.clip(clearance / config.good_clearance, 0.0, 1.0))


def predicted_success(detection: Detection, config: GraspScoringConfig) -> bool:
    """Whether the chosen grasp is expected to work: fingers fit, nothing on top, reachable."""
    terms = detection.score_terms
    return (
        detection.clearance >= config.min_clearance
        and terms.get("uncovered", 0.0) > 0.0
        and terms.get("reach", 0.0) > 0.0
    )


def weighted_geometric_mean(terms: dict[str, float], weights: dict[str, float]) -> float:
    total = sum(weights.get(name, 0.0) for name in terms)
    if total <= 0.0:
        return 0.0
    log_sum = sum(
        weights.get(name, 0.0) * np.log(max(value, 1e-12)) for name, value in terms.items()
    )
    return float(np.exp(log_sum / total)) if min(terms.values()) > 0.0 else 0.0


def best_grasp(
    domino_pose: np.ndarray, obstacles: np.ndarray, config: GraspScoringConfig
) -> GraspChoice:
    """The first of ``pick_grasps``' order that clears every neighbour, else the clearest one.

    Only grasps that come from above and keep the pads above the table are considered;
    with none, the clearance is -1 (unpickable).
    """
    candidates = pick_grasps(RigidTransform(domino_pose), base_xy=config.base_xy)
    feasible = feasible_grasps(candidates, config)
    if not feasible:
        return GraspChoice(candidates[0], -1.0)
    choices, clearances = [], {}
    for grasp in feasible:
        key = _pad_space(grasp)
        if key not in clearances:  # a finger-swapped twin's pads pass through the same space
            clearances[key] = grasp_clearance(grasp, obstacles, config.approach_distance)
        choice = GraspChoice(grasp, clearances[key])
        if choice.clearance >= config.min_clearance:
            return choice
        choices.append(choice)
    return max(choices, key=lambda choice: choice.clearance)


def feasible_grasps(candidates: Sequence[Grasp], config: GraspScoringConfig) -> list[Grasp]:
    """Those of ``candidates`` that come from above and keep the pads above the table."""
    return [
        grasp
        for grasp in candidates
        if comes_from_above(grasp.pose) and pads_above_table(grasp, config.min_table_clearance)
    ]


def grasp_clearance(grasp: Grasp, obstacles: np.ndarray, approach_distance: float) -> float:
    """Smallest distance [m] from the pads' path (``Grasp.pad_paths``: straight down to the
    grasp, the planner's first approach line, then closing onto the domino) to any
    obstacle point; ``FREE_SPACE`` when nothing is nearer."""
    paths = grasp.pad_path_array(approach_distance, VERTICAL)
    return nearest_distance(paths, obstacles, cap=FREE_SPACE)


def _pad_space(grasp: Grasp) -> tuple:
    """The TCP position and approach axis, rounded to 1 nm: grasps with the same key have
    the same ``pad_paths`` (finger-swapped twins differ by a half turn about the approach;
    the pad boxes' centres lie in the TCP's y-z plane, wsg50.urdf, so it swaps the pads)."""
    pose = grasp.pose.GetAsMatrix4()
    return tuple(np.round(np.concatenate([pose[:3, 3], pose[:3, 2]]), 9))


def pads_above_table(grasp: Grasp, min_height: float) -> bool:
    """Whether both open pads stay at least ``min_height`` above the table (z = 0)."""
    for box in grasp.pad_boxes(grasp.pregrasp_opening):
        rotation = box.pose.rotation().matrix()
        lowest = box.pose.translation()[2] - np.abs(rotation[2, :]) @ (box.size / 2.0)
        if lowest < min_height:
            return False
    return True


def _obstacles(
    domino_pose: np.ndarray, scene_points: np.ndarray, own_surface: float
) -> tuple[np.ndarray, np.ndarray]:
    """Scene points within NEIGHBOURHOOD not on this domino's own surface, in world and in
    the domino's frame."""
    # a distance mask: a k-d tree's answer, as a list, costs more to turn into an index
    offsets = scene_points - domino_pose[:3, 3]
    nearby = dot3(offsets, offsets) <= NEIGHBOURHOOD**2
    local = offsets[nearby] @ domino_pose[:3, :3]
    apart = box_signed_distance(local) > own_surface
    return scene_points[nearby][apart], local[apart]


def _points_on_top(
    domino_pose: np.ndarray, obstacles: np.ndarray, local: np.ndarray, cover_height: float
) -> int:
    """Obstacle points (world, and ``local`` in the domino's frame) above the domino's top,
    inside its outline across its up axis."""
    across = [axis for axis in range(3) if axis != int(np.argmax(np.abs(domino_pose[2, :3])))]
    outline = np.all(np.abs(local[:, across]) <= HALF_SIZE[across], axis=1)
    above = obstacles[:, 2] > _top_height(domino_pose) + cover_height
    return int(np.count_nonzero(outline & above))


def _top_height(domino_pose: np.ndarray) -> float:
    return float(domino_pose[2, 3] + np.abs(domino_pose[2, :3]) @ HALF_SIZE)


def _reach_term(grasp: Grasp, config: GraspScoringConfig) -> float:
    if not comes_from_above(grasp.pose):
        return 0.0
    position = grasp.pose.translation()
    radius = float(np.hypot(position[0] - config.base_xy[0], position[1] - config.base_xy[1]))
    outside = max(config.reach[0] - radius, radius - config.reach[1], 0.0)
    return float(np.clip(1.0 - outside / config.reach_falloff, 0.0, 1.0))

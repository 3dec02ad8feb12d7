"""Score detections against the simulator's ground truth (evaluation only).

Matching: detections and true dominoes are paired one-to-one (Hungarian assignment
on centre distance); a pair further apart than ``max_match_distance`` is no match.
A true domino is *top and unoccluded* when no other domino lies above any part of it
(vertical rays from its top face hit nothing) and at least ``min_visible`` of its
silhouette is visible in one camera (label pixels over the projected box's convex
hull area, which for a box is exactly its silhouette).

Grasp success *actual* is checked geometrically on the true scene: the grasp chosen
from the detected pose must close on the true domino (its pose in the gripper frame
within the pads' tolerance) and its open pads, swept along the approach, must clear
every other true domino (all of each box, hidden parts included) and the table.
"""

from __future__ import annotations

from dataclasses import dataclass

import numpy as np
from pydrake.math import RigidTransform
from scipy.optimize import linear_sum_assignment
from scipy.spatial import ConvexHull, QhullError

from dombot_description.grasp import (
    FINGER_SWAP,
    PREGRASP_CLEARANCE,
    Grasp,
    canonical_grasp,
)
from dombot_perception.domino_model import DOMINO_SIZE, HALF_SIZE, orientation_error
from dombot_perception.frames import Detection
from dombot_perception.grasp_scoring import grasp_clearance, pads_above_table

CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])


@dataclass(frozen=True)
class EvaluationConfig:
    max_match_distance: float = 0.010  # m
    min_visible: float = 0.8  # of the silhouette, in the best camera
    grasp_position_tolerance: float = 0.005  # m along the gripper's x and z (pads stay on)
    grasp_angle_tolerance: float = np.radians(10.0)
    min_true_clearance: float = 0.0  # m: pads may not touch anything


@dataclass(frozen=True)
class TruthDomino:
    index: int
    X_WD: np.ndarray


@dataclass
class Match:
    detection: int
    truth: int
    position_error: float  # m
    orientation_error: float  # rad, modulo the box symmetries


def match_detections(
    detections: list[Detection], truths: list[TruthDomino], max_distance: float
) -> list[Match]:
    if not detections or not truths:
        return []
    found = np.array([d.X_WD[:3, 3] for d in detections])
    true = np.array([t.X_WD[:3, 3] for t in truths])
    distance = np.linalg.norm(found[:, None, :] - true[None, :, :], axis=2)
    rows, cols = linear_sum_assignment(distance)
    return [
        Match(
            int(r),
            int(c),
            float(distance[r, c]),
            orientation_error(detections[r].X_WD[:3, :3], truths[c].X_WD[:3, :3]),
        )
        for r, c in zip(rows, cols, strict=True)
        if distance[r, c] <= max_distance
    ]


def covered_from_above(truths: list[TruthDomino], samples: int = 5) -> np.ndarray:
    """Per domino: does any other domino lie above some point of its top face?"""
    grid = np.linspace(-0.9, 0.9, samples)
    local = np.array([[x, y, 1.0] for x in grid for y in grid])
    covered = np.zeros(len(truths), dtype=bool)
    for i, truth in enumerate(truths):
        rotation, centre = truth.X_WD[:3, :3], truth.X_WD[:3, 3]
        up_axis = int(np.argmax(np.abs(rotation[2, :])))
        axes = [(up_axis + 1) % 3, (up_axis + 2) % 3, up_axis]
        starts = np.zeros((local.shape[0], 3))
        starts[:, axes] = local * HALF_SIZE[axes]
        starts[:, up_axis] *= np.sign(rotation[2, up_axis])
        starts = starts @ rotation.T + centre
        for j, other in enumerate(truths):
            if j != i and np.any(_vertical_ray_hits(starts, other.X_WD)):
                covered[i] = True
                break
    return covered


def _vertical_ray_hits(starts: np.ndarray, box_pose: np.ndarray) -> np.ndarray:
    """Whether upward rays from ``starts`` pass through the box (slab test)."""
    origin = (starts - box_pose[:3, 3]) @ box_pose[:3, :3]
    direction = box_pose[2, :3]  # world z in the box frame
    with np.errstate(divide="ignore", invalid="ignore"):
        t1 = (-HALF_SIZE - origin) / direction
        t2 = (HALF_SIZE - origin) / direction
    parallel = np.abs(direction) < 1e-12
    inside_slab = np.abs(origin) <= HALF_SIZE
    near = np.where(parallel, np.where(inside_slab, -np.inf, np.inf), np.minimum(t1, t2))
    far = np.where(parallel, np.where(inside_slab, np.inf, -np.inf), np.maximum(t1, t2))
    enter, leave = near.max(axis=1), far.min(axis=1)
    return (enter <= leave) & (leave > 1e-6)


def visible_fraction(
    truth: TruthDomino, label: np.ndarray, intrinsics: np.ndarray, camera_pose: np.ndarray
) -> float:
    """Label pixels of this domino over the area of its projected silhouette."""
    corners = (CORNERS * HALF_SIZE) @ truth.X_WD[:3, :3].T + truth.X_WD[:3, 3]
    in_camera = (corners - camera_pose[:3, 3]) @ camera_pose[:3, :3]
    if np.any(in_camera[:, 2] <= 0):
        return 0.0
    pixels = in_camera[:, :2] / in_camera[:, 2:] * intrinsics[[0, 1], [0, 1]]
    try:
        area = ConvexHull(pixels).volume  # a 2-D hull's "volume" is its area
    except QhullError:
        return 0.0
    return float(np.count_nonzero(label == truth.index) / area) if area > 0 else 0.0


def true_obstacle_points(truths: list[TruthDomino], exclude: int, spacing: float = 0.003):
    """Dense points filling every true domino but one (hidden parts included)."""
    axes = [np.linspace(-h, h, max(2, int(np.ceil(2 * h / spacing)) + 1)) for h in HALF_SIZE]
    grid = np.stack(np.meshgrid(*axes, indexing="ij"), axis=-1).reshape(-1, 3)
    clouds = [grid @ t.X_WD[:3, :3].T + t.X_WD[:3, 3] for k, t in enumerate(truths) if k != exclude]
    return np.concatenate(clouds) if clouds else np.zeros((0, 3))


def grasp_succeeds(
    detection: Detection,
    truths: list[TruthDomino],
    truth_index: int | None,
    config: EvaluationConfig,
) -> bool:
    """Would the detection's grasp close on the true domino without hitting anything?"""
    if truth_index is None:
        return False
    grasp_pose = RigidTransform(detection.grasp_pose)
    true_pose = truths[truth_index].X_WD
    if not _holds(grasp_pose, true_pose, config):
        return False
    grasp = Grasp(grasp_pose, float(DOMINO_SIZE[1]), detection.grasp_width)
    if not pads_above_table(grasp, 0.0):
        return False
    obstacles = true_obstacle_points(truths, truth_index)
    return grasp_clearance(grasp, obstacles, approach_distance=0.05) > config.min_true_clearance


def _holds(grasp_pose: RigidTransform, true_pose: np.ndarray, config: EvaluationConfig) -> bool:
    """The true domino sits where the canonical grasp expects it (up to the symmetries of
    the box and of the two fingers)."""
    actual = grasp_pose.inverse().GetAsMatrix4() @ true_pose
    for swap in (RigidTransform(), FINGER_SWAP):
        expected = (swap.inverse() @ canonical_grasp().inverse()).GetAsMatrix4()  # X_GD
        offset = actual[:3, 3] - expected[:3, 3]
        if (
            abs(offset[1]) <= PREGRASP_CLEARANCE
            and np.all(np.abs(offset[[0, 2]]) <= config.grasp_position_tolerance)
            and orientation_error(actual[:3, :3], expected[:3, :3]) <= config.grasp_angle_tolerance
        ):
            return True
    return False

"""Benchmark perception against the simulator's ground truth on seeded piles.

For each pile size (default 10, 30, 60) and seed, the simulator pours and settles a
pile, renders both cameras, and the pipeline runs three ways: both cameras, camera_0
alone, camera_1 alone. Reported: precision, recall (all dominoes in the pile region
and the top, unoccluded ones), median position and orientation errors, latency per
stage, and grasp success on the true scene for the top choices of our ranking and
of the paper's flatness-only ranking, plus predicted-vs-actual grasp success.
Latency is given per stage as wall time and as this process's CPU time (on a shared
machine the wall time mostly measures the load).

Placement checks (``/perception/check_placement``): runs laid out as the bring-up lays
them (``dombot_bringup.layouts``: a line, an arc and an S-curve in the build area) are put
in the simulator while being built (the dominoes placed so far, shifted and turned by a
few mm and degrees, some knocked away, the last one sometimes tipping forward or back),
complete, and struck; the simulator lets them settle (or topple), every camera of
``--placement-cameras`` (perception_node's ``placement_cameras``) renders the scene once,
and the check is run on each camera alone and on all of them (the node's check), its
status, position and tilt compared with the final true poses: per camera set, and per
scene kind what went wrong (standing called fallen or missing, fallen called standing,
not seen).

Prints one JSON object on stdout (progress on stderr). ``--figures DIR`` writes a
mask overlay and a detection picture of the first 30-domino pile into DIR.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time
from pathlib import Path

import numpy as np
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialVelocity

from dombot_bringup import layouts
from dombot_description import DOMINO_SIZE, tilt_from_vertical
from dombot_description.grasp import pick_grasps, upright_pose
from dombot_perception.debug_image import draw_detections, mask_overlay
from dombot_perception.evaluation import (
    EvaluationConfig,
    TruthDomino,
    covered_from_above,
    grasp_succeeds,
    match_detections,
    visible_fraction,
)
from dombot_perception.frames import CameraView, Detection
from dombot_perception.grasp_scoring import predicted_success
from dombot_perception.perception_parameters import PerceptionParameters
from dombot_perception.pipeline import STAGES, PerceptionPipeline, build_pipeline
from dombot_perception.placement_check import (
    FALLEN,
    MISSING,
    NOT_SEEN,
    STANDING,
    PlacementConfig,
    check_placements,
)
from dombot_sim.physics_checks import PUSH_SPIN
from dombot_sim.world import CellWorld, WorldConfig

CAMERA_SETS = {
    "both": ("camera_0", "camera_1"),
    "camera_0": ("camera_0",),
    "camera_1": ("camera_1",),
}
TOP_K = 3  # grasp choices per pile compared between rankings
RUN_LENGTH = 12  # dominoes per benchmarked run
KINDS = ("building", "complete", "struck")
STATUS_NAMES = {STANDING: "standing", FALLEN: "fallen", MISSING: "missing", NOT_SEEN: "not_seen"}
BRINGUP_TOLERANCE = (0.003, np.radians(3.0))  # m, rad: the bring-up's acceptance of a placement


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def views_of(frames: dict, offset: float) -> list[CameraView]:
    """What perception is given: the frames with the camera matrix the simulator publishes,
    its principal point moved by ``offset`` pixels (0 but to diagnose a calibration error)."""
    views = []
    for f in frames.values():
        matrix = f.K.copy()
        matrix[:2, 2] += offset
        views.append(CameraView(f.name, f.rgb, f.depth, matrix, f.X_WC))
    return views


def truth_of(world: CellWorld) -> list[TruthDomino]:
    return [TruthDomino(t.index, t.X_WD) for t in world.domino_truth() if t.in_use]


def flattest_first(detections: list[Detection]) -> list[Detection]:
    """The paper's choice: largest face most parallel to the floor, first grasp as listed."""
    ranked = sorted(detections, key=lambda d: -abs(d.X_WD[2, 2]))
    copies = []
    for detection in ranked:
        grasp = pick_grasps(RigidTransform(detection.X_WD))[0]
        copies.append(
            Detection(
                **{
                    **detection.__dict__,
                    "grasp_pose": grasp.pose.GetAsMatrix4(),
                    "grasp_width": grasp.pregrasp_opening,
                }
            )
        )
    return copies


def evaluate_pile(world: CellWorld, offset: float, figures: Path | None) -> dict:
    """Each camera set on the pile as rendered (a fresh pipeline each: no regions remembered
    from another run), then both cameras again after the first choice was picked."""
    frames = {n: f for n, f in world.render().items() if n in CAMERA_SETS["both"]}
    views = views_of(frames, offset)
    truths = truth_of(world)
    top = top_unoccluded(frames, truths)
    pile = {"dominoes": len(truths), "top_unoccluded": int(top.sum())}
    for name, cameras in CAMERA_SETS.items():
        pipeline = build_pipeline(world.scenario)
        chosen = [v for v in views if v.name in cameras]
        result, entry, matches = detect(chosen, pipeline, truths, top)
        if name == "both":
            config = EvaluationConfig()
            entry.update(grasp_outcomes(result.detections, matches, truths, pipeline, config))
            if figures is not None:
                write_figures(figures, views, result)
            first = [m.truth for m in matches if m.detection == 0]
            if first:
                pile["after_pick"] = detect_after_pick(world, pipeline, truths[first[0]], offset)
        pile[name] = entry
    return pile


def top_unoccluded(frames: dict, truths: list[TruthDomino]) -> np.ndarray:
    """Mask of the dominoes nothing lies on that some camera sees at least mostly."""
    covered = covered_from_above(truths)
    visible = np.array(
        [max(visible_fraction(t, f.label, f.K, f.X_WC) for f in frames.values()) for t in truths]
    )
    return ~covered & (visible >= EvaluationConfig().min_visible)


def detect(
    views: list[CameraView],
    pipeline: PerceptionPipeline,
    truths: list[TruthDomino],
    top: np.ndarray,
) -> tuple:
    """The pipeline's result on ``views``, its figures against the ``truths`` (``top``:
    mask of the top, unoccluded ones), the matches."""
    started, cpu_started = time.perf_counter(), time.process_time()
    result = pipeline.run(views)
    total, cpu = time.perf_counter() - started, time.process_time() - cpu_started
    matches = match_detections(result.detections, truths, EvaluationConfig().max_match_distance)
    entry = {
        "detections": len(result.detections),
        "matched": len(matches),
        "matched_top": int(sum(top[m.truth] for m in matches)),
        "position_errors": [m.position_error for m in matches],
        "orientation_errors": [m.orientation_error for m in matches],
        "latency": {**result.timings, "total": total, "cpu_total": cpu},
        "cpu": result.cpu_timings,
    }
    return result, entry, matches


def detect_after_pick(
    world: CellWorld, pipeline: PerceptionPipeline, picked: TruthDomino, offset: float
) -> dict:
    """The next detect of the bring-up: the first choice taken away (the rest left as it
    lies), rendered again and detected by the same pipeline, which remembers the regions
    of the last frame."""
    world.set_domino_poses({t.index: t.X_WD for t in truth_of(world) if t.index != picked.index})
    frames = {n: f for n, f in world.render().items() if n in CAMERA_SETS["both"]}
    truths = truth_of(world)
    top = top_unoccluded(frames, truths)
    _, entry, _ = detect(views_of(frames, offset), pipeline, truths, top)
    return {**entry, "dominoes": len(truths), "top_unoccluded": int(top.sum())}


def grasp_outcomes(detections, matches, truths, pipeline, config) -> dict:
    """Actual success of the top choices (ours, flatness-only) and of every prediction."""
    truth_of_detection = {m.detection: m.truth for m in matches}
    ours = [
        grasp_succeeds(d, truths, truth_of_detection.get(i), config)
        for i, d in enumerate(detections)
    ]
    flat_order = sorted(range(len(detections)), key=lambda i: -abs(detections[i].X_WD[2, 2]))
    flat_ranked = flattest_first(detections)
    flat = [
        grasp_succeeds(d, truths, truth_of_detection.get(i), config)
        for d, i in zip(flat_ranked[:TOP_K], flat_order[:TOP_K], strict=True)
    ]
    predicted = [predicted_success(d, pipeline.config.scoring) for d in detections]
    return {
        "ours_top": ours[:TOP_K],
        "flatness_top": flat,
        "predicted": predicted,
        "actual": ours,
    }


def write_figures(directory: Path, views: list[CameraView], result) -> None:
    """Mask overlay and detections per camera, cropped to the pile and enlarged 2x."""
    from PIL import Image

    directory.mkdir(parents=True, exist_ok=True)
    for view in views:
        masks = result.masks.get(view.name, [])
        crop = _pile_window(view, masks)
        for name, picture in (
            ("masks", mask_overlay(view, masks)),
            ("detections", draw_detections(view.rgb, view, result.detections)),
        ):
            image = Image.fromarray(picture[crop])
            image = image.resize((image.width * 2, image.height * 2), Image.NEAREST)
            image.save(directory / f"perception_{name}_{view.name}.png")


def _pile_window(view: CameraView, masks: list[np.ndarray], margin: int = 30):
    if not masks:
        return np.s_[:, :]
    rows, cols = np.divmod(np.concatenate(masks), view.depth.shape[1])
    height, width = view.depth.shape
    return np.s_[
        max(rows.min() - margin, 0) : min(rows.max() + margin, height),
        max(cols.min() - margin, 0) : min(cols.max() + margin, width),
    ]


def summarise(piles: list[dict]) -> dict:
    summary = {}
    for name in (*CAMERA_SETS, "after_pick"):
        # after_pick: the pile less the first choice, detected next by the same pipeline
        counted = [(p[name], p if name in CAMERA_SETS else p[name]) for p in piles if name in p]
        if not counted:
            continue
        entries = [entry for entry, _ in counted]
        detections = sum(e["detections"] for e in entries)
        matched = sum(e["matched"] for e in entries)
        positions = np.concatenate([e["position_errors"] for e in entries] or [[]])
        angles = np.degrees(np.concatenate([e["orientation_errors"] for e in entries] or [[]]))
        latency = {
            stage: float(np.median([e["latency"][stage] for e in entries]))
            for stage in (*STAGES, "total", "cpu_total")
        }
        cpu = {stage: float(np.median([e["cpu"][stage] for e in entries])) for stage in STAGES}
        summary[name] = {
            "precision": matched / detections if detections else None,
            "recall_all": matched / sum(c["dominoes"] for _, c in counted),
            "recall_top": sum(e["matched_top"] for e in entries)
            / max(1, sum(c["top_unoccluded"] for _, c in counted)),
            "median_position_error_mm": _percentile(positions * 1000, 50),
            "p90_position_error_mm": _percentile(positions * 1000, 90),
            "median_orientation_error_deg": _percentile(angles, 50),
            "p90_orientation_error_deg": _percentile(angles, 90),
            "median_latency_s": latency,  # wall per stage, total wall and CPU
            "median_cpu_s": cpu,  # CPU per stage
            "max_total_latency_s": float(max(e["latency"]["total"] for e in entries)),
            # CPU time of the process: the wall time it would take without competing jobs
            "max_cpu_latency_s": float(max(e["latency"]["cpu_total"] for e in entries)),
        }
    both = [p["both"] for p in piles]
    summary["grasps"] = {
        "ours_first_success": _rate([e["ours_top"][:1] for e in both]),
        "flatness_first_success": _rate([e["flatness_top"][:1] for e in both]),
        f"ours_top{TOP_K}_success": _rate([e["ours_top"] for e in both]),
        f"flatness_top{TOP_K}_success": _rate([e["flatness_top"] for e in both]),
        "prediction": _confusion(both),
    }
    return summary


def _percentile(values: np.ndarray, q: float) -> float | None:
    return float(np.percentile(values, q)) if values.size else None


def _rate(lists: list[list[bool]]) -> float | None:
    values = [v for values in lists for v in values]
    return float(np.mean(values)) if values else None


def _confusion(entries: list[dict]) -> dict:
    predicted = np.array([v for e in entries for v in e["predicted"]], dtype=bool)
    actual = np.array([v for e in entries for v in e["actual"]], dtype=bool)
    return {
        "true_positive": int(np.sum(predicted & actual)),
        "false_positive": int(np.sum(predicted & ~actual)),
        "false_negative": int(np.sum(~predicted & actual)),
        "true_negative": int(np.sum(~predicted & ~actual)),
    }


def settled_pile(count: int, seed: int, cache: Path | None) -> dict[int, np.ndarray] | None:
    """Domino poses of the seeded pile (poured and settled once, then read from ``cache``).

    None when the simulator fails on this pile (reported, not fatal).
    """
    path = cache / f"pile_{count}_{seed}.npz" if cache else None
    if path is not None and path.is_file():
        stored = np.load(path)
        return dict(zip(stored["indices"].tolist(), stored["poses"], strict=True))
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=count))
    try:
        report = world.reset(domino_count=count, seed=seed)
    except RuntimeError as error:
        log(f"pile of {count}, seed {seed}: simulator failed ({error})")
        return None
    log(f"pile of {count}, seed {seed}: settled={report.settled} in {report.wall_time:.1f} s")
    poses = {t.index: t.X_WD for t in world.domino_truth() if t.in_use}
    if path is not None:
        path.parent.mkdir(parents=True, exist_ok=True)
        np.savez(path, indices=np.array(list(poses)), poses=np.array(list(poses.values())))
    return poses


def run_layouts(build_area: layouts.BuildArea) -> dict[str, list[np.ndarray]]:
    """The bring-up's default line, arc and S-curve (12 dominoes), as upright poses."""
    shapes = {
        "line": layouts.line((0.45, 0.0), np.radians(90.0), RUN_LENGTH),
        "arc": layouts.arc((0.0, 0.0), 0.6, np.radians(-2.0), RUN_LENGTH),
        "s_curve": layouts.s_curve((0.45, 0.0), np.radians(90.0), 0.45, 0.05, RUN_LENGTH),
    }
    runs = {}
    for name, placements in shapes.items():
        layouts.validate(placements, build_area)
        runs[name] = [upright_pose(p.x, p.y, p.heading).GetAsMatrix4() for p in placements]
    return runs


def shifted(target: np.ndarray, rng: np.random.Generator) -> np.ndarray:
    """Where a careful arm might leave it: half exact, half off by up to 5 mm and 6 degrees."""
    if rng.random() < 0.5:
        return target
    pose = target.copy()
    angle = rng.uniform(0.0, 2.0 * np.pi)
    pose[:2, 3] += rng.uniform(0.0, 0.005) * np.array([np.cos(angle), np.sin(angle)])
    yaw = np.radians(rng.uniform(-6.0, 6.0))
    turn = np.array([[np.cos(yaw), -np.sin(yaw), 0], [np.sin(yaw), np.cos(yaw), 0], [0, 0, 1]])
    pose[:3, :3] = turn @ pose[:3, :3]
    return pose


def tipped(target: np.ndarray, angle: float) -> np.ndarray:
    """The upright domino turned ``angle`` about its bottom edge, forwards (> 0, along its
    body z) or backwards: the simulator lets it fall from there."""
    forward = target[:3, 2]
    axis = np.cross([0.0, 0.0, 1.0], forward) * np.sign(angle)
    pivot = target[:3, 3] + np.sign(angle) * DOMINO_SIZE[2] / 2 * forward
    pivot[2] = 0.0
    turn = RotationMatrix(AngleAxis(abs(angle), axis)).matrix()
    pose = target.copy()
    pose[:3, :3] = turn @ target[:3, :3]
    pose[:3, 3] = pivot + turn @ (target[:3, 3] - pivot)
    return pose


def run_scene(kind: str, targets: list[np.ndarray], rng: np.random.Generator) -> dict:
    """Initial poses (by place) of a run being built, complete, or complete and struck."""
    count = len(targets) if kind != "building" else int(rng.integers(3, len(targets) + 1))
    poses = {i: shifted(targets[i], rng) for i in range(count) if rng.random() >= 0.1}
    last = count - 1
    if kind == "building" and last in poses and rng.random() < 0.5:
        poses[last] = tipped(targets[last], np.radians(rng.choice([-15.0, 15.0])))
    return {"expected": targets[:count], "poses": poses, "struck": kind == "struck"}


def settle_run(world: CellWorld, scene: dict) -> dict[int, np.ndarray]:
    """Put the run in the simulator, push the first domino over if struck, let it settle."""
    world.set_domino_poses(scene["poses"])
    if scene["struck"] and 0 in scene["poses"]:
        forward = scene["poses"][0][:3, 2]
        axis = np.cross([0.0, 0.0, 1.0], forward)
        lever = DOMINO_SIZE[2] / 2 * forward + np.array([0.0, 0.0, DOMINO_SIZE[0] / 2])
        world.kick_domino(0, SpatialVelocity(PUSH_SPIN * axis, PUSH_SPIN * np.cross(axis, lever)))
    world.advance(2.0)
    return {t.index: t.X_WD for t in world.domino_truth() if t.in_use}


def true_status(target: np.ndarray, pose: np.ndarray | None, config: PlacementConfig) -> int:
    """What stands at the place: the domino placed there, upright within the check's
    limits, near it (FALLEN), or gone (MISSING)."""
    if pose is None:
        return MISSING
    offset = float(np.hypot(*(pose[:2, 3] - target[:2, 3])))
    if offset <= config.search_radius and tilt_from_vertical(pose) <= config.max_tilt:
        return STANDING
    return FALLEN if offset <= config.search_radius + DOMINO_SIZE[0] / 2 else MISSING


def camera_sets(cameras: list[str]) -> dict[str, tuple[str, ...]]:
    """Each camera alone, then all of them in their order (the node's check)."""
    sets = {camera: (camera,) for camera in cameras}
    if len(cameras) > 1:
        sets[" + ".join(cameras)] = tuple(cameras)
    return sets


def evaluate_run(
    world: CellWorld,
    pipeline: PerceptionPipeline,
    scene: dict,
    cameras: list[str],
    offset: float,
) -> dict[str, list[dict]]:
    """Per camera set (``camera_sets``), one row per expected place: true and reported
    status, errors, check latency; the settled scene rendered once for all sets."""
    config = PlacementConfig()
    truth = settle_run(world, scene)
    views = views_of(world.render(cameras), offset)
    rows = {}
    for name, chosen in camera_sets(cameras).items():
        started = time.perf_counter()
        results = check_placements(
            scene["expected"], [v for v in views if v.name in chosen], pipeline, config
        )
        latency = time.perf_counter() - started
        rows[name] = [
            {**placement_row(target, truth.get(index), result, config), "latency": latency}
            for index, (target, result) in enumerate(zip(scene["expected"], results, strict=True))
        ]
    return rows


def placement_row(target: np.ndarray, pose: np.ndarray | None, result, config) -> dict:
    """True and reported status of a place, and the errors of the reported pose."""
    row = {"true": true_status(target, pose, config), "reported": result.status}
    if pose is not None:
        row["true_offset"] = float(np.hypot(*(pose[:2, 3] - target[:2, 3])))
        row["true_tilt"] = tilt_from_vertical(pose)
        row["position_error"] = float(np.hypot(*(result.measured[:2, 3] - pose[:2, 3])))
        row["reported_offset"], row["reported_tilt"] = result.position_error, result.tilt
        row["measured_pose"] = not np.array_equal(result.measured, target)
    return row


def summarise_placements(rows: list[dict]) -> dict:
    """Status confusion, accuracy, the errors of what was found standing or fallen, and
    how often the bring-up's acceptance (standing within 3 mm and 3 degrees) is right."""
    confusion = {STATUS_NAMES[t]: {STATUS_NAMES[r]: 0 for r in STATUS_NAMES} for t in STATUS_NAMES}
    for row in rows:
        confusion[STATUS_NAMES[row["true"]]][STATUS_NAMES[row["reported"]]] += 1
    standing = [r for r in rows if r["true"] == STANDING and r["reported"] == STANDING]
    fallen = [r for r in rows if r["true"] == FALLEN and r["reported"] == FALLEN]
    located = [r for r in fallen if r["measured_pose"]]
    accepted = np.array([_accepted(r, "reported_offset", "reported_tilt") for r in standing])
    within = np.array([_accepted(r, "true_offset", "true_tilt") for r in standing])
    return {
        "places": len(rows),
        "status_accuracy": float(np.mean([r["true"] == r["reported"] for r in rows])),
        "confusion_true_by_reported": confusion,
        "standing_position_error_mm": _spread([r["position_error"] * 1e3 for r in standing]),
        "standing_offset_error_mm": _spread(
            [abs(r["reported_offset"] - r["true_offset"]) * 1e3 for r in standing]
        ),
        "standing_tilt_error_deg": _spread(
            [np.degrees(abs(r["reported_tilt"] - r["true_tilt"])) for r in standing]
        ),
        "fallen_located": len(located),
        "fallen_position_error_mm": _spread([r["position_error"] * 1e3 for r in located]),
        "bringup_accepts": {
            "right": int(np.sum(accepted == within)),
            "accepted_but_outside": int(np.sum(accepted & ~within)),
            "refused_but_within": int(np.sum(~accepted & within)),
        },
        "median_latency_s": float(np.median([r["latency"] for r in rows])),
        "max_latency_s": float(max(r["latency"] for r in rows)),
    }


def wrong_calls(rows: list[dict]) -> dict:
    """The calls the bring-up acts on wrongly (a standing domino picked up again, a fallen
    one left), and the places without evidence."""
    return {
        "places": len(rows),
        "standing_called_fallen": sum(
            r["true"] == STANDING and r["reported"] == FALLEN for r in rows
        ),
        "standing_called_missing": sum(
            r["true"] == STANDING and r["reported"] == MISSING for r in rows
        ),
        "fallen_called_standing": sum(
            r["true"] == FALLEN and r["reported"] == STANDING for r in rows
        ),
        "not_seen": sum(r["reported"] == NOT_SEEN for r in rows),
    }


def _accepted(row: dict, offset: str, tilt: str) -> bool:
    return row[offset] <= BRINGUP_TOLERANCE[0] and row[tilt] <= BRINGUP_TOLERANCE[1]


def _spread(values: list[float]) -> dict | None:
    if not values:
        return None
    return {
        "median": float(np.median(values)),
        "p90": float(np.percentile(values, 90)),
        "max": float(max(values)),
    }


def placement_benchmark(seeds: list[int], cameras: list[str], offset: float) -> dict:
    """Every layout × seed: a run being built; seeds' first half also complete and struck;
    each checked by every camera set (``camera_sets``)."""
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=RUN_LENGTH))
    pipeline = build_pipeline(world.scenario)
    area = layouts.BuildArea(
        *world.scenario.build_x, *world.scenario.build_y, *world.scenario.build_reach
    )
    sets = camera_sets(cameras)
    rows = {name: {kind: [] for kind in KINDS} for name in sets}
    scenes = []
    for shape, (name, targets) in enumerate(run_layouts(area).items()):
        for seed in seeds:
            kinds = KINDS if seed <= len(seeds) // 2 else KINDS[:1]
            for kind in kinds:
                rng = np.random.default_rng([seed, shape, KINDS.index(kind)])
                scene = run_scene(kind, targets, rng)
                found = evaluate_run(world, pipeline, scene, cameras, offset)
                for cameras_name, found_rows in found.items():
                    rows[cameras_name][kind] += found_rows
                    log(f"  {name} seed {seed} {kind} {cameras_name}: " + _statuses(found_rows))
                places = len(next(iter(found.values())))
                scenes.append({"layout": name, "seed": seed, "kind": kind, "places": places})
    return {
        "scenes": scenes,
        "by_cameras": {
            name: {
                "summary": summarise_placements([r for k in KINDS for r in by_kind[k]]),
                "wrong_by_kind": {k: wrong_calls(by_kind[k]) for k in KINDS if by_kind[k]},
            }
            for name, by_kind in rows.items()
        },
    }


def _statuses(rows: list[dict]) -> str:
    return " ".join(f"{STATUS_NAMES[r['true']][0]}>{STATUS_NAMES[r['reported']][0]}" for r in rows)


def pile_benchmark(count: int, seeds: list[int], args: argparse.Namespace) -> dict:
    """Every seeded pile of ``count``: detections against the truth, three camera sets."""
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=count))
    piles, failed = [], []
    for seed in seeds:
        poses = settled_pile(count, seed, args.pile_cache)
        if poses is None:
            failed.append(seed)
            continue
        world.set_domino_poses(poses)
        figures = args.figures if count == 30 and not piles else None
        offset = args.principal_point_offset
        piles.append({"seed": seed, **evaluate_pile(world, offset, figures)})
        found = {k: piles[-1]["both"][k] for k in ("detections", "matched", "matched_top")}
        log(f"  N={count} seed {seed}: {json.dumps(found)}")
    return {
        "summary": summarise(piles) if piles else None,
        "simulator_failed_seeds": failed,
        "piles": [
            {k: v for k, v in p.items() if k in ("seed", "dominoes", "top_unoccluded")}
            for p in piles
        ],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="*", default=[10, 30, 60])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument(
        "--placement-seeds",
        type=int,
        nargs="*",
        default=[1, 2, 3, 4],
        help="run scenes per layout (none: skip the placement checks)",
    )
    parser.add_argument(
        "--placement-cameras",
        nargs="+",
        default=list(PerceptionParameters().placement_cameras),
        help="cameras of the placement checks, in order of preference (each alone and all)",
    )
    parser.add_argument("--figures", type=Path, default=None)
    parser.add_argument(
        "--principal-point-offset",
        type=float,
        default=0.0,
        help="px added to the published principal point (to measure a calibration error)",
    )
    parser.add_argument(
        "--pile-cache",
        type=Path,
        default=Path("out/perception_piles"),
        help="settled piles are stored here and reused (delete to pour again)",
    )
    args = parser.parse_args()
    report = {
        "counts": {},
        "seeds": args.seeds,
        "principal_point_offset_px": args.principal_point_offset,
        "load_average_start": os.getloadavg(),
    }
    for count in args.counts:
        report["counts"][str(count)] = pile_benchmark(count, args.seeds, args)
    if args.placement_seeds:
        report["placement"] = {
            "seeds": args.placement_seeds,
            "cameras": args.placement_cameras,
            **placement_benchmark(
                args.placement_seeds, args.placement_cameras, args.principal_point_offset
            ),
        }
    report["load_average_end"] = os.getloadavg()
    print(json.dumps(report, indent=1, default=float))


if __name__ == "__main__":
    main()

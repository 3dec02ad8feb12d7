"""Benchmark perception against the simulator's ground truth on seeded piles.

For each pile size (default 10, 30, 60) and seed, the simulator pours and settles a
pile, renders both cameras, and the pipeline runs three ways: both cameras, camera_0
alone, camera_1 alone. Reported: precision, recall (all dominoes in the pile region
and the top, unoccluded ones), median position and orientation errors, latency per
stage, and grasp success on the true scene for the top choices of our ranking and
of the paper's flatness-only ranking, plus predicted-vs-actual grasp success.

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
from pydrake.math import RigidTransform

from dombot_description.grasp import pick_grasps
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
from dombot_perception.pipeline import STAGES, PerceptionPipeline, build_pipeline
from dombot_sim.world import CellWorld, WorldConfig

CAMERA_SETS = {
    "both": ("camera_0", "camera_1"),
    "camera_0": ("camera_0",),
    "camera_1": ("camera_1",),
}
TOP_K = 3  # grasp choices per pile compared between rankings


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def views_of(frames: dict) -> list[CameraView]:
    return [CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC) for f in frames.values()]


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


def evaluate_pile(
    world: CellWorld, pipeline: PerceptionPipeline, config: EvaluationConfig, figures: Path | None
) -> dict:
    frames = {n: f for n, f in world.render().items() if n in CAMERA_SETS["both"]}
    views = views_of(frames)
    truths = truth_of(world)
    covered = covered_from_above(truths)
    visible = np.array(
        [max(visible_fraction(t, f.label, f.K, f.X_WC) for f in frames.values()) for t in truths]
    )
    top = ~covered & (visible >= config.min_visible)
    pile = {"dominoes": len(truths), "top_unoccluded": int(top.sum())}
    for name, cameras in CAMERA_SETS.items():
        chosen = [v for v in views if v.name in cameras]
        started, cpu_started = time.perf_counter(), time.process_time()
        result = pipeline.run(chosen)
        total, cpu = time.perf_counter() - started, time.process_time() - cpu_started
        matches = match_detections(result.detections, truths, config.max_match_distance)
        matched_truth = {m.truth for m in matches}
        entry = {
            "detections": len(result.detections),
            "matched": len(matches),
            "matched_top": int(sum(top[t] for t in matched_truth)),
            "position_errors": [m.position_error for m in matches],
            "orientation_errors": [m.orientation_error for m in matches],
            "latency": {**result.timings, "total": total, "cpu_total": cpu},
        }
        if name == "both":
            entry.update(grasp_outcomes(result.detections, matches, truths, pipeline, config))
            if figures is not None:
                write_figures(figures, views, result)
        pile[name] = entry
    return pile


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
    for name in CAMERA_SETS:
        entries = [p[name] for p in piles]
        detections = sum(e["detections"] for e in entries)
        matched = sum(e["matched"] for e in entries)
        positions = np.concatenate([e["position_errors"] for e in entries] or [[]])
        angles = np.degrees(np.concatenate([e["orientation_errors"] for e in entries] or [[]]))
        latency = {
            stage: float(np.median([e["latency"][stage] for e in entries]))
            for stage in (*STAGES, "total", "cpu_total")
        }
        summary[name] = {
            "precision": matched / detections if detections else None,
            "recall_all": matched / sum(p["dominoes"] for p in piles),
            "recall_top": sum(e["matched_top"] for e in entries)
            / max(1, sum(p["top_unoccluded"] for p in piles)),
            "median_position_error_mm": _percentile(positions * 1000, 50),
            "p90_position_error_mm": _percentile(positions * 1000, 90),
            "median_orientation_error_deg": _percentile(angles, 50),
            "p90_orientation_error_deg": _percentile(angles, 90),
            "median_latency_s": latency,
            "max_total_latency_s": float(max(e["latency"]["total"] for e in entries)),
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


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--counts", type=int, nargs="+", default=[10, 30, 60])
    parser.add_argument("--seeds", type=int, nargs="+", default=[1, 2, 3, 4, 5])
    parser.add_argument("--figures", type=Path, default=None)
    parser.add_argument(
        "--pile-cache",
        type=Path,
        default=Path("out/perception_piles"),
        help="settled piles are stored here and reused (delete to pour again)",
    )
    args = parser.parse_args()
    config = EvaluationConfig()
    report = {"counts": {}, "seeds": args.seeds, "load_average_start": os.getloadavg()}
    for count in args.counts:
        world = CellWorld(WorldConfig(cameras=True, domino_capacity=count))
        pipeline = build_pipeline(world.scenario)
        piles, failed = [], []
        for seed in args.seeds:
            poses = settled_pile(count, seed, args.pile_cache)
            if poses is None:
                failed.append(seed)
                continue
            world.set_domino_poses(poses)
            figures = args.figures if count == 30 and not piles else None
            piles.append({"seed": seed, **evaluate_pile(world, pipeline, config, figures)})
            log(
                f"  N={count} seed {seed}: "
                + json.dumps(
                    {k: piles[-1]["both"][k] for k in ("detections", "matched", "matched_top")}
                )
            )
        report["counts"][str(count)] = {
            "summary": summarise(piles) if piles else None,
            "simulator_failed_seeds": failed,
            "piles": [
                {k: v for k, v in p.items() if k in ("seed", "dominoes", "top_unoccluded")}
                for p in piles
            ],
        }
    report["load_average_end"] = os.getloadavg()
    print(json.dumps(report, indent=1, default=float))


if __name__ == "__main__":
    main()

"""Benchmark the arm job end to end: build runs from seeded piles and knock them down.

Runs ``ros2 run dombot_bringup bringup`` (real node processes over DDS, the simulator
paced to real time as for a user; on this 2-core machine it runs below that anyway) for
a 10-domino arc and a 20-domino S-curve over a set of seeds and prints one JSON object:
placement success per domino (first attempt and after retries), runs completed, full
topples, simulated and wall seconds per domino. Reports and pictures of every run go to
``--out`` (default out/bench_bringup).
"""

from __future__ import annotations

import argparse
import json
import os
import subprocess
import sys
import time
from pathlib import Path

import numpy as np
from ament_index_python.packages import get_package_prefix

CASES = {
    "arc10": ["--layout", "arc", "--count", "10", "--pile", "30"],
    "s_curve20": [
        "--layout",
        "s-curve",
        "--start",
        "0.50",
        "-0.07",
        "--heading",
        "90",
        "--length",
        "0.55",
        "--amplitude",
        "0.05",
        "--count",
        "20",
        "--pile",
        "40",
    ],
}
SEEDS = (1, 2, 3)


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def run_case(name: str, arguments: list[str], seed: int, out: Path) -> dict:
    folder = out / f"{name}_seed{seed}"
    bringup = Path(get_package_prefix("dombot_bringup")) / "lib" / "dombot_bringup" / "bringup"
    command = [
        str(bringup),
        "--out",
        str(folder),
        *arguments,
        "--seed",
        str(seed),
    ]  # at the user's real-time factor (1): unpaced, the idle simulator floods perception
    started = time.monotonic()
    result = subprocess.run(command, capture_output=True, text=True, timeout=3600)
    wall = time.monotonic() - started
    (out / f"{name}_seed{seed}.log").write_text(result.stdout + result.stderr)
    report_path = folder / "run_report.json"
    if not report_path.exists():
        log(f"{name} seed {seed}: no report (exit {result.returncode})")
        return {
            "case": name,
            "seed": seed,
            "exit": result.returncode,
            "completed": False,
            "wall_s": wall,
            "error": result.stderr[-500:],
        }
    report = json.loads(report_path.read_text())
    summary = report["summary"]
    log(f"{name} seed {seed}: {summary}")
    return {
        "case": name,
        "seed": seed,
        "exit": result.returncode,
        "completed": summary["placed"] == summary["dominoes"],
        "toppled": bool(summary["toppled_by_truth"]),
        "dominoes": summary["dominoes"],
        "placed": summary["placed"],
        "placed_first_attempt": summary["placed_first_attempt"],
        "retries": summary["retries"],
        "simulated_s_per_domino": summary["simulated_s_per_domino_mean"],
        "wall_s_per_domino": summary["wall_s_per_domino_mean"],
        "wall_s": wall,
    }


def aggregate(runs: list[dict]) -> dict:
    dominoes = sum(r.get("dominoes", 0) for r in runs)
    first = sum(r.get("placed_first_attempt", 0) for r in runs)
    placed = sum(r.get("placed", 0) for r in runs)
    completed = [r for r in runs if r["completed"]]
    per_domino = [r["simulated_s_per_domino"] for r in runs if r.get("simulated_s_per_domino")]
    return {
        "runs": len(runs),
        "placements_first_attempt_rate": first / dominoes if dominoes else None,
        "placements_rate": placed / dominoes if dominoes else None,
        "runs_completed_rate": len(completed) / len(runs),
        "completed_runs_toppled_rate": (
            sum(r["toppled"] for r in completed) / len(completed) if completed else None
        ),
        "simulated_s_per_domino_mean": float(np.mean(per_domino)) if per_domino else None,
        "simulated_s_per_domino_max": float(np.max(per_domino)) if per_domino else None,
        "wall_s_per_domino_mean": float(
            np.mean([r["wall_s_per_domino"] for r in runs if r.get("wall_s_per_domino")])
        )
        if per_domino
        else None,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/bench_bringup"))
    parser.add_argument("--cases", nargs="+", choices=sorted(CASES), default=sorted(CASES))
    parser.add_argument("--seeds", type=int, nargs="+", default=list(SEEDS))
    args = parser.parse_args()
    args.out.mkdir(parents=True, exist_ok=True)
    report = {
        "benchmark": "bringup",
        "load_average_at_start": os.getloadavg(),
        "cases": {},
    }
    for name in args.cases:
        runs = [run_case(name, CASES[name], seed, args.out) for seed in args.seeds]
        report["cases"][name] = {"arguments": CASES[name], "runs": runs, **aggregate(runs)}
    report["load_average_at_end"] = os.getloadavg()
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

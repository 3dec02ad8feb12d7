"""How fast the default job runs, and where its time goes: one bring-up, one JSON object.

Runs ``bringup`` (the default 10-domino arc from a pile of 30, with ``--seed``) and
prints its wall and simulated seconds and their ratio (the real-time factor reached),
the simulated seconds per placed domino split by activity (motion, perception,
planning, gripper, waiting, other: the run report's split), the wall seconds per
domino, and the CPU seconds each node process used (psutil, read off the process tree);
sim_node's CPU per simulated second over the whole job and while the arm moves (from
its "executing a T s trajectory" to its "trajectory done" lines, against the T's), and
how many picks were planned ahead (asked as the descent to the slot started, the
moment the pile look answered while the arm placed, or after the retreat, used or
dropped: ``task.ahead``), and the
planner's refusals by service and error code.
Compare two code versions by running this in both workspaces at the same time (the
machine's load then weighs on both alike) and taking ratios: docs/SPEED.md.

    ./dombot bench speed                       # seed 0, as fast as possible
    python benchmarks/bench_speed.py --seed 3 --real-time-factor 1 -- --count 4
"""

from __future__ import annotations

import argparse
import json
import os
import re
import subprocess
import sys
import time
from collections import Counter
from pathlib import Path

import psutil
from ament_index_python.packages import get_package_prefix

NODES = ("sim_node", "perception_node", "planner_node")
RUN_TIMEOUT = 3600.0  # s of wall time
TRAJECTORY_START = re.compile(r"\[sim_node\].*executing a ([0-9.]+) s trajectory")
TRAJECTORY_END = re.compile(r"\[sim_node\].*(trajectory done|follow_joint_trajectory \w+:)")
FRAMES = re.compile(r"\[sim_node\].*camera frames rendered: (.*)")
STILL = re.compile(r"\[sim_node\].*simulated [0-9.]+ s, of which the cell was still .* ([0-9.]+) s")
# the planner's refusals, requests planned ahead and pushes included
REFUSED = re.compile(r"\[planner_node\] \[WARN\].*(plan_place|plan_strike): ([A-Z_]+) at")
# perception's words for a look that found no usable frame of a camera
MISSED_FRAMES = re.compile(
    r"\[perception_node\] \[WARN\].*(stopped publishing|no colour and depth images)"
)


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(description=__doc__.split("\n\n")[0])
    parser.add_argument("--seed", type=int, default=0, help="pile seed (0)")
    parser.add_argument(
        "--real-time-factor", type=float, default=0.0, help="sim_node's (0: as fast as possible)"
    )
    parser.add_argument("--out", type=Path, default=Path("out/bench_speed"), help="report folder")
    parser.add_argument("bringup_args", nargs="*", help="more bringup options, after --")
    return parser.parse_args(argv)


class ProcessCpu:
    """CPU seconds of the bring-up's node processes, by node name (restarts summed)."""

    def __init__(self, root: int) -> None:
        self.root = psutil.Process(root)
        self.seen: dict[int, tuple[str, float]] = {}  # pid → (node, last CPU seconds)

    def sample(self) -> None:
        for child in self.root.children(recursive=True):
            try:
                name = next((n for n in NODES if n in " ".join(child.cmdline())), None)
                if name:
                    times = child.cpu_times()
                    self.seen[child.pid] = (name, times.user + times.system)
            except psutil.Error:  # it ended between the listing and the read
                continue

    def node(self, name: str) -> float:
        self.sample()
        return sum(cpu for node, cpu in self.seen.values() if node == name)

    def totals(self) -> dict[str, float]:
        return {
            name: round(sum(c for n, c in self.seen.values() if n == name), 1) for name in NODES
        }


def run(args: argparse.Namespace) -> dict:
    bringup = Path(get_package_prefix("dombot_bringup")) / "lib" / "dombot_bringup" / "bringup"
    command = [
        str(bringup),
        "--out",
        str(args.out),
        "--seed",
        str(args.seed),
        "--real-time-factor",
        str(args.real_time_factor),
        *args.bringup_args,
    ]
    args.out.mkdir(parents=True, exist_ok=True)
    load_before = os.getloadavg()[0]
    started = time.monotonic()
    moving_cpu = moving_sim = 0.0
    frames, missed, still = None, 0, None
    refused: Counter[str] = Counter()
    motion_start: tuple[float, float] | None = None  # (sim_node CPU, trajectory seconds)
    with (
        (args.out / "bringup.log").open("w") as log_file,
        subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        ) as process,
    ):
        cpu = ProcessCpu(process.pid)
        for line in process.stdout:
            log_file.write(line)
            if line.startswith("[bringup]"):
                print(line.rstrip(), file=sys.stderr, flush=True)
            missed += bool(MISSED_FRAMES.search(line))
            if refusal := REFUSED.search(line):
                refused[" ".join(refusal.groups())] += 1
            if rendered := FRAMES.search(line):
                frames = rendered.group(1)
            if skipped := STILL.search(line):
                still = float(skipped.group(1))
            if start := TRAJECTORY_START.search(line):
                motion_start = (cpu.node("sim_node"), float(start.group(1)))
            elif motion_start and TRAJECTORY_END.search(line):
                moving_cpu += cpu.node("sim_node") - motion_start[0]
                moving_sim += motion_start[1]
                motion_start = None
            else:
                cpu.sample()
            if time.monotonic() - started > RUN_TIMEOUT:
                process.kill()
    wall = time.monotonic() - started
    result = {
        "seed": args.seed,
        "real_time_factor_asked": args.real_time_factor,
        "bringup_args": args.bringup_args,
        "exit": process.returncode,
        "wall_s_process": round(wall, 1),
        "load_average_before_after": [round(load_before, 2), round(os.getloadavg()[0], 2)],
        "cpu_s_by_node": cpu.totals(),
        "camera_frames_rendered": frames,  # sim_node's last line; None: it did not say
        "sim_node_still_simulated_s": still,  # advanced without physics steps; None: not said
        "perception_missed_frames": missed,
        "planner_refusals": dict(refused.most_common()),  # "service CODE" → requests
    }
    return summarize(args, result, (moving_cpu, moving_sim))


def summarize(args, result: dict, moving: tuple[float, float]) -> dict:
    """``result`` with the run report's figures and sim_node's CPU per simulated second."""
    report_path = args.out / "run_report.json"
    if not report_path.exists():
        return result | {"error": "no run_report.json"}
    summary = json.loads(report_path.read_text())["summary"]
    simulated, job_wall = summary["simulated_s"], summary["wall_s"]
    moving_cpu, moving_sim = moving
    return result | {
        "placed": summary["placed"],
        "dominoes": summary["dominoes"],
        "placed_first_attempt": summary["placed_first_attempt"],
        "toppled": summary.get("toppled_by_truth"),
        "job_wall_s": round(job_wall, 1),
        "job_simulated_s": round(simulated, 1),
        "real_time_factor_reached": round(simulated / job_wall, 3) if job_wall else None,
        "simulated_s_per_domino": summary["simulated_s_per_domino_mean"],
        "wall_s_per_domino": summary["wall_s_per_domino_mean"],
        "simulated_s_per_domino_by_activity": summary["simulated_s_per_domino_by_activity"],
        "sim_node_cpu_s_per_simulated_s": (
            round(result["cpu_s_by_node"]["sim_node"] / simulated, 3) if simulated else None
        ),
        "sim_node_cpu_s_per_simulated_s_moving": (
            round(moving_cpu / moving_sim, 3) if moving_sim else None
        ),
        "arm_moving_simulated_s": round(moving_sim, 1),
        "planned_ahead": {
            key.removeprefix("planned_ahead_"): n
            for key, n in summary.items()
            if key.startswith("planned_ahead_")
        },
    }


def main(argv: list[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    result = run(args)
    print(json.dumps(result, indent=2))
    return 0 if result.get("exit") == 0 else 1


if __name__ == "__main__":
    sys.exit(main())

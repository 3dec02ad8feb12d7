"""Benchmark the arm job end to end: build runs from seeded piles and knock them down.

Runs ``ros2 run dombot_bringup bringup`` (real node processes over DDS, the simulator
as fast as it can go, ``--real-time-factor 0``; docs/SPEED.md) for a 10-domino arc and
a 20-domino S-curve (and, asked for, 30-domino circle, S-curve and spiral) over a set of
seeds and prints one JSON object: placement success per domino (first attempt and after
retries), runs completed, full topples, simulated and wall seconds per domino; for the
``--cycles`` case each cycle and each process's memory growth from the first cycle to
the last. Reports and pictures of every run go to
``--out`` (default out/bench_bringup); with ``--record-picks`` every pick's record too
(``<out>/<case>_seed<N>/picks/``, for benchmarks/replay_pick.py).

With ``--ledger FILE`` every finished run is appended to FILE (one JSON object a line,
with the commit it ran at) and a case and seed already in it with the same options is
not run again: a benchmark of many 30-domino runs (20-45 min each here) accumulates over
several sittings, and the figures aggregate all of them. ``--table`` prints the cases as
a Markdown table instead of JSON; ``--ledger-only`` runs nothing and reports the ledger's
runs of the cases (all its seeds unless ``--seeds`` names some): a partial series.
"""

from __future__ import annotations

import argparse
import json
import os
import shlex
import signal
import subprocess
import sys
import threading
import time
from pathlib import Path

import numpy as np
from ament_index_python.packages import get_package_prefix

from dombot_bringup.bringup import parse_args
from dombot_bringup.process_group import end_process
from dombot_bringup.sections import EXIT_REFUSED

CASES = {
    "arc10": ["--layout", "arc", "--count", "10", "--pile", "30"],
    # the perpetual cycle: the arc built, knocked down and built again from its own
    # dominoes and the pile, five times (issue 23: 5/5 cycles, RSS growing < 10 %)
    "arc10_cycles5": ["--layout", "arc", "--count", "10", "--pile", "30", "--cycles", "5"],
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
    # at scale (issue 23): 30 dominoes that fit the build area, from piles of 45-60; not
    # in the default list (a run takes 30-45 min here): --cases circle30 s_curve30 spiral30
    "circle30": shlex.split(
        "--layout circle --center 0.54 0.18 --radius 0.14 --count 30 --pile 45"
    ),
    "s_curve30": shlex.split(
        "--layout s-curve --start 0.46 -0.08 --heading 75 --length 0.6 --amplitude 0.08 "
        "--spacing 0.022 --count 30 --pile 60"
    ),
    "spiral30": shlex.split("--layout spiral --count 30 --pile 50"),
}
DEFAULT_CASES = ("arc10", "arc10_cycles5", "s_curve20")
SEEDS = (1, 2, 3)
CYCLE_TIMEOUT = 3600.0  # s of wall time per cycle (a --cycles run has as many) ...
WALL_PER_DOMINO = 240.0  # ... or per domino of a cycle, if more (30 dominoes: 7200 s)
# s a bring-up told to stop has for its nodes (SIGINT, SIGTERM, SIGKILL 5 s apart) before
# it is killed itself
STOP_GRACE = 60.0


def run_timeout(arguments: list[str]) -> float:
    """Wall time [s] a bring-up with ``arguments`` may take: per cycle (``--cycles`` as
    bringup reads it) CYCLE_TIMEOUT or WALL_PER_DOMINO a domino, whichever is more.
    arc10_cycles5 at load 9-18 took 770-1633 s a cycle; s_curve30 seed 2 at load ~11 was
    cut off at 21 of 30 placed by a limit of 3600 s."""
    options = parse_args(arguments)
    return max(CYCLE_TIMEOUT, WALL_PER_DOMINO * options.count) * options.cycles


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def run_logged(
    command: list[str], log_path: Path, name: str, timeout: float
) -> tuple[int, str, bool]:
    """Run the bring-up, its output into ``log_path`` and its own progress lines (not the
    nodes') onto stderr as they come; stopped after ``timeout`` s, or when the benchmark
    is interrupted (Ctrl-C, SIGTERM): SIGTERM, on which the bring-up stops its nodes, and
    SIGKILL STOP_GRACE s later. Exit code, last lines, and whether the limit stopped it."""
    lines: list[str] = []
    killed = threading.Event()

    def kill(process: subprocess.Popen) -> None:
        killed.set()
        end_process(process, STOP_GRACE)

    with (
        log_path.open("w") as log_file,
        subprocess.Popen(
            command, stdout=subprocess.PIPE, stderr=subprocess.STDOUT, text=True
        ) as process,
    ):
        watchdog = threading.Timer(timeout, kill, args=(process,))
        watchdog.start()
        try:
            for line in process.stdout:
                log_file.write(line)
                lines = [*lines[-19:], line]
                if line.startswith("[bringup]"):
                    log(f"{name}: {line.rstrip()}")
        except BaseException:  # not left running, nor its nodes
            end_process(process, STOP_GRACE)
            raise
        finally:
            watchdog.cancel()
    return process.returncode, "".join(lines), killed.is_set()


def run_case(
    name: str, arguments: list[str], seed: int, out: Path, record: bool, factor: float
) -> dict:
    """One bring-up of case ``name`` (``arguments``) with ``seed``: its figures, with
    what identifies it in a ledger (``ledger_key``) and the commit it ran at."""
    return {
        "case": name,
        "seed": seed,
        "arguments": arguments,
        "real_time_factor": factor,
        "commit": commit(),
        "date": time.strftime("%Y-%m-%d %H:%M", time.gmtime()),
        "load_average_at_start": os.getloadavg()[0],
        **bring_up(name, arguments, seed, out, record, factor),
    }


def bring_up(
    name: str, arguments: list[str], seed: int, out: Path, record: bool, factor: float
) -> dict:
    folder = out / f"{name}_seed{seed}"
    bringup = Path(get_package_prefix("dombot_bringup")) / "lib" / "dombot_bringup" / "bringup"
    command = [
        str(bringup),
        "--out",
        str(folder),
        *arguments,
        "--seed",
        str(seed),
        "--real-time-factor",
        str(factor),
        *(["--record-picks"] if record else []),
    ]
    report_path = folder / "run_report.json"
    report_path.unlink(missing_ok=True)  # an earlier run's, in the same --out
    started = time.monotonic()
    log_path, timeout = out / f"{name}_seed{seed}.log", run_timeout(arguments)
    exit_code, tail, timed_out = run_logged(command, log_path, f"{name} seed {seed}", timeout)
    wall = time.monotonic() - started
    if timed_out or not report_path.exists():
        log(f"{name} seed {seed}: no report (exit {exit_code})")
        return {
            "exit": exit_code,
            "completed": False,
            "timed_out": timed_out,
            "wall_s": wall,
            "error": tail,
        }
    report = json.loads(report_path.read_text())
    summary = report["summary"]
    log(f"{name} seed {seed}: {summary}")
    return {
        **cycles_of(report),
        "exit": exit_code,
        "completed": summary["placed"] == summary["dominoes"],
        "toppled": bool(summary["toppled_by_truth"]),
        "dominoes": summary["dominoes"],
        "placed": summary["placed"],
        "placed_first_attempt": summary["placed_first_attempt"],
        "placed_off_target": summary["placed_off_target"],
        "retries": summary["retries"],
        "corrected_in_hand": summary.get("corrected_in_hand", 0),
        "debris_swept": summary.get("debris_swept", 0),
        "set_aside": summary.get("set_aside", 0),
        "pile_spread": summary.get("pile_spread", 0),
        "put_back_on_pile": summary.get("put_back_on_pile", 0),
        "simulated_s_per_domino": summary["simulated_s_per_domino_mean"],
        "simulated_s_per_domino_by_activity": summary.get("simulated_s_per_domino_by_activity"),
        "wall_s_per_domino": summary["wall_s_per_domino_mean"],
        "wall_s": wall,
    }


def commit() -> str:
    """The workspace's commit, ``-dirty`` with uncommitted changes outside docs/ (the
    ledger there changes with every run and changes no run), for the ledger."""
    repo = str(Path(__file__).resolve().parent)
    head = subprocess.run(
        ["git", "-C", repo, "rev-parse", "--short", "HEAD"],
        capture_output=True,
        text=True,
        check=False,
    ).stdout.strip()
    code_changed = subprocess.run(
        ["git", "-C", repo, "diff", "--quiet", "HEAD", "--", ":/", ":(exclude,top)docs"],
        check=False,
    ).returncode
    return f"{head}-dirty" if head and code_changed else head or "unknown"


def ledger_key(run: dict) -> tuple:
    """What makes two runs the same measurement: case, seed, options, pacing."""
    return run["case"], run["seed"], tuple(run["arguments"]), run["real_time_factor"]


def read_ledger(path: Path | None) -> dict[tuple, dict]:
    """The ledger's runs by ``ledger_key`` (the latest of a key wins); none without one."""
    if path is None or not path.exists():
        return {}
    runs = [json.loads(line) for line in path.read_text().splitlines() if line.strip()]
    return {ledger_key(run): run for run in runs}


def markdown(report: dict) -> str:
    """The cases as a Markdown table: a row per run, then each case's summary."""
    rows = [
        "| case | seed | commit | placed | first attempt | toppled | exit | sim s / domino "
        "| wall s |",
        "| --- | --- | --- | --- | --- | --- | --- | --- | --- |",
    ]
    for name, case in report["cases"].items():
        for run in case["per_seed"]:
            placed = f"{run.get('placed', 0)} / {run.get('dominoes', '?')}"
            per_domino = run.get("simulated_s_per_domino")
            toppled = "yes" if run.get("toppled") else "no"
            rows.append(
                f"| {name} | {run['seed']} | {run['commit']} | {placed} "
                f"| {run.get('placed_first_attempt', '—')} | {toppled} "
                f"| {run['exit']} | {f'{per_domino:.1f}' if per_domino else '—'} "
                f"| {run['wall_s']:.0f} |"
            )
        first = case["placements_first_attempt_rate"]
        rows.append(
            f"| **{name}** | {case['runs']} runs | | fewest {case['placed_fewest']}; "
            f"all placed in {case['runs_completed_rate']:.0%} | "
            f"{f'{first:.1%}' if first is not None else '—'} "
            f"| {case['runs_toppled_rate']:.0%} | | | |"
        )
    return "\n".join(rows)


def cycles_of(report: dict) -> dict:
    """A ``--cycles`` run's cycles (placed, toppled, exit status, RSS per process) and
    how much each process's resident memory grew from the first cycle's end to the
    last's; nothing for a run of one cycle."""
    cycles = report.get("cycles", [])
    if len(cycles) < 2:
        return {}
    first, last = cycles[0]["rss_mb"], cycles[-1]["rss_mb"]
    growth = {name: last[name] / first[name] - 1.0 for name in first if name in last}
    return {
        "cycles": len(cycles),
        "cycles_full": sum(c["exit_status"] == 0 for c in cycles),
        "rss_growth": {name: round(g, 3) for name, g in growth.items()},
        "per_cycle": [
            {
                k: c[k]
                for k in (
                    "cycle",
                    "placed",
                    "dominoes",
                    "toppled_found",
                    "toppled_picked",
                    "toppled_by_perception",
                    "exit_status",
                    "simulated_s",
                    "wall_s",
                    "rss_mb",
                )
            }
            for c in cycles
        ],
    }


def aggregate(runs: list[dict]) -> dict:
    dominoes = sum(r.get("dominoes", 0) for r in runs)
    first = sum(r.get("placed_first_attempt", 0) for r in runs)
    placed = sum(r.get("placed", 0) for r in runs)
    completed = [r for r in runs if r["completed"]]
    per_domino = [r["simulated_s_per_domino"] for r in runs if r.get("simulated_s_per_domino")]
    cycled = [r for r in runs if r.get("cycles")]
    return {
        "runs": len(runs),
        "placements_first_attempt_rate": first / dominoes if dominoes else None,
        "placements_rate": placed / dominoes if dominoes else None,
        "placements_off_target": sum(r.get("placed_off_target", 0) for r in runs),
        "placements_corrected_in_hand": sum(r.get("corrected_in_hand", 0) for r in runs),
        "debris_swept": sum(r.get("debris_swept", 0) for r in runs),
        "set_aside": sum(r.get("set_aside", 0) for r in runs),
        "pile_spread": sum(r.get("pile_spread", 0) for r in runs),
        "put_back_on_pile": sum(r.get("put_back_on_pile", 0) for r in runs),
        "runs_completed_rate": len(completed) / len(runs),
        "placed_fewest": min((r.get("placed", 0) for r in runs), default=None),
        "runs_toppled_rate": sum(bool(r.get("toppled")) for r in runs) / len(runs),
        "completed_runs_toppled_rate": (
            sum(r["toppled"] for r in completed) / len(completed) if completed else None
        ),
        "simulated_s_per_domino_mean": float(np.mean(per_domino)) if per_domino else None,
        "simulated_s_per_domino_max": float(np.max(per_domino)) if per_domino else None,
        "cycles_full_rate": (
            sum(r["cycles_full"] for r in cycled) / sum(r["cycles"] for r in cycled)
            if cycled
            else None
        ),
        "rss_growth_max": (
            max(max(r["rss_growth"].values(), default=0.0) for r in cycled) if cycled else None
        ),
        "wall_s_per_domino_mean": float(
            np.mean([r["wall_s_per_domino"] for r in runs if r.get("wall_s_per_domino")])
        )
        if per_domino
        else None,
    }


def ledger_runs(ledger: dict[tuple, dict], case: tuple, seeds: list[int] | None) -> list[dict]:
    """The ledger's runs of ``case`` (name, arguments, pacing) by seed: of ``seeds``, or
    all its seeds when None."""
    name, arguments, factor = case
    runs = {
        run["seed"]: run
        for key, run in ledger.items()
        if key == (name, run["seed"], arguments, factor) and (seeds is None or run["seed"] in seeds)
    }
    return [runs[seed] for seed in sorted(runs)]


def case_report(arguments: list[str], runs: list[dict]) -> dict:
    """A case's entry in the report: its options, the commits its runs ran at, the
    aggregate figures and each run."""
    commits = sorted({run["commit"] for run in runs})
    return {"arguments": arguments, "commits": commits, **aggregate(runs), "per_seed": runs}


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--out", type=Path, default=Path("out/bench_bringup"))
    parser.add_argument("--cases", nargs="+", choices=sorted(CASES), default=list(DEFAULT_CASES))
    parser.add_argument(
        "--seeds", type=int, nargs="+", help=f"default {list(SEEDS)}; --ledger-only: all"
    )
    parser.add_argument("--record-picks", action="store_true", help="bringup --record-picks")
    parser.add_argument(
        "--real-time-factor", type=float, default=0.0, help="sim_node's (0: as fast as possible)"
    )
    parser.add_argument(
        "--options",
        default="",
        help="bringup options after each case's, which they override: e.g. a short cycles run, "
        "'--cycles 2 --count 4'",
    )
    parser.add_argument(
        "--ledger", type=Path, help="JSON lines: runs kept here, and not run again if in it"
    )
    parser.add_argument("--again", action="store_true", help="run cases in the ledger again")
    parser.add_argument("--table", action="store_true", help="print a Markdown table, not JSON")
    parser.add_argument(
        "--ledger-only", action="store_true", help="run nothing: report the ledger's runs"
    )
    args = parser.parse_args()
    # SIGTERM as Ctrl-C: the running bring-up is stopped (run_logged), not left behind
    signal.signal(signal.SIGTERM, signal.default_int_handler)
    if args.ledger_only and args.ledger is None:
        parser.error("--ledger-only needs --ledger")
    args.out.mkdir(parents=True, exist_ok=True)
    extra = shlex.split(args.options)
    report = {
        "benchmark": "bringup",
        "load_average_at_start": os.getloadavg(),
        "real_time_factor": args.real_time_factor,
        "cases": {},
    }
    ledger = read_ledger(args.ledger)
    for name in args.cases:
        arguments = [*CASES[name], *extra]
        if args.ledger_only:
            runs = ledger_runs(ledger, (name, tuple(arguments), args.real_time_factor), args.seeds)
            if runs:
                report["cases"][name] = case_report(arguments, runs)
            continue
        runs = []
        for seed in args.seeds or SEEDS:
            key = (name, seed, tuple(arguments), args.real_time_factor)
            if key in ledger and not args.again:
                at = ledger[key]["commit"]
                log(f"{name} seed {seed}: in the ledger (at {at}), not run again")
                runs.append(ledger[key])
                continue
            runs.append(
                run_case(name, arguments, seed, args.out, args.record_picks, args.real_time_factor)
            )
            if runs[-1].get("timed_out"):
                log(f"{name} seed {seed}: cut off by the wall-time limit: not kept in the ledger")
            elif runs[-1].get("exit") == EXIT_REFUSED:
                log(f"{name} seed {seed}: refused before it started: not kept in the ledger")
            elif args.ledger is not None:
                with args.ledger.open("a") as ledger_file:
                    ledger_file.write(json.dumps(runs[-1]) + "\n")
        report["cases"][name] = case_report(arguments, runs)
    report["load_average_at_end"] = os.getloadavg()
    print(markdown(report) if args.table else json.dumps(report, indent=2))


if __name__ == "__main__":
    try:
        main()
    except KeyboardInterrupt:
        print("bench_bringup: interrupted; the bring-up was stopped", file=sys.stderr)
        sys.exit(130)

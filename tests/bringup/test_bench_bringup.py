"""benchmarks/bench_bringup.py's limit on a run's wall time."""

from __future__ import annotations

import json
from pathlib import Path

from support.benchmarks import load_benchmark


def test_a_run_may_take_a_cycle_timeout_per_cycle() -> None:
    bench = load_benchmark("bench_bringup")
    limit = bench.CYCLE_TIMEOUT
    assert bench.run_timeout(bench.CASES["arc10"]) == limit
    assert bench.run_timeout(bench.CASES["arc10_cycles5"]) == 5 * limit
    # --options come after the case's and override them, as in bringup's own parser
    assert bench.run_timeout([*bench.CASES["arc10_cycles5"], "--cycles", "2"]) == 2 * limit
    # a cycle of many dominoes gets WALL_PER_DOMINO each
    assert bench.run_timeout(bench.CASES["circle30"]) == 30 * bench.WALL_PER_DOMINO > limit


def test_the_limit_says_whether_it_killed_the_run(tmp_path: Path) -> None:
    bench = load_benchmark("bench_bringup")
    _, _, timed_out = bench.run_logged(["sleep", "600"], tmp_path / "a.log", "slow", 0.2)
    assert timed_out
    code, tail, timed_out = bench.run_logged(
        ["echo", "[bringup] done"], tmp_path / "b.log", "quick", 60.0
    )
    assert (code, tail, timed_out) == (0, "[bringup] done\n", False)


def test_the_ledger_alone_reports_its_runs_of_a_case() -> None:
    bench = load_benchmark("bench_bringup")
    arguments = tuple(bench.CASES["circle30"])

    def run(case: str, seed: int, placed: int, options: tuple = arguments) -> dict:
        return {
            "case": case,
            "seed": seed,
            "arguments": list(options),
            "real_time_factor": 0.0,
            "commit": "abc1234",
            "placed": placed,
        }

    lines = [
        run("circle30", 2, 30),
        run("circle30", 0, 12),
        run("circle30", 0, 30),  # the same run again: the latest wins
        run("circle30", 1, 30, (*arguments, "--cycles", "2")),  # other options
        run("spiral30", 0, 30),
    ]
    ledger = {bench.ledger_key(line): line for line in lines}
    case = ("circle30", arguments, 0.0)
    assert [(r["seed"], r["placed"]) for r in bench.ledger_runs(ledger, case, None)] == [
        (0, 30),
        (2, 30),
    ]
    assert [r["seed"] for r in bench.ledger_runs(ledger, case, [2, 5])] == [2]


def test_a_run_refused_before_it_started_is_not_kept_in_the_ledger(
    tmp_path: Path, monkeypatch, capsys
) -> None:
    """bringup's exit 2 (bad options or environment, e.g. a ROS_DOMAIN_ID Fast DDS cannot
    open): nothing ran, so the ledger does not count it as a run that failed; a run that
    failed on its way (exit 1) is kept."""
    bench = load_benchmark("bench_bringup")
    ledger = tmp_path / "ledger.jsonl"
    for code in (2, 1):
        run = {"exit": code, "completed": False, "timed_out": False, "commit": "abc1234"}
        monkeypatch.setattr(bench, "run_case", lambda *args, run=run: dict(run))
        argv = ["bench_bringup.py", "--cases", "arc10", "--seeds", "4", "--again"]
        monkeypatch.setattr("sys.argv", [*argv, "--out", str(tmp_path), "--ledger", str(ledger)])
        bench.main()
    assert [json.loads(line)["exit"] for line in ledger.read_text().splitlines()] == [1]
    assert "refused before it started: not kept in the ledger" in capsys.readouterr().err

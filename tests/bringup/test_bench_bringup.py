"""benchmarks/bench_bringup.py's limit on a run's wall time."""

from __future__ import annotations

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

"""benchmarks/bench_bringup.py's limit on a run's wall time."""

from __future__ import annotations

import importlib.util
from pathlib import Path

BENCH = Path(__file__).parents[2] / "benchmarks" / "bench_bringup.py"


def bench_bringup():
    spec = importlib.util.spec_from_file_location("bench_bringup", BENCH)
    module = importlib.util.module_from_spec(spec)
    spec.loader.exec_module(module)
    return module


def test_a_run_may_take_a_cycle_timeout_per_cycle() -> None:
    bench = bench_bringup()
    limit = bench.CYCLE_TIMEOUT
    assert bench.run_timeout(bench.CASES["arc10"]) == limit
    assert bench.run_timeout(bench.CASES["arc10_cycles5"]) == 5 * limit
    # --options come after the case's and override them, as in bringup's own parser
    assert bench.run_timeout([*bench.CASES["arc10_cycles5"], "--cycles", "2"]) == 2 * limit
    # a cycle of many dominoes gets WALL_PER_DOMINO each
    assert bench.run_timeout(bench.CASES["circle30"]) == 30 * bench.WALL_PER_DOMINO > limit

"""sim_node's loop keeps simulated time to its real-time factor, and at factor 0 runs the
ticks in which the cell was still at real time."""

from __future__ import annotations

import pytest

from dombot_sim.pacing import MAX_LAG, Pacer

TICK = 0.01  # s simulated


def run_ticks(pacer: Pacer, ticks: int, cost: float, still: bool, start=(0.0, 0.0)):
    """Ticks that each take ``cost`` wall seconds of work, then the pacer's wait; the
    (wall, simulated) time at the end."""
    wall, simulated = start
    for _ in range(ticks):
        simulated += TICK
        wall += cost
        wall += pacer.delay(simulated, wall, still)
    return wall, simulated


@pytest.mark.parametrize("factor", [0.5, 1.0, 4.0])
def test_a_paced_loop_keeps_simulated_time_to_the_factor(factor: float) -> None:
    pacer = Pacer(factor)
    wall, simulated = run_ticks(pacer, 1000, cost=0.001, still=False)
    # the first tick anchors the pace: the rest run at it
    assert (simulated - TICK) / (wall - 0.001) == pytest.approx(factor)


def test_a_paced_loop_slower_than_the_factor_does_not_wait() -> None:
    pacer = Pacer(1.0)
    wall, _ = run_ticks(pacer, 50, cost=0.02, still=False)
    assert wall == pytest.approx(50 * 0.02)


def test_unpaced_moving_ticks_never_wait_and_still_ones_run_at_real_time() -> None:
    pacer = Pacer(0.0)
    wall, simulated = run_ticks(pacer, 100, cost=0.001, still=False)
    assert wall == pytest.approx(100 * 0.001)
    wall_still, simulated_still = run_ticks(pacer, 101, 0.001, still=True, start=(wall, simulated))
    # the first still tick anchors the pace, the next 100 take their simulated time
    assert wall_still - wall == pytest.approx(0.001 + 100 * TICK)
    wall_moving, _ = run_ticks(pacer, 10, 0.001, still=False, start=(wall_still, simulated_still))
    assert wall_moving - wall_still == pytest.approx(10 * 0.001)


def test_far_behind_the_pace_it_restarts_rather_than_races() -> None:
    pacer = Pacer(1.0)
    wall, simulated = run_ticks(pacer, 10, cost=0.001, still=False)
    wall += 5 * MAX_LAG  # e.g. a reset held the loop
    assert pacer.delay(simulated + TICK, wall, still=False) == 0.0
    # paced from there: the next tick waits for its own simulated time
    assert pacer.delay(simulated + 2 * TICK, wall + 0.001, still=False) == pytest.approx(
        TICK - 0.001
    )


def test_a_new_factor_counts_from_the_next_tick() -> None:
    pacer = Pacer(1.0)
    wall, simulated = run_ticks(pacer, 10, cost=0.001, still=False)
    pacer.factor = 2.0
    assert pacer.delay(simulated + TICK, wall + 0.001, still=False) == 0.0  # anchored here
    assert pacer.delay(simulated + 2 * TICK, wall + 0.002, still=False) == pytest.approx(
        TICK / 2.0 - 0.001
    )

"""van Leeuwen's toppling-wave model (dombot_sim.wave_model): mechanics it must obey."""

from __future__ import annotations

import math

import numpy as np
import pytest
from scipy.integrate import solve_ivp

from dombot_sim.wave_model import GRAVITY, Row, Train, wave

HEIGHT, THICKNESS = 0.048, 0.0075


def energy(train: Train, head: float, rate: float) -> float:
    """Kinetic + potential energy of the train per unit domino mass."""
    theta, slope = train.angles(head)
    centre = 0.5 * THICKNESS * np.sin(theta) + 0.5 * HEIGHT * np.cos(theta)
    return float(0.5 * train.inertia * np.sum((slope * rate) ** 2) + GRAVITY * np.sum(centre))


def test_without_friction_the_train_keeps_its_energy_between_collisions() -> None:
    train = Train(Row(HEIGHT, THICKNESS, 0.5 * HEIGHT, mu=0.0), size=6)
    solution = solve_ivp(
        lambda _t, y: [y[1], train.acceleration(y[0], y[1])],
        (0.0, 0.04),
        [0.0, 3.0],
        rtol=1e-10,
        atol=1e-12,
    )
    start = energy(train, 0.0, 3.0)
    end = energy(train, solution.y[0, -1], solution.y[1, -1])
    assert solution.y[0, -1] > 0.05  # the head moved
    assert end == pytest.approx(start, rel=1e-6)


@pytest.mark.parametrize("mu", [0.0, 0.4])
def test_a_collision_loses_energy(mu: float) -> None:
    row = Row(HEIGHT, THICKNESS, 0.6 * HEIGHT, mu=mu)
    train, grown = Train(row, size=4), Train(row, size=5)
    standing = GRAVITY * 0.5 * HEIGHT  # the domino about to be struck
    before = energy(train, row.hit_angle, 4.0) + standing
    grown_rate = train.collide(row.hit_angle, 4.0)
    after = energy(grown, 0.0, grown_rate)
    assert 0.0 < grown_rate < 4.0  # the train goes on, slower
    assert after < before
    assert after > energy(grown, 0.0, 0.0)  # and still moves


def test_friction_between_dominoes_slows_the_wave() -> None:
    speeds = [wave(Row(HEIGHT, THICKNESS, 0.5 * HEIGHT, mu), 3.0).speed for mu in (0.0, 0.2, 0.4)]
    assert speeds[0] > speeds[1] > speeds[2] > 0.0


def test_the_steady_speed_forgets_the_strike() -> None:
    row = Row(HEIGHT, THICKNESS, 0.6 * HEIGHT, mu=0.2)
    assert wave(row, 3.0).speed == pytest.approx(wave(row, 8.0).speed, rel=0.01)


def test_dominoes_crossing_the_threshold_come_in_order_before_they_are_struck_further() -> None:
    row = Row(HEIGHT, THICKNESS, 0.6 * HEIGHT, mu=0.4)
    result = wave(row, 3.0, dominoes=10)
    assert result.crossings.size == 10 and result.hits.size == 9
    assert np.all(np.diff(result.crossings) > 0.0)
    assert np.all(result.crossings[1:] > result.hits)  # struck first, then past 2°


@pytest.mark.parametrize("pitch", [0.005, 0.0075, 0.056])
def test_a_row_that_cannot_topple_is_refused(pitch: float) -> None:
    with pytest.raises(ValueError):
        Row(HEIGHT, THICKNESS, pitch)


def test_the_hit_angle_is_where_the_top_edge_reaches_the_next_back_face() -> None:
    row = Row(HEIGHT, THICKNESS, 0.5 * HEIGHT)
    assert HEIGHT * math.sin(row.hit_angle) == pytest.approx(0.5 * HEIGHT - THICKNESS)

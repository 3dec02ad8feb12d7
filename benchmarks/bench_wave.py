"""Benchmark the toppling wave: its steady speed in the simulator against van Leeuwen's model.

Straight runs of ``--count`` upright dominoes (the 48 × 24 × 7.5 mm set and a 44 × 22 × 7
mm one) at centre spacings d/ℓ = 0.2 … 0.9 of the height ℓ, in the simulator sim_node
runs (dombot_sim.world.CellWorld: its 1 ms step, contact model and sleeping unless told
otherwise). The first domino is set turning about its front bottom edge at 6 rad/s (the
physics tests' push): the bring-up's strike tilts it at 2.8 rad/s (push speed over push
height) but keeps pushing for 15 mm, which a spin at that rate alone does not, and at
d/ℓ ≤ 0.3 such a spin stalls on the second domino in the simulator and the model. Each
domino's time to pass a 2° tilt is recorded; the wave speed is the pitch over the slope
of a straight-line fit of those times over the middle half of the run. The model
(dombot_sim.wave_model: van Leeuwen, Am. J. Phys. 78, 721 (2010)) gets the same row, the
simulator's domino–domino friction and the same start; its steady speed does not depend
on the start (tests/sim/test_wave_model.py).

Prints one JSON object on stdout (progress on stderr); ``--figure`` also plots
v/√(gℓ) against d/ℓ. ``--quick``: 4 spacings of the 48 mm set, 20 dominoes.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
import time
from pathlib import Path

import numpy as np

from dombot_description import DOMINO_SIZE, tilt_from_vertical
from dombot_sim.physics_checks import PUSH_SPIN, push_over, stand_line, tilt_crossings
from dombot_sim.sleeping import SleepSettings
from dombot_sim.wave_model import GRAVITY, Row, wave
from dombot_sim.world import CellWorld, WorldConfig

SETS = {"48x24x7.5": DOMINO_SIZE, "44x22x7": (0.044, 0.022, 0.007)}
RATIOS = (0.2, 0.3, 0.4, 0.5, 0.6, 0.7, 0.8, 0.9)
QUICK_RATIOS = (0.3, 0.5, 0.7, 0.9)
THRESHOLD = math.radians(2.0)  # below every spacing's hit angle (2.3° at d/ℓ = 0.2)
MU_DOMINO = 0.4  # the simulator's domino–domino (dynamic) friction: domino.sdf
TARGET_RANGE = (0.3, 0.8)  # d/ℓ where the issue asks for 15 %
RUN_X = 0.65  # m: the run goes along +y through (RUN_X, 0), clear of the arm


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def fitted_speed(crossings: np.ndarray, pitch: float, first: int, last: int) -> float | None:
    """Pitch over the slope of crossing time against index, dominoes first … last - 1."""
    span = np.arange(first, last)
    if np.isnan(crossings[span]).any():
        return None
    slope = np.polyfit(span, crossings[span], 1)[0]
    return float(pitch / slope)


def simulate(world: CellWorld, count: int, ratio: float) -> dict:
    height = world.config.domino_size[0]
    pitch = ratio * height
    start = np.array([RUN_X, -(count - 1) * pitch / 2])
    direction = stand_line(world, count, pitch, start, math.pi / 2)
    edges = _pivot_edges(world, count)
    push_over(world, direction, PUSH_SPIN)
    began = time.perf_counter()
    crossings = tilt_crossings(world, count, THRESHOLD, limit=0.2 * count)
    world.advance(0.3)  # the last ones land
    tilts = [math.degrees(d) for d in _tilts(world, count)]
    fallen = int(np.sum(~np.isnan(crossings)))
    middle = slice(count // 4, count - count // 4)
    slip = ((_pivot_edges(world, count) - edges) @ direction)[middle]  # + forward
    return {
        "speed": fitted_speed(crossings, pitch, count // 4, count - count // 4),
        # at d/ℓ = 0.3 the wave takes ~15 dominoes to settle: the second half is steadier
        "speed_second_half": fitted_speed(crossings, pitch, count // 2, count),
        "passed_threshold": fallen,
        "all_fell": bool(min(tilts) > 45.0),
        "smallest_final_tilt_deg": round(min(tilts), 1),
        "pivot_slip_mm_median_max": [
            round(float(np.median(slip)) * 1e3, 2),
            round(float(slip[np.argmax(np.abs(slip))]) * 1e3, 2),
        ],
        "crossings": [None if math.isnan(t) else round(float(t), 4) for t in crossings],
        "wall_s": round(time.perf_counter() - began, 1),
    }


def _pivot_edges(world: CellWorld, count: int) -> np.ndarray:
    """Where each domino's front bottom edge (its pivot while it falls) is, world (count × 3);
    the model assumes it does not slip."""
    height, _, thickness = world.config.domino_size
    edge = np.array([-height / 2, 0.0, thickness / 2, 1.0])
    return np.array([(d.X_WD @ edge)[:3] for d in world.domino_truth()[:count]])


def _tilts(world: CellWorld, count: int) -> list[float]:
    return [tilt_from_vertical(d.X_WD) for d in world.domino_truth()[:count]]


def model_speed(size: tuple[float, float, float], ratio: float, mu: float) -> float | None:
    height, _, thickness = size
    try:
        return wave(Row(height, thickness, ratio * height, mu), PUSH_SPIN).speed
    except (RuntimeError, ValueError):
        return None  # no wave in the model at this spacing


def case(world: CellWorld, name: str, count: int, ratio: float) -> dict:
    size = world.config.domino_size
    scale = math.sqrt(GRAVITY * size[0])
    sim = simulate(world, count, ratio)
    model = {mu: model_speed(size, ratio, mu) for mu in (0.0, 0.2, MU_DOMINO)}
    row = {
        "set": name,
        "d_over_l": ratio,
        "sim_v": _round(sim["speed"]),
        "model_v": _round(model[MU_DOMINO]),
        "sim_v_over_sqrt_gl": _round(sim["speed"] and sim["speed"] / scale),
        "model_v_over_sqrt_gl": {str(mu): _round(v and v / scale) for mu, v in model.items()},
        "error_percent": None,
        "sim_v_second_half": _round(sim["speed_second_half"]),
        "error_percent_second_half": None,
        **{k: v for k, v in sim.items() if not k.startswith("speed")},
    }
    if sim["speed"] and model[MU_DOMINO]:
        row["error_percent"] = round(100.0 * (sim["speed"] / model[MU_DOMINO] - 1.0), 1)
    if sim["speed_second_half"] and model[MU_DOMINO]:
        error = 100.0 * (sim["speed_second_half"] / model[MU_DOMINO] - 1.0)
        row["error_percent_second_half"] = round(error, 1)
    log(
        f"{name} d/l={ratio:.2f}: sim {row['sim_v']} m/s, model {row['model_v']} m/s "
        f"({row['error_percent']} %), fell {sim['passed_threshold']}/{count}, "
        f"{sim['wall_s']} s wall"
    )
    return row


def _round(value: float | None) -> float | None:
    return None if value is None else round(float(value), 3)


def plot(rows: list[dict], path: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    figure, axes = plt.subplots(figsize=(7, 4.5))
    ratios = np.arange(0.25, 0.951, 0.05)
    for mu, style in ((0.0, ":"), (0.2, "--"), (MU_DOMINO, "-")):
        curve = [model_speed(DOMINO_SIZE, r, mu) for r in ratios]
        scaled = [np.nan if v is None else v / math.sqrt(GRAVITY * DOMINO_SIZE[0]) for v in curve]
        axes.plot(ratios, scaled, "k" + style, label=f"van Leeuwen model, μ = {mu}")
    for name, marker in zip(SETS, "os", strict=False):
        mine = [r for r in rows if r["set"] == name and r["sim_v_over_sqrt_gl"] is not None]
        axes.plot(
            [r["d_over_l"] for r in mine],
            [r["sim_v_over_sqrt_gl"] for r in mine],
            marker,
            label=f"Drake simulation, {name} mm",
        )
    axes.axvspan(*TARGET_RANGE, color="0.9", zorder=0, label="target range (±15 %)")
    axes.set_xlabel("centre spacing / height  d/ℓ")
    axes.set_ylabel("wave speed  v / √(gℓ)")
    axes.legend(fontsize=8)
    axes.grid(alpha=0.3)
    figure.tight_layout()
    figure.savefig(path, dpi=110)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.splitlines()[0])
    parser.add_argument("--quick", action="store_true")
    parser.add_argument("--count", type=int, help="dominoes per run (default 30, quick 20)")
    parser.add_argument("--sets", nargs="+", choices=sorted(SETS), help="domino sets")
    parser.add_argument("--ratios", type=float, nargs="+", help="spacings d/ℓ")
    parser.add_argument("--time-step", type=float, default=WorldConfig.time_step)
    parser.add_argument("--contact-model", default=WorldConfig.contact_model)
    parser.add_argument("--approximation", default=WorldConfig.contact_approximation)
    parser.add_argument("--no-sleeping", action="store_true")
    parser.add_argument("--figure", type=Path, help="write the plot here (PNG)")
    args = parser.parse_args()
    count = args.count or (20 if args.quick else 30)
    sets = args.sets or (["48x24x7.5"] if args.quick else list(SETS))
    ratios = args.ratios or (QUICK_RATIOS if args.quick else RATIOS)
    began, rows = time.perf_counter(), []
    for name in sets:
        world = CellWorld(
            WorldConfig(
                cameras=False,
                domino_capacity=count,
                domino_size=SETS[name],
                time_step=args.time_step,
                contact_model=args.contact_model,
                contact_approximation=args.approximation,
                sleep=SleepSettings(enabled=not args.no_sleeping),
            )
        )
        rows.extend(case(world, name, count, ratio) for ratio in ratios)
    in_range = [
        r
        for r in rows
        if TARGET_RANGE[0] <= r["d_over_l"] <= TARGET_RANGE[1] and r["error_percent"] is not None
    ]
    report = {
        "count": count,
        "time_step": args.time_step,
        "contact_model": args.contact_model,
        "approximation": args.approximation,
        "sleeping": not args.no_sleeping,
        "threshold_deg": math.degrees(THRESHOLD),
        "mu_domino_model": MU_DOMINO,
        "worst_error_percent_in_target_range": max(
            (abs(r["error_percent"]) for r in in_range), default=None
        ),
        "rows": rows,
        "wall_s": round(time.perf_counter() - began, 1),
    }
    if args.figure:
        plot(rows, args.figure)
    print(json.dumps(report, indent=1))


if __name__ == "__main__":
    main()

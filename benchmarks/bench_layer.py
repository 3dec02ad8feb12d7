"""Benchmark the domino-layer kinematics: accuracy, speed, and agreement with the simulation.

Prints one JSON object on stdout (progress on stderr). ``--figures DIR`` also
regenerates the figures of docs/LAYER.md into DIR.
"""

from __future__ import annotations

import argparse
import dataclasses
import json
import math
import sys
import time
from pathlib import Path

import numpy as np
from scipy.optimize import brentq

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import LayerKinematics, deposit_radius, forward, trolley_wheel_radius
from dombot_layer.plotting import write_doc_figures
from dombot_layer.vehicle_sim import SimulationResult
from dombot_layer.verification import drive_circle

SPEED = 0.1  # m/s
SETTLED = 1e-6  # rad: trolley angle this close to eq. (9) counts as past the transient
SIM_DISTANCE = 20.0  # m driven from straight per radius


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def benchmark_radii(kinematics: LayerKinematics) -> list[float]:
    """From each turn's minimum laying radius to 10 m."""
    radii = []
    for side, sign in (("left", 1.0), ("right", -1.0)):
        minimum = kinematics.minimum_laying_radius(side)
        radii += [sign * minimum * f for f in (1.0, 1.0001, 1.01, 1.5)]
        radii += [sign * r for r in (0.1, 0.3, 1.0, 3.0, 10.0)]
    return radii


def ik_accuracy(kinematics: LayerKinematics) -> dict:
    left_min = kinematics.minimum_laying_radius("left")
    right_min = kinematics.minimum_laying_radius("right")
    radii = np.concatenate(
        [np.geomspace(left_min, 1000.0, 500_000), -np.geomspace(right_min, 1000.0, 500_000)]
    )
    inverse = kinematics.midpoint_radii(radii)
    error = np.abs(deposit_radius(kinematics.geometry, inverse.midpoint_radius) - radii)
    return {
        "radii": int(radii.size),
        "domain_m": [-1000.0, -right_min, left_min, 1000.0],
        "all_valid": bool(inverse.valid.all()),
        "max_abs_error_m": float(error.max()),
        "max_rel_error": float((error / np.abs(radii)).max()),
        "max_diff_from_brentq_on_eqs_1_9_m": brentq_difference(kinematics),
    }


def brentq_difference(kinematics: LayerKinematics) -> float:
    """Largest |r_m| gap between the closed form and scipy's brentq on eqs (1)–(9)."""
    geometry = kinematics.geometry
    worst = 0.0
    for side, sign in (("left", 1.0), ("right", -1.0)):
        minimum = kinematics.minimum_laying_radius(side)
        branch_start = abs(kinematics.midpoint_radius(sign * minimum))
        for target in minimum * np.geomspace(1.0 + 1e-6, 1e4, 200):
            root = brentq(
                lambda r, t=target, s=sign: abs(deposit_radius(geometry, s * r)) - t,
                branch_start,
                target + 1.0,
                xtol=1e-15,
            )
            worst = max(worst, abs(root - abs(kinematics.midpoint_radius(sign * target))))
    return worst


def ik_speed(kinematics: LayerKinematics) -> dict:
    rng = np.random.default_rng(7)
    radii = rng.choice([-1.0, 1.0], 1_000_000) * np.exp(
        rng.uniform(np.log(0.1), np.log(100.0), 1_000_000)
    )
    kinematics.midpoint_radii(radii[:1000])  # warm-up
    runs = []
    for _ in range(5):
        start = time.perf_counter()
        kinematics.midpoint_radii(radii)
        runs.append(time.perf_counter() - start)
    singles = []
    for radius in radii[:20_000].tolist():
        start = time.perf_counter()
        kinematics.midpoint_radius(radius)
        singles.append(time.perf_counter() - start)
    return {
        "vectorized_radii": int(radii.size),
        "vectorized_radii_per_s": float(radii.size / np.median(runs)),
        "single_call_median_us": float(np.median(singles) * 1e6),
        "single_call_p95_us": float(np.percentile(singles, 95) * 1e6),
    }


def settling_distance(kinematics: LayerKinematics, radius: float, theta: float) -> float | None:
    """Drive distance for the trolley angle to fall from θ to SETTLED, linearised model.

    The error shrinks by exp(−R_w/d_tw) per radian the tractor turns; None when
    R_w = 0 (trolley wheel on O), where it never settles.
    """
    midpoint = kinematics.midpoint_radius(radius)
    rate = float(trolley_wheel_radius(kinematics.geometry, midpoint)) / kinematics.geometry.d_tw
    return math.log(theta / SETTLED) / rate * abs(midpoint) if rate > 0 else None


def settling_time(result: SimulationResult, signed_theta: float) -> float | None:
    """When the trolley angle last came within SETTLED of eq. (9); None if it never did."""
    unsettled = np.nonzero(np.abs(result.trolley_angle - signed_theta) > SETTLED)[0]
    if unsettled.size == 0:
        return 0.0
    return result.time[unsettled[-1] + 1] if unsettled[-1] + 1 < result.time.size else None


def simulation_case(kinematics: LayerKinematics, radius: float) -> dict:
    midpoint = kinematics.midpoint_radius(radius)
    theta = forward(kinematics.geometry, midpoint).theta
    _, steady = drive_circle(kinematics, radius, 3.0, SPEED, start_at_equilibrium=True)
    result, laid = drive_circle(kinematics, radius, SIM_DISTANCE, SPEED)
    settled_at = settling_time(result, math.copysign(theta, midpoint))
    after = result.deposit_times > (math.inf if settled_at is None else settled_at)
    settled = np.count_nonzero(after) >= 10
    return {
        "deposit_radius_m": radius,
        "steady_state_max_error_m": float(np.abs(steady - abs(radius)).max()),
        "from_straight_settled_after_m": float(settled_at * SPEED) if settled else None,
        "from_straight_max_error_after_settling_m": (
            float(np.abs(laid[after] - abs(radius)).max()) if settled else None
        ),
        "predicted_settling_distance_m": settling_distance(kinematics, radius, theta),
    }


def simulation_agreement(kinematics: LayerKinematics) -> dict:
    cases = []
    for radius in benchmark_radii(kinematics):
        cases.append(simulation_case(kinematics, radius))
        log(f"sim r_d={radius:+.6f} m: {cases[-1]}")
    settled = [c for c in cases if c["from_straight_settled_after_m"] is not None]
    return {
        "speed_m_per_s": SPEED,
        "from_straight_distance_m": SIM_DISTANCE,
        "settled_when_trolley_angle_within_rad": SETTLED,
        "cases": cases,
        "max_error_steady_state_m": max(c["steady_state_max_error_m"] for c in cases),
        "max_error_after_transient_m": max(
            c["from_straight_max_error_after_settling_m"] for c in settled
        ),
        "unsettled_radii_m": [c["deposit_radius_m"] for c in cases if c not in settled],
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--figures", type=Path, help="also write the docs figures into this folder")
    args = parser.parse_args()
    kinematics = LayerKinematics(VehicleGeometry())
    report = {
        "benchmark": "layer",
        "geometry": dataclasses.asdict(kinematics.geometry),
        "minimum_laying_radius_m": {
            side: kinematics.minimum_laying_radius(side) for side in ("left", "right")
        },
    }
    log("IK accuracy ...")
    report["ik_accuracy"] = ik_accuracy(kinematics)
    log("IK speed ...")
    report["ik_speed"] = ik_speed(kinematics)
    log("simulation ...")
    report["simulation"] = simulation_agreement(kinematics)
    if args.figures:
        log("figures ...")
        report["figures"] = [str(p) for p in write_doc_figures(kinematics, args.figures)]
    print(json.dumps(report, indent=2, allow_nan=False))


if __name__ == "__main__":
    main()

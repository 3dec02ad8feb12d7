"""Benchmark the domino-layer kinematics: accuracy, speed, and agreement with the simulation.

Prints one JSON object on stdout (progress on stderr). ``--figures DIR`` also
writes the geometry, r_d(r_m) and simulation figures used in docs/LAYER.md.
"""

from __future__ import annotations

import argparse
import json
import sys
import time
from pathlib import Path

import numpy as np

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import (
    LayerKinematics,
    deposit_radius,
)
from dombot_layer.plotting import plot_deposit_curve, plot_geometry, plot_simulation
from dombot_layer.vehicle_sim import circle_center
from dombot_layer.verification import drive_circle

SPEED = 0.1  # m/s


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def ik_accuracy(kinematics: LayerKinematics) -> dict:
    left_min = kinematics.minimum_laying_radius("left")
    right_min = kinematics.minimum_laying_radius("right")
    radii = np.concatenate(
        [np.geomspace(left_min, 1000.0, 500_000), -np.geomspace(right_min, 1000.0, 500_000)]
    )
    midpoint, valid = kinematics.midpoint_radii(radii)
    error = np.abs(deposit_radius(kinematics.geometry, midpoint) - radii)
    return {
        "radii": int(radii.size),
        "domain_m": [(-1000.0), float(-right_min), float(left_min), 1000.0],
        "all_valid": bool(valid.all()),
        "max_abs_error_m": float(error.max()),
        "max_abs_error_m_0.1_to_100": float(
            error[(np.abs(radii) >= 0.1) & (np.abs(radii) <= 100)].max()
        ),
    }


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
    for radius in radii[:2000]:
        start = time.perf_counter()
        kinematics.midpoint_radius(radius)
        singles.append(time.perf_counter() - start)
    return {
        "vectorized_radii_per_s": float(radii.size / np.median(runs)),
        "single_call_median_us": float(np.median(singles) * 1e6),
        "single_call_p95_us": float(np.percentile(singles, 95) * 1e6),
    }


def simulation_agreement(kinematics: LayerKinematics) -> dict:
    rows = []
    for side, sign in (("left", 1.0), ("right", -1.0)):
        minimum = kinematics.minimum_laying_radius(side)
        for radius in sign * np.array([minimum * 1.0001, minimum * 1.01, 0.1, 0.3, 1.0, 3.0, 10.0]):
            if abs(radius) < minimum:
                continue
            _, at_equilibrium = drive_circle(
                kinematics, radius, 3.0, SPEED, start_at_equilibrium=True
            )
            _, from_straight = drive_circle(kinematics, radius, 10.0, SPEED)
            settled = from_straight[len(from_straight) // 2 :]
            rows.append(
                {
                    "deposit_radius_m": float(radius),
                    "max_error_from_predicted_steady_state_m": float(
                        np.abs(at_equilibrium - abs(radius)).max()
                    ),
                    "max_error_after_transient_m": float(np.abs(settled - abs(radius)).max()),
                }
            )
            log(f"sim r_d={radius:+.4f} m: {rows[-1]}")
    return {
        "speed_m_per_s": SPEED,
        "cases": rows,
        "max_error_steady_state_m": max(r["max_error_from_predicted_steady_state_m"] for r in rows),
        "max_error_after_transient_m_for_radii_ge_0.1": max(
            r["max_error_after_transient_m"] for r in rows if abs(r["deposit_radius_m"]) >= 0.1
        ),
    }


def write_figures(kinematics: LayerKinematics, folder: Path) -> list[str]:
    result, _ = drive_circle(kinematics, 0.3, 3.0, SPEED)
    midpoint = kinematics.midpoint_radius(0.3)
    return [
        str(plot_geometry(kinematics.geometry, 0.25, folder / "layer_geometry.png")),
        str(plot_deposit_curve(kinematics, folder / "layer_deposit_radius.png")),
        str(plot_simulation(result, folder / "layer_sim.png", 0.3, circle_center(midpoint))),
    ]


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--figures", type=Path, help="also write the docs figures into this folder")
    args = parser.parse_args()
    geometry = VehicleGeometry()
    kinematics = LayerKinematics(geometry)
    log("IK accuracy ...")
    report = {
        "benchmark": "layer",
        "geometry": geometry.__dict__,
        "minimum_laying_radius_m": {
            "left": kinematics.minimum_laying_radius("left"),
            "right": kinematics.minimum_laying_radius("right"),
        },
        "ik_accuracy": ik_accuracy(kinematics),
    }
    log("IK speed ...")
    report["ik_speed"] = ik_speed(kinematics)
    log("simulation ...")
    report["simulation"] = simulation_agreement(kinematics)
    if args.figures:
        report["figures"] = write_figures(kinematics, args.figures)
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

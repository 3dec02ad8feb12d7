"""Benchmark the simulated cell: speed with and without cameras, render time, pile settling,
and the contact/time-step choices behind docs/SIM.md.

Prints one JSON object on stdout (progress on stderr). ``--quick`` skips the 60-domino
pile and the contact study.
"""

from __future__ import annotations

import argparse
import json
import os
import sys
import time

import numpy as np
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.trajectories import PiecewisePolynomial

from dombot_description import DOMINO_SIZE
from dombot_sim.physics_checks import grip_and_swing, stand_upright, topple_line
from dombot_sim.sleeping import SleepSettings
from dombot_sim.world import CellWorld, WorldConfig

SEED = 2026
CAMERA_RATE = 2.0  # Hz simulated
SWING = np.array([0.6, 0.3, 0.0, 0.3, 0.0, -0.3, 0.6])  # rad, an arm move over the cell


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


def arm_swing(world: CellWorld, duration: float) -> PiecewisePolynomial:
    """Home → home + SWING → home, so the arm moves during the whole measurement."""
    home = world.scenario.home_position
    times = [0.0, duration / 2, duration]
    knots = np.column_stack([home, home + SWING, home])
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        times, knots, np.zeros(7), np.zeros(7)
    )


def real_time_factor(world: CellWorld, seconds: float, cameras: bool, arm_moving: bool) -> dict:
    """Simulated seconds per wall second over ``seconds`` of simulation."""
    if arm_moving:
        world.follow_trajectory(arm_swing(world, seconds))
    renders, render_wall, tracking = 0, 0.0, 0.0
    start, wall = world.time, time.perf_counter()
    next_frame = start
    while world.time < start + seconds - 1e-9:
        world.advance(0.01)
        desired = world.desired_arm_state()[0]
        tracking = max(tracking, float(np.abs(world.joint_state().position[:7] - desired).max()))
        if cameras and world.time >= next_frame:
            before = time.perf_counter()
            world.render(labels=False)  # what sim_node publishes
            render_wall += time.perf_counter() - before
            renders += 1
            next_frame += 1.0 / CAMERA_RATE
    elapsed = time.perf_counter() - wall
    world.hold_arm(world.scenario.home_position)
    return {
        "simulated_s": seconds,
        "wall_s": elapsed,
        "real_time_factor": seconds / elapsed,
        "camera_frame_sets": renders,
        "render_wall_s": render_wall,
        "max_tracking_error_rad": tracking,
    }


def render_time(world: CellWorld, labels: bool, repeats: int = 10) -> dict:
    """Median render time per camera while the arm moves (a new scene every frame)."""
    world.render(labels=labels)  # the first render builds VTK's pipelines
    world.follow_trajectory(arm_swing(world, 0.02 * repeats))
    per_set = []
    for _ in range(repeats):
        world.advance(0.02)  # an unchanged context would return the cached images
        before = time.perf_counter()
        world.render(labels=labels)
        per_set.append(time.perf_counter() - before)
    world.advance(0.5)
    cameras = len(world.camera_names)
    return {
        "cameras": cameras,
        "per_camera_ms_median": 1e3 * float(np.median(per_set)) / cameras,
        "images_per_camera": ["rgb8 640x480", "depth 32FC1"] + (["label"] if labels else []),
    }


def pile_case(count: int) -> dict:
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=count))
    report = world.reset(count, SEED)
    depth, where = world.deepest_penetration()
    log(
        f"pile {count}: settled={report.settled} in {report.settle_time:.2f} s sim, "
        f"{report.wall_time:.1f} s wall; deepest overlap {depth * 1e3:.3f} mm"
    )
    case = {
        "dominoes": count,
        "settled": report.settled,
        "settle_time_simulated_s": report.settle_time,
        "settle_wall_s": report.wall_time,
        "deepest_overlap_mm": depth * 1e3,
        "deepest_overlap_pair": where,
    }
    if count == 30:
        case["render_with_labels"] = render_time(world, labels=True)
        case["render_colour_depth"] = render_time(world, labels=False)
        case["rtf_idle_no_cameras"] = real_time_factor(world, 5.0, cameras=False, arm_moving=False)
        case["rtf_arm_moving_no_cameras"] = real_time_factor(world, 5.0, False, True)
        case["rtf_arm_moving_cameras_2hz"] = real_time_factor(world, 5.0, True, True)
        case["sleeping"] = sleeping_saves(world)
        factor = case["rtf_arm_moving_cameras_2hz"]["real_time_factor"]
        log(f"real-time factor with cameras at 2 Hz: {factor:.2f}")
    return case


def flat_domino_rocking(contact_model: str, time_step: float, approximation: str) -> dict:
    """A flat domino dropped 5 mm onto the table with sleeping off: does it come to rest?"""
    config = WorldConfig(
        cameras=False,
        domino_capacity=1,
        contact_model=contact_model,
        time_step=time_step,
        contact_approximation=approximation,
        sleep=SleepSettings(enabled=False),
    )
    world = CellWorld(config)
    pose = RigidTransform(
        RotationMatrix.MakeZRotation(0.4), [0.55, -0.3, DOMINO_SIZE[2] / 2 + 0.005]
    )
    world.set_domino_poses({0: pose})
    world.advance(1.0)
    speeds = []
    wall = time.perf_counter()
    for _ in range(100):
        world.advance(0.01)
        speeds.append(np.linalg.norm(world.domino_truth()[0].velocity[:3]))
    return {
        "contact_model": contact_model,
        "time_step_s": time_step,
        "approximation": approximation,
        "max_angular_speed_after_1s_rad_s": float(max(speeds)),
        "wall_per_simulated_s": time.perf_counter() - wall,
    }


def sleeping_saves(world: CellWorld) -> dict:
    """Wall time per simulated second of the settled pile asleep, then with sleeping off."""
    asleep = time.perf_counter()
    world.advance(1.0)
    asleep = time.perf_counter() - asleep
    world.set_sleeping(False)
    awake = time.perf_counter()
    world.advance(1.0)
    awake = time.perf_counter() - awake
    world.set_sleeping(True)
    return {"asleep_wall_per_simulated_s": asleep, "awake_wall_per_simulated_s": awake}


def physics() -> dict:
    """The experiments of tests/sim/test_physics.py, with their numbers."""
    standing = stand_upright(CellWorld(WorldConfig(cameras=False, domino_capacity=1)), 10.0)
    awake = CellWorld(
        WorldConfig(cameras=False, domino_capacity=1, sleep=SleepSettings(enabled=False))
    )
    standing_awake = stand_upright(awake, 10.0)
    tilts = topple_line(CellWorld(WorldConfig(cameras=False, domino_capacity=10)), 10, 0.6)
    swing = grip_and_swing(CellWorld(WorldConfig(cameras=False, domino_capacity=1)))
    return {
        "upright_10s_drift_mm": standing.drift * 1e3,
        "upright_10s_tilt_deg": float(np.degrees(standing.tilt)),
        "upright_10s_drift_mm_sleeping_off": standing_awake.drift * 1e3,
        "line_of_10_at_60pct_min_tilt_after_push_deg": float(np.degrees(tilts.min())),
        "grip_opening_mm": swing.opening * 1e3,
        "grip_swing_peak_tcp_speed_m_s": swing.peak_tcp_speed,
        "grip_swing_slip_mm": swing.slip * 1e3,
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__)
    parser.add_argument("--quick", action="store_true", help="skip N = 60 and the contact study")
    args = parser.parse_args()
    report = {
        "benchmark": "sim",
        "seed": SEED,
        "cpu_count": os.cpu_count(),
        "load_average_at_start": os.getloadavg(),
        "config": {
            "time_step_s": WorldConfig().time_step,
            "contact_approximation": WorldConfig().contact_approximation,
            "contact_model": WorldConfig().contact_model,
        },
        "piles": [pile_case(n) for n in ((10, 30) if args.quick else (10, 30, 60))],
    }
    log("physics checks ...")
    report["physics"] = physics()
    if not args.quick:
        log("contact study ...")
        report["flat_domino_at_rest"] = [
            flat_domino_rocking("point", 0.002, "similar"),
            flat_domino_rocking("point", 0.001, "lagged"),
            flat_domino_rocking("hydroelastic", 0.002, "similar"),
            flat_domino_rocking("hydroelastic", 0.001, "lagged"),
        ]
    report["load_average_at_end"] = os.getloadavg()
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

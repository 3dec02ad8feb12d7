"""A physics step must not map and fault in fresh pages: sim_node fixes glibc's mmap
threshold (dombot_description.allocator), and at 128 KiB every step's dense matrices of
the plant were mapped on their own (~80 page faults a 1 ms step, +60 % CPU on a swing)."""

from __future__ import annotations

import json
import subprocess
import sys

import pytest

# Steps the arm through a swing in the world sim_node builds (capacity 30, cameras on:
# without the render scene built the 128 KiB threshold showed no faults) in a fresh
# interpreter (mallopt changes the whole process), counting minor page faults per step
# with the sim's threshold and, for the failure message, with tune_allocator's 128 KiB.
SCRIPT = """
import json, resource
import numpy as np
from pydrake.trajectories import PiecewisePolynomial
from dombot_description.allocator import MMAP_THRESHOLD, set_mmap_threshold, tune_allocator
from dombot_sim.world import CellWorld, WorldConfig

tune_allocator()
world = CellWorld(WorldConfig(cameras=True, domino_capacity=30))
home = world.scenario.home_position
swing = PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
    [0.0, 0.6], np.column_stack([home, home + 0.3]), np.zeros(7), np.zeros(7))

def faults_per_step(threshold):
    set_mmap_threshold(threshold)
    world.advance(0.05)  # the allocator reaches its working size
    before = resource.getrusage(resource.RUSAGE_SELF).ru_minflt
    world.advance(0.3)
    return (resource.getrusage(resource.RUSAGE_SELF).ru_minflt - before) / 300

world.follow_trajectory(swing)
print(json.dumps({
    "size": world.step_block_size,
    "velocities": 9 + 6 * 30,
    "sim": faults_per_step(world.step_block_size),
    "glibc_fixed": faults_per_step(MMAP_THRESHOLD),
}))
"""


@pytest.mark.timeout(600)
def test_a_step_of_sim_nodes_plant_faults_in_no_fresh_pages() -> None:
    done = subprocess.run(
        [sys.executable, "-c", SCRIPT], capture_output=True, text=True, check=True
    )
    result = json.loads(done.stdout.strip().splitlines()[-1])
    assert result["size"] >= max(1 << 20, 16 * result["velocities"] ** 2)
    assert result["sim"] < 5.0, result  # a few per step at most: the heap serves them

"""sim_node's parameters and what makes a set of them wrong: a user's YAML file and the
tests check them without starting a node."""

from __future__ import annotations

import math
from dataclasses import dataclass

from dombot_adapters.parameters import described
from dombot_sim.world_config import CONTACT_APPROXIMATIONS

MAX_DOMINOES = 200
RATES = ("joint_state_rate", "camera_rate", "ground_truth_rate", "tf_rate", "domino_tf_rate")


@dataclass(frozen=True)
class SimParameters:
    """sim_node's parameters (RESTART_PARAMETERS are read at start-up only)."""

    scenario: str = described("", "scenario file; empty: dombot_description's default")
    domino_count: int = described(30, f"dominoes poured into the pile, 0..{MAX_DOMINOES}")
    seed: int = described(0, "seed of the pile pour (>= 0)")
    time_step: float = described(0.001, "physics time step [s], (0, 0.01]")
    contact_approximation: str = described("similar", "Drake's contact approximation")
    real_time_factor: float = described(1.0, "simulated per wall second; 0: as fast as it can")
    joint_state_rate: float = described(100.0, "/joint_states rate [Hz]: the simulation tick")
    camera_rate: float = described(2.0, "camera image rate [Hz]; 0: none")
    ground_truth_rate: float = described(2.0, "/sim/domino_ground_truth rate [Hz]; 0: none")
    tf_rate: float = described(100.0, "/tf rate of the robot links [Hz], at most one per tick")
    domino_tf_rate: float = described(2.0, "/tf rate of the domino_N frames [Hz]; 0: none")
    cameras: bool = described(True, "render the cameras")
    meshcat: bool = described(False, "serve Meshcat")
    meshcat_recording_path: str = described(
        "", "with meshcat: record what Meshcat shows, written here as HTML on shutdown"
    )
    sleeping: bool = described(True, "dominoes at rest sleep (docs/SIM.md)")
    skip_still: bool = described(
        True, "while nothing moves, advance the clock without physics steps (docs/SIM.md)"
    )
    log_moved_mm: float = described(
        1.0, "log the dominoes that moved this far [mm] during a goal; 0: no log"
    )

    def __post_init__(self) -> None:
        problems = parameter_problems(self)
        if problems:
            raise ValueError("; ".join(problems))


def parameter_problems(values: SimParameters) -> list[str]:
    """What is wrong with ``values``, one phrase each (none: they are good)."""
    problems = []
    for name in RATES:
        rate = getattr(values, name)
        if not (rate >= 0.0 and math.isfinite(rate)):
            problems.append(f"{name} must be a finite rate >= 0 Hz, got {rate}")
    if not values.joint_state_rate > 0.0:
        problems.append("joint_state_rate must be > 0 Hz (it is the simulation tick)")
    if not values.real_time_factor >= 0.0:
        problems.append(
            f"real_time_factor must be >= 0 (0: as fast as possible), got {values.real_time_factor}"
        )
    if not 0.0 < values.time_step <= 0.01:
        problems.append(f"time_step must be in (0, 0.01] s, got {values.time_step}")
    if values.contact_approximation not in CONTACT_APPROXIMATIONS:
        problems.append(
            f"contact_approximation must be one of {sorted(CONTACT_APPROXIMATIONS)}, "
            f"got {values.contact_approximation!r}"
        )
    if not 0.0 <= values.log_moved_mm < math.inf:
        problems.append(f"log_moved_mm must be a finite distance >= 0, got {values.log_moved_mm}")
    if values.meshcat_recording_path and not values.meshcat:
        problems.append("meshcat_recording_path needs meshcat:=true")
    if not 0 <= values.domino_count <= MAX_DOMINOES:
        problems.append(f"domino_count must be 0..{MAX_DOMINOES}, got {values.domino_count}")
    if values.seed < 0:
        problems.append(f"seed must be >= 0, got {values.seed}")
    return problems

"""Planner parameters (the node exposes each as a ROS parameter of the same name)."""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

# m: the canonical TCP is this far from the end of the domino the pads hold
MAX_GRASP_SHIFT = 0.005
ARM_JOINTS = 7
# The ``time`` function each budget clock reads (motion.Deadline).
BUDGET_CLOCKS = {"wall": "monotonic", "cpu": "thread_time"}


@dataclass(frozen=True)
class PlannerSettings:
    # Final approach and retreat: straight vertical lines solved by IK at close waypoints.
    pick_approach_distance: float = 0.06  # m above the grasp where the coarse move ends
    place_approach_distance: float = 0.07  # m above the placement (clears 48 mm neighbours)
    waypoint_spacing: float = 0.005  # m between IK waypoints on the lines
    release_height: float = 0.0002  # m the domino is let go above its place pose
    approach_speed: float = 0.3  # m/s TCP speed limit on the lines (docs/PLANNER.md, Timing)
    # Clearances [m]: coarse moves keep everything this far from table and dominoes ...
    coarse_clearance: float = 0.005
    # ... and the optimizer enforces this much more at its samples (covers the gaps).
    coarse_margin: float = 0.006
    # Within the lines only pads and the held domino come closer: pads to the table,
    # pads and held domino to standing dominoes.
    pad_table_clearance: float = 0.0005
    fine_obstacle_clearance: float = 0.002
    # Pile dominoes (perceived, ±2 mm) on the final approach, at the grasp and on the lift:
    # the pads keep pile_clearance from them when a grasp allows it, else may reach up to
    # pile_nudge into one (pushing it aside, as a builder's fingers do; 0: never); gripper
    # body and arm always keep pile_arm_clearance (a bump there stops the arm short of the
    # grasp). The picked domino may touch them.
    pile_clearance: float = 0.003
    pile_nudge: float = 0.004
    pile_arm_clearance: float = 0.006
    # Seen points on no detected domino (PlanPlace's pile_points: one on its edge, or mostly
    # hidden): the pads' path, down the approach and closing, keeps this far from them.
    pile_point_clearance: float = 0.0015
    self_clearance: float = 0.001  # robot against itself, everywhere
    # Kinematic trajectory optimization.
    kto_control_points: int = 10
    kto_collision_samples: int = 16
    kto_attempts: int = 4
    # m a coarse move's TCP may rise above the higher of its ends. Moves between IK
    # branches (joint 3 turned over at one end only) swung it 0.4-0.7 m higher and threw a
    # held domino onto the run (decision 0015); the raised via rises 0.15 m.
    max_coarse_rise: float = 0.25
    ik_random_seeds: int = 6
    # Retiming.
    velocity_scale: float = 1.0  # of the URDF joint velocity limits
    # rad/s², every joint (not in the URDF): the LBR iiwa 14's measured limits are 8.57
    # (joints 1, 2), 8.74 (3), 11.36 (4), 12.23 (5), 15.72 (6, 7) (Drake's iiwa models).
    acceleration_limit: float = 8.5
    # rad/s², per joint, on moves with no domino in the hand (the coarse move and the line
    # down to a grasp, the retreat after the let-go): those limits rounded down. Moves
    # holding a domino keep acceleration_limit: with these on the carry too, two held
    # dominoes of an S-curve run turned ~7° in the hand and were placed edge-on.
    free_acceleration_limits: tuple[float, ...] = (8.5, 8.5, 8.5, 11.3, 12.2, 15.7, 15.7)
    retreat_speed: float = 0.6  # m/s TCP limit on the retreat line after the let-go
    sample_period: float = 0.01  # s between published trajectory points
    # Gripper: the close command aims at a fully closed gripper, so its force limit (not a
    # position) sets the squeeze, as a WSG grasp command does.
    grip_force: float = 40.0  # N
    # Strike (/plan_strike): the closed fingers push the first domino of a run along its
    # body z (the direction it topples) with their tips at strike_height × its height;
    # where the pads start and a sweep's height are dombot_description.pusher's.
    strike_height: float = 0.75  # of the domino's height, where the fingertips push
    strike_approach_height: float = 0.05  # m of the vertical line down to the strike pose
    push_distance: float = 0.015  # m the fingertips travel past the back face (request: 0)
    push_speed: float = 0.1  # m/s of the fingertips during the push (request: 0)
    # Requests.
    default_time_budget: float = 5.0  # s when the request says 0
    # The clock a request's budget runs on (BUDGET_CLOCKS): "wall" for a robot that waits
    # for the answer; "cpu", the planning thread's CPU time, for the same search and so the
    # same answer however loaded the machine (the bring-up's: a refusal is remembered).
    budget_clock: str = "wall"
    # s an empty start state waits for /joint_states to show the arm at rest: right after a
    # motion the latest one may be from before it stopped (tens of mrad off); then as it is
    start_rest_wait: float = 5.0
    workspace_reach: tuple[float, float] = (0.25, 0.85)  # m from the arm base axis
    workspace_height: tuple[float, float] = (-0.005, 0.35)  # m, domino centres
    seed: int = 0  # random IK seeds and KTO restarts
    allow_regrasp: bool = True  # turn a domino no tilted grasp reaches, then pick it again
    # When no canonical grasp works, grasps turned about the domino's width towards a
    # vertical approach by half this and this (grasp_candidates.steeper_grasps); 0: none.
    steeper_grasp_turn: float = math.radians(20.0)  # rad
    # Grasps turned the other way and moved towards the end the pads hold, by half these
    # and these (grasp_candidates.flatter_grasps): at place the gripper stands more upright and its
    # pads ride higher, for slots of a curved run and near the inner reach limit; 0 and 0:
    # none. Beyond ~7° the wrist comes within coarse_clearance (5 mm) of the table at pick;
    # each mm of shift takes ~1.5 mm² off the pads' 40.7 mm² on the side faces.
    flatter_grasp_turn: float = math.radians(5.0)  # rad
    flatter_grasp_shift: float = 0.002  # m

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            values = value if isinstance(value, tuple) else (value,)
            if field.name in ("seed", "allow_regrasp", "budget_clock"):
                continue
            if not all(
                isinstance(v, int | float) and not isinstance(v, bool) and math.isfinite(v)
                for v in values
            ):
                raise ValueError(f"{field.name} must be finite numbers, got {value!r}")
            may_be_zero = (
                "release_height",
                "steeper_grasp_turn",
                "flatter_grasp_turn",
                "flatter_grasp_shift",
                "pile_nudge",
            )
            if not isinstance(value, tuple) and field.name not in may_be_zero and value <= 0:
                raise ValueError(f"{field.name} must be positive, got {value!r}")
            if field.name == "free_acceleration_limits":
                if len(values) != ARM_JOINTS or min(values) <= 0:
                    raise ValueError(
                        f"{field.name} must be {ARM_JOINTS} positive numbers, got {value!r}"
                    )
            elif isinstance(value, tuple) and not values[0] < values[1]:
                raise ValueError(f"{field.name} must be (low, high) with low < high, got {value}")
        if self.budget_clock not in BUDGET_CLOCKS:
            raise ValueError(
                f"budget_clock must be one of {sorted(BUDGET_CLOCKS)}, got {self.budget_clock!r}"
            )
        if self.pile_nudge < 0:
            raise ValueError(f"pile_nudge must be >= 0, got {self.pile_nudge}")
        if self.release_height < 0:
            raise ValueError(f"release_height must be >= 0, got {self.release_height}")
        for name in ("steeper_grasp_turn", "flatter_grasp_turn"):
            if not 0.0 <= getattr(self, name) <= math.pi / 2:
                raise ValueError(f"{name} must be 0 to π/2 rad, got {getattr(self, name)}")
        if not 0.0 <= self.flatter_grasp_shift <= MAX_GRASP_SHIFT:
            raise ValueError(
                f"flatter_grasp_shift must be 0 to {MAX_GRASP_SHIFT} m (the TCP at the "
                f"domino's end), got {self.flatter_grasp_shift}"
            )
        if self.strike_height > 1.0:
            raise ValueError(f"strike_height is a fraction of the height, got {self.strike_height}")
        if self.kto_control_points < 4:
            raise ValueError("kto_control_points must be at least 4 (cubic B-spline)")

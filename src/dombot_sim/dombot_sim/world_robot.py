"""A CellWorld's arm and gripper: commands (a trajectory, a hold, an opening and force),
a pose set by hand, and their state (joint positions, velocities and efforts, the TCP,
the fingers).

``WorldRobot`` is a part of ``CellWorld`` (``world.py``), which builds the controllers it
commands: the attributes declared here are CellWorld's.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.multibody.tree import RigidBody
from pydrake.systems.framework import Context, InputPort
from pydrake.trajectories import PiecewisePolynomial

from dombot_description.cell import CellModels
from dombot_description.scenario import Scenario
from dombot_sim.control import ArmCommand, GripperController
from dombot_sim.trajectory import JointLimits
from dombot_sim.world_config import WorldConfig

GRIPPER_OPEN = 0.10  # m, opening after a reset


@dataclass(frozen=True)
class JointStateSample:
    names: tuple[str, ...]
    position: np.ndarray
    velocity: np.ndarray
    effort: np.ndarray


@dataclass(frozen=True)
class GripperState:
    opening: float  # m
    opening_rate: float  # m/s
    force: float  # N per finger along the opening; negative squeezes
    goal: float
    force_limit: float


class WorldRobot:
    """CellWorld's arm and gripper."""

    config: WorldConfig
    scenario: Scenario
    time: float  # WorldStepping's
    _root: Context
    _plant: MultibodyPlant
    _plant_context: Context
    _models: CellModels
    _arm_source: ArmCommand
    _gripper: GripperController
    _actuation_inputs: list[InputPort]
    _arm_pd: np.ndarray
    _effort_limits: np.ndarray
    _domino_bodies: list[RigidBody]
    _commanded: bool

    def _go_home(self) -> None:
        plant, context = self._plant, self._plant_context
        plant.SetPositions(context, self._models.arm, self.scenario.home_position)
        plant.SetVelocities(context, self._models.arm, np.zeros(7))
        plant.SetPositions(context, self._models.gripper, [GRIPPER_OPEN / 2] * 2)
        plant.SetVelocities(context, self._models.gripper, np.zeros(2))
        self._command_arm(lambda: self._arm_source.hold(self.scenario.home_position))
        self._gripper.command(GRIPPER_OPEN, 0.0, self.time, GRIPPER_OPEN)

    def joint_state(self) -> JointStateSample:
        """Arm joints then finger joints: positions [rad | m], velocities, and the efforts
        the controllers apply now (``_efforts``)."""
        plant, context = self._plant, self._plant_context
        models = (self._models.arm, self._models.gripper)
        position = np.concatenate([plant.GetPositions(context, m) for m in models])
        velocity = np.concatenate([plant.GetVelocities(context, m) for m in models])
        return JointStateSample(
            names=self.scenario.arm_joints + self.scenario.gripper_joints,
            position=position,
            velocity=velocity,
            effort=self._efforts(position, velocity),
        )

    def _efforts(self, position: np.ndarray, velocity: np.ndarray) -> np.ndarray:
        """The actuators' efforts at the current state and command: the arm's feedforward
        plus its joint PD, the fingers' forces, clamped to the limits as the plant clamps
        them. The plant's net actuation port gave the last step's (its PD is implicit, so
        they differ by the command's change over one step, ~3 N·m on joint 1 in a fast
        swing); with live output ports (``add_cell_plant``) evaluating it solves a step again."""
        feedforward, fingers = (port.Eval(self._plant_context) for port in self._actuation_inputs)
        desired = self._arm_source.desired_state_port.Eval(
            self._arm_source.split.GetMyContextFromRoot(self._root)
        )
        stiffness, damping = self._arm_pd
        dofs = len(stiffness)
        arm = (
            feedforward
            + stiffness * (desired[:dofs] - position[:dofs])
            + damping * (desired[dofs:] - velocity[:dofs])
        )
        return np.clip(np.concatenate([arm, fingers]), -self._effort_limits, self._effort_limits)

    def arm_limits(self) -> JointLimits:
        """Position and velocity limits of the arm joints, in ``arm_joint_names`` order."""
        joints = [self._plant.GetJointByName(name) for name in self.scenario.arm_joints]
        return JointLimits(
            names=self.scenario.arm_joints,
            lower=np.array([j.position_lower_limits()[0] for j in joints]),
            upper=np.array([j.position_upper_limits()[0] for j in joints]),
            velocity=np.array([j.velocity_upper_limits()[0] for j in joints]),
        )

    def set_robot_positions(
        self, arm: np.ndarray | None = None, opening: float | None = None
    ) -> None:
        """Put the arm at ``arm`` (joint positions; None: home) and the fingers ``opening``
        apart (None: fully open), at rest, and hold them there.

        Like ``set_domino_poses``, for building scenes by hand (e.g. a domino held by the
        gripper in front of a camera); no physics runs.
        """
        arm = self.scenario.home_position if arm is None else np.asarray(arm, dtype=float)
        opening = GRIPPER_OPEN if opening is None else float(opening)
        if arm.shape != (7,) or not np.all(np.isfinite(arm)):
            raise ValueError(f"need 7 finite arm joint positions, got {arm}")
        if not (np.isfinite(opening) and 0.0 <= opening <= self.gripper_stroke):
            raise ValueError(f"gripper opening must be within 0–{self.gripper_stroke:.3f} m")
        plant, context = self._plant, self._plant_context
        plant.SetPositions(context, self._models.arm, arm)
        plant.SetVelocities(context, self._models.arm, np.zeros(7))
        plant.SetPositions(context, self._models.gripper, [opening / 2] * 2)
        plant.SetVelocities(context, self._models.gripper, np.zeros(2))
        self._command_arm(lambda: self._arm_source.hold(arm))
        self._gripper.command(opening, 0.0, self.time, opening)

    def follow_trajectory(self, trajectory: PiecewisePolynomial) -> float:
        """Start tracking ``trajectory`` (arm joints, time from 0) now; returns its end time."""
        if trajectory.rows() != 7 or trajectory.cols() != 1:
            raise ValueError(
                f"need a 7x1 joint trajectory, got {trajectory.rows()}x{trajectory.cols()}"
            )
        self._command_arm(lambda: self._arm_source.follow(trajectory, self.time))
        return self._arm_source.end_time

    def hold_arm(self, position: np.ndarray | None = None) -> None:
        """Hold ``position`` (default: where the arm is now)."""
        if position is None:
            position = self._plant.GetPositions(self._plant_context, self._models.arm)
        self._command_arm(lambda: self._arm_source.hold(np.asarray(position, dtype=float)))

    def _command_arm(self, change: Callable[[], None]) -> None:
        """Change the arm's command; re-setting the time drops outputs cached for the old one."""
        change()
        self._root.SetTime(self._root.get_time())
        self._commanded = True

    def desired_arm_state(self) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """What the arm controller is tracking now: (q, v, a)."""
        return self._arm_source.desired(self.time)

    def tcp_pose(self) -> np.ndarray:
        """4x4 pose of the gripper's TCP frame in world."""
        frame = self._plant.GetFrameByName(self.scenario.tcp_frame)
        return frame.CalcPoseInWorld(self._plant_context).GetAsMatrix4()

    def tcp_speed(self) -> float:
        frame = self._plant.GetFrameByName(self.scenario.tcp_frame)
        velocity = frame.CalcSpatialVelocityInWorld(self._plant_context)
        return float(np.linalg.norm(velocity.translational()))

    def domino_in_tcp(self, index: int) -> np.ndarray:
        """4x4 pose of a domino in the TCP frame: constant while it is held without slipping."""
        pose = self._domino_bodies[index].EvalPoseInWorld(self._plant_context).GetAsMatrix4()
        return np.linalg.inv(self.tcp_pose()) @ pose

    def command_gripper(self, opening: float, max_force: float = 0.0) -> None:
        """Move the fingers to ``opening`` [m] at the speed limit; squeeze with ``max_force`` N."""
        stroke = self.gripper_stroke
        if not (np.isfinite(opening) and 0.0 <= opening <= stroke):
            raise ValueError(f"gripper opening must be within 0–{stroke:.3f} m, got {opening}")
        if not (np.isfinite(max_force) and max_force >= 0.0):
            raise ValueError(f"gripper max_force must be >= 0, got {max_force}")
        self._gripper.command(opening, max_force, self.time, self.gripper_state().opening)
        self._commanded = True

    @property
    def gripper_stroke(self) -> float:
        """Largest opening [m]: both fingers at their upper limit."""
        finger = self._plant.GetJointByName(self.scenario.gripper_joints[0])
        return 2.0 * float(finger.position_upper_limits()[0])

    @property
    def gripper_stroke_time(self) -> float:
        """Seconds a full stroke takes at the fingers' speed."""
        return self.gripper_stroke / self.config.gripper.speed

    def gripper_state(self) -> GripperState:
        state = self._plant.GetPositionsAndVelocities(self._plant_context, self._models.gripper)
        return GripperState(
            opening=float(state[0] + state[1]),
            opening_rate=float(state[2] + state[3]),
            force=self._gripper.opening_force(self.time, state),
            goal=self._gripper.goal,
            force_limit=self._gripper.force_limit,
        )

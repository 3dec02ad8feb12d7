"""The cell's controllers, as a real cell has them: a joint trajectory follower for the arm
and a position-controlled gripper with a force limit.

* Arm: the commanded trajectory gives the desired joint state and acceleration; the
  plant's built-in joint PD controllers (solved implicitly by Drake's discrete contact
  solver, so stiff gains stay stable) track it, and an inverse-dynamics feedforward
  (gravity, Coriolis, inertia of the arm and gripper at the desired state) does the
  rest, like the iiwa's own joint impedance controller with gravity compensation.
* Gripper: the two fingers move together (a WSG 50 drives both from one motor): a PD on
  the opening with the force clamped to the command's limit, the target moving at
  the gripper's speed limit, and a stiff PD keeping the fingers symmetric. Closing on
  a domino therefore squeezes it with the limit force, as the paper's "close fully and
  squeeze" does.
"""

from __future__ import annotations

import copy
import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np
from pydrake.systems.framework import BasicVector, Context, DiagramBuilder, LeafSystem, OutputPort
from pydrake.systems.primitives import Demultiplexer, TrajectorySource
from pydrake.trajectories import PiecewisePolynomial


@dataclass(frozen=True)
class ArmGains:
    """Joint stiffness [N·m/rad] and damping [N·m·s/rad] of the arm's position control."""

    stiffness: tuple[float, ...] = (4000.0, 4000.0, 2000.0, 2000.0, 800.0, 400.0, 400.0)
    damping: tuple[float, ...] = (200.0, 200.0, 100.0, 100.0, 40.0, 20.0, 20.0)


@dataclass(frozen=True)
class GripperSettings:
    """WSG 50-class gripper: opening gains, speed and force limits."""

    opening_stiffness: float = 2000.0  # N/m per finger
    opening_damping: float = 20.0  # N·s/m
    centering_stiffness: float = 4000.0  # N/m, keeps the fingers symmetric
    centering_damping: float = 20.0
    speed: float = 0.1  # m/s, rate of the opening target
    max_force: float = 80.0  # N per finger, the hardware's limit
    default_force: float = 20.0  # N when a command asks for 0


class ArmCommand:
    """The arm's command as a Drake ``TrajectorySource`` (C++, evaluated every step).

    The source outputs [q; q̇; q̈] of a trajectory in simulated time; a demultiplexer
    splits it into the desired state (PD) and acceleration (feedforward). The world
    replaces the trajectory between simulator steps, as a robot driver does; holding a
    position is a constant trajectory.
    """

    def __init__(self, builder: DiagramBuilder, home: np.ndarray) -> None:
        self._dofs = len(home)
        self._trajectory = _constant(home)
        self._end = 0.0
        self.source = builder.AddSystem(
            TrajectorySource(self._trajectory, output_derivative_order=2)
        )
        self.split = builder.AddSystem(Demultiplexer([2 * self._dofs, self._dofs]))
        builder.Connect(self.source.get_output_port(), self.split.get_input_port())

    @property
    def desired_state_port(self) -> OutputPort:
        return self.split.get_output_port(0)

    @property
    def desired_acceleration_port(self) -> OutputPort:
        return self.split.get_output_port(1)

    def hold(self, position: np.ndarray) -> None:
        self._set(_constant(position), end=0.0)

    def follow(self, trajectory: PiecewisePolynomial, start_time: float) -> None:
        """Track ``trajectory`` (time from 0) from simulated ``start_time``, then hold its end."""
        shifted = copy.copy(trajectory)
        shifted.shiftRight(start_time)
        self._set(shifted, start_time + trajectory.end_time())

    def _set(self, trajectory: PiecewisePolynomial, end: float) -> None:
        self._trajectory, self._end = trajectory, end
        self.source.UpdateTrajectory(trajectory)  # the world then invalidates cached outputs

    @property
    def end_time(self) -> float:
        """Simulated time at which the current command ends."""
        return self._end

    def desired(self, time: float) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """(q, v, a) commanded at simulated ``time``; outside the trajectory, at rest."""
        trajectory = self._trajectory
        clamped = float(np.clip(time, trajectory.start_time(), trajectory.end_time()))
        q = trajectory.value(clamped).ravel()
        if clamped != time:
            return q, np.zeros(self._dofs), np.zeros(self._dofs)
        return (
            q,
            trajectory.EvalDerivative(time, 1).ravel(),
            trajectory.EvalDerivative(time, 2).ravel(),
        )


def _constant(position: np.ndarray) -> PiecewisePolynomial:
    """A trajectory that holds ``position`` (zero derivatives) at every time."""
    column = np.asarray(position, dtype=float).reshape(-1, 1)
    return PiecewisePolynomial.ZeroOrderHold([0.0, 1.0], np.hstack([column, column]))


class GripperController(LeafSystem):
    """Finger forces from the finger state: opening PD with a force limit, fingers centred.

    Finger joint convention (dombot_description): each coordinate is that finger's
    distance from the centre line, so the opening is their sum and a positive force opens.
    """

    def __init__(self, settings: GripperSettings, initial_opening: float) -> None:
        super().__init__()
        self.settings = settings
        self._goal = initial_opening
        self._force_limit = settings.default_force
        self._ramp_start_opening = initial_opening
        self._ramp_start_time = 0.0
        self._state_port = self.DeclareVectorInputPort("finger_state", 4)
        self.DeclareVectorOutputPort("finger_force", 2, self._calc_force)

    def command(self, opening: float, max_force: float, now: float, current_opening: float) -> None:
        """Move towards ``opening`` [m] at the speed limit, squeezing with at most ``max_force``."""
        self._goal = opening
        self._force_limit = min(max_force or self.settings.default_force, self.settings.max_force)
        self._ramp_start_opening = current_opening
        self._ramp_start_time = now

    @property
    def goal(self) -> float:
        return self._goal

    @property
    def force_limit(self) -> float:
        return self._force_limit

    def reference(self, time: float) -> float:
        """The opening target at ``time``: a ramp from the command's start at the speed limit."""
        delta = self._goal - self._ramp_start_opening
        return self._ramp_start_opening + math.copysign(min(self._travel(time), abs(delta)), delta)

    def target_reached(self, time: float) -> bool:
        """Has the opening target arrived at the goal by ``time`` (it moves no more)?"""
        return self._travel(time) >= abs(self._goal - self._ramp_start_opening)

    def _travel(self, time: float) -> float:
        """How far the ramp has moved the target by ``time`` if nothing stopped it."""
        return self.settings.speed * max(time - self._ramp_start_time, 0.0)

    def opening_force(self, time: float, state: Sequence[float]) -> float:
        """Force per finger along the opening (negative squeezes), clamped to the limit."""
        s = self.settings
        left, right, left_rate, right_rate = (float(x) for x in state[:4])
        opening, opening_rate = left + right, left_rate + right_rate
        force = s.opening_stiffness * (self.reference(time) - opening) - s.opening_damping * (
            opening_rate
        )
        return min(max(force, -self._force_limit), self._force_limit)

    def _calc_force(self, context: Context, output: BasicVector) -> None:
        """Evaluated at every physics step: plain floats, no numpy scalars."""
        s = self.settings
        state = self._state_port.Eval(context).tolist()
        opening_force = self.opening_force(context.get_time(), state)
        asymmetry, asymmetry_rate = state[0] - state[1], state[2] - state[3]
        centering = -s.centering_stiffness * asymmetry - s.centering_damping * asymmetry_rate
        output.SetFromVector([opening_force + centering, opening_force - centering])

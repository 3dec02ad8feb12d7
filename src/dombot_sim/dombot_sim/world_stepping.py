"""How a CellWorld's time moves on: physics steps in chunks between the sleepers'
checks, a still cell's clock moved on without steps, a diverged step undone, a domino
that left the cell parked, a pile settled.

``WorldStepping`` is a part of ``CellWorld`` (``world.py``), which builds the diagram it
steps: the attributes declared here are CellWorld's.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence

import numpy as np
from pydrake.multibody.plant import MultibodyPlant
from pydrake.systems.analysis import InitializeParams, Simulator
from pydrake.systems.framework import Context

from dombot_description.cell import CellModels
from dombot_sim.control import ArmCommand, GripperController
from dombot_sim.sleeping import SleepManager
from dombot_sim.world_config import WorldConfig

DIVERGED_STATE = 1e3  # m, m/s or rad/s: no state of the cell comes near this
CHUNK_STEPS = 10  # at most this many steps between looks at the state (sleeping off)
LEFT_CELL_BELOW = -0.2  # m: a domino this far under the table top fell off the table
LEFT_CELL_BEYOND = 3.0  # m from the robot base: flung out of the cell
# m/s, rad/s: every joint of the cell slower than this, and nothing commanded to move,
# is still (an arm holding after a trajectory is below it ~0.3 s after the end; the
# fingers at rest jitter at ~1e-7 m/s)
STILL_SPEED = 1e-5


class WorldStepping:
    """CellWorld's clock and physics steps."""

    config: WorldConfig
    skip_still: bool
    skipped_time: float
    divergences: int
    trouble_listener: Callable[[str], None] | None
    _root: Context
    _simulator: Simulator
    _plant: MultibodyPlant
    _plant_context: Context
    _models: CellModels
    _arm_source: ArmCommand
    _gripper: GripperController
    _sleep: SleepManager
    _in_use: list[int]
    _domino_names: list[str]
    _domino_xyz: np.ndarray
    _state_owners: np.ndarray
    _skipped: bool
    _commanded: bool
    _diverged_last_step: bool
    _park: Callable[[Sequence[int]], None]  # CellWorld's: dominoes off the table, asleep

    @property
    def time(self) -> float:
        return self._root.get_time()

    def advance(self, duration: float) -> None:
        """Simulate ``duration`` seconds (rounded to whole steps), updating sleepers between
        steps."""
        self.advance_to(self.time + duration)

    def advance_to(self, target: float) -> None:
        """Simulate up to ``target`` (on the step grid). While the cell is ``still`` (and
        ``skip_still``) only the clock moves: a step would change nothing."""
        last = self._step_index() + max(round((target - self.time) / self.config.time_step), 0)
        if self._step_index() < last and self.skip_still and self.still():
            self._skip_to(last)
        while self._step_index() < last:
            self._advance_chunk(last)

    def still(self) -> bool:
        """Nothing in the cell moves, nor would in a step: every domino in use at rest —
        asleep, or held still in the fingers (``SleepManager.all_at_rest``: rested at the
        last check, no faster than a resting body now; its grip's creep, a step-size
        artefact of regularized friction, is not simulated meanwhile) — the arm holding
        after its last trajectory and the fingers at their goal, every arm joint (and
        finger joint, unless closed on a resting domino) slower than STILL_SPEED since a
        step after the last command (a new hold starts from rest: its first step shows
        the pull), and sleeping on (it is what says a domino rests)."""
        sleep = self._sleep
        if self._commanded or not (sleep.enabled and sleep.all_at_rest(self._in_use)):
            return False
        now = self.time
        if now < self._arm_source.end_time or not self._gripper.target_reached(now):
            return False
        held = sleep.resting_awake()
        if held and sleep.moving(self._root, held):
            return False
        # fingers closed on a resting domino creep with it (~2e-5 m/s)
        finger_limit = sleep.settings.moving_speed if held else STILL_SPEED
        arm = self._plant.GetVelocities(self._plant_context, self._models.arm)
        fingers = self._plant.GetVelocities(self._plant_context, self._models.gripper)
        return bool(np.all(np.abs(arm) < STILL_SPEED) and np.all(np.abs(fingers) < finger_limit))

    def _skip_to(self, last: int) -> None:
        """Move the clock to step ``last`` without stepping; the state stays as it is."""
        target = last * self.config.time_step
        self.skipped_time += target - self.time
        self._root.SetTime(target)
        self._skipped = True

    def _step_index(self) -> int:
        """The time as a number of steps: it is always on the plant's grid k * dt."""
        return round(self.time / self.config.time_step)

    def _advance_chunk(self, last: int) -> None:
        """Steps up to the sleepers' next check (or ``last``, or CHUNK_STEPS), in one
        ``AdvanceTo``, then the checks that look at the state between steps.

        Nothing in Python needs to see the steps in between: the sleep check runs at the
        same steps as when every step was advanced on its own, and a chunk that diverges
        is redone step by step from its start, which undoes the very step that diverged
        (a step is a function of the state and the time). A domino that left the cell is
        parked up to a chunk later, where it touches nothing.
        """
        dt, start = self.config.time_step, self._step_index()
        if self._skipped:  # its pending step was for the time before the skip
            self._simulator.Initialize(InitializeParams(suppress_initialization_events=True))
            self._skipped = False
        due = self._sleep.next_check
        end = start + 1
        while end < min(last, start + CHUNK_STEPS) and end * dt < due:
            end += 1
        before = self._plant.GetPositionsAndVelocities(self._plant_context)
        self._simulator.AdvanceTo(end * dt)
        after = self._plant.GetPositionsAndVelocities(self._plant_context)
        if not np.all(np.abs(after) < DIVERGED_STATE):  # NaN compares False
            self._plant.SetPositionsAndVelocities(self._plant_context, before)
            self._root.SetTime(start * dt)  # a simulator's time goes back by Initialize only
            self._simulator.Initialize(InitializeParams(suppress_initialization_events=True))
            for _ in range(end - start):
                after = self._step(dt)
        else:
            self._diverged_last_step = False
        self._remove_escaped(after)
        self._sleep.update(self._root)
        self._commanded = False

    def _step(self, dt: float) -> np.ndarray:
        """One physics step; a step that leaves a diverged state is undone. Returns the
        state after it.

        The contact physics diverged once in 15 benchmark runs (NaN poses; not
        reproducible, paced runs differ in timing). Rather than losing the run, the state
        goes back to the one before the step with the diverged bodies' velocities zeroed
        (time still moves on by the step), and the trouble listener (the node's log)
        hears which bodies. Diverging again in the next step raises.
        """
        start = self.time
        before = self._plant.GetPositionsAndVelocities(self._plant_context)
        # on the plant's own grid k * dt: a sum of steps drifts off it, and then a step
        # holds zero or two plant updates depending on the absolute time
        self._simulator.AdvanceTo((self._step_index() + 1) * dt)
        after = self._plant.GetPositionsAndVelocities(self._plant_context)
        diverged = ~(np.abs(after) < DIVERGED_STATE)  # NaN compares False
        if not diverged.any():
            self._diverged_last_step = False
            return after
        owners = sorted(set(self._state_owners[diverged]))
        message = f"physics diverged at t={start:.3f} s (state of {', '.join(owners)})"
        if self._diverged_last_step:
            raise RuntimeError(f"{message} in two steps running; the simulation cannot go on")
        self._diverged_last_step = True
        self.divergences += 1
        self._tell(f"{message}; step undone, their velocities zeroed")
        velocities = slice(self._plant.num_positions(), None)
        restart = before.copy()
        restart[velocities][np.isin(self._state_owners[velocities], owners)] = 0.0
        self._plant.SetPositionsAndVelocities(self._plant_context, restart)
        return restart

    def _remove_escaped(self, state: np.ndarray) -> None:
        """Park the dominoes in use that left the cell (off the table, or flung away).

        Falling for ever, one ran its state up to the divergence check, whose undo could
        not stop the fall, and the simulator ended (S-curve seed 3). Parked, it is no
        longer in use: perception, the truth and the report no longer see it.
        """
        in_use = np.array(self._in_use, dtype=int)
        xyz = state[self._domino_xyz[in_use]]  # (dominoes in use, 3)
        away = (xyz[:, 2] < LEFT_CELL_BELOW) | (np.hypot(xyz[:, 0], xyz[:, 1]) > LEFT_CELL_BEYOND)
        gone = away & ~self._sleep.asleep[in_use]  # asleep: parked, e.g. not yet poured
        for index, position in zip(in_use[gone], xyz[gone], strict=True):
            self._in_use.remove(int(index))
            self._park([int(index)])
            where = np.round(position, 2).tolist()
            self._tell(f"{self._domino_names[index]} left the cell at {where} m: removed")

    def _tell(self, trouble: str) -> None:
        if self.trouble_listener is not None:
            self.trouble_listener(trouble)

    def set_sleeping(self, enabled: bool) -> None:
        """Turn sleeping on or off (off wakes every domino in use)."""
        self._sleep.enabled = enabled
        if not enabled:
            self._sleep.wake(self._root, self._in_use)

    def settle(self, limit: float) -> bool:
        """Advance until the dominoes in use are at rest; False if still moving at ``limit`` s.

        At rest means asleep with sleeping on, and no domino point faster than the sleep
        settings' moving speed for their rest time with it off.
        """
        dt, deadline, rested = self.config.time_step, self.time + max(limit, 0.0), 0.0
        last = self._step_index()
        while last * dt < deadline:
            last += 1
        while self._step_index() < last:
            if self._sleep.enabled:
                # dominoes fall asleep (or are parked) only between chunks
                if self._sleep.all_asleep(self._in_use):
                    return True
                self._advance_chunk(last)
                continue
            moving = self._sleep.moving(self._root, self._in_use)
            rested = 0.0 if moving else rested + dt
            if rested >= self.config.sleep.rest_time:
                return True
            self._advance_chunk(self._step_index() + 1)
        return False

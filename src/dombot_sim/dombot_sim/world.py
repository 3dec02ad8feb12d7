"""The simulated DOM-BOT cell: Drake physics, controllers, cameras and a pile of dominoes.

This is the ROS-free core that ``sim_node`` exposes; tests, benchmarks and the
perception harness use it directly::

    world = CellWorld(WorldConfig(cameras=True))
    world.reset(domino_count=30, seed=7)        # pour a seeded pile and let it settle
    frames = world.render()                     # {camera: CameraFrame}
    world.follow_trajectory(trajectory)         # PiecewisePolynomial of the 7 arm joints
    world.command_gripper(opening=0.0, max_force=20.0)
    world.advance(2.0)
    world.domino_truth()                        # ground truth, for evaluation only

Physics choices (measured in docs/SIM.md): discrete plant with a 1 ms step and the
"similar" convex contact approximation; dominoes are compliant hydroelastic boxes on a
rigid hydroelastic table and rigid pads (pressure patches instead of single contact
points, so dominoes rest flat, stand still and are held without pivoting); resting
dominoes sleep (``sleeping.py``).
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np
from pydrake.geometry import (
    CollisionFilterDeclaration,
    Meshcat,
    MeshcatVisualizer,
    MeshcatVisualizerParams,
    Role,
    SceneGraph,
)
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialVelocity
from pydrake.multibody.plant import (
    AddMultibodyPlantSceneGraph,
    ContactModel,
    DiscreteContactApproximation,
    MultibodyPlant,
)
from pydrake.multibody.tree import ModelInstanceIndex, PdControllerGains
from pydrake.systems.analysis import InitializeParams, Simulator
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import DiagramBuilder
from pydrake.trajectories import PiecewisePolynomial

from dombot_description import DOMINO_SIZE
from dombot_description.cell import CellModels, add_cell, add_dominoes, build_shadow_plant
from dombot_description.scenario import Scenario, load_scenario
from dombot_sim.cameras import CameraFrame, RenderScene
from dombot_sim.control import ArmCommand, ArmGains, GripperController, GripperSettings
from dombot_sim.frames import WORLD, FrameTransform, LinkTree
from dombot_sim.pile import PourSettings, parking_pose, pour_wave, wave_sizes
from dombot_sim.sleeping import SleepManager, SleepSettings
from dombot_sim.trajectory import JointLimits

CONTACT_MODELS = {
    "hydroelastic": ContactModel.kHydroelasticWithFallback,
    "point": ContactModel.kPoint,  # ignores the hydroelastic properties; for comparison
}
CONTACT_APPROXIMATIONS = {
    "tamsi": DiscreteContactApproximation.kTamsi,
    "sap": DiscreteContactApproximation.kSap,
    "similar": DiscreteContactApproximation.kSimilar,
    "lagged": DiscreteContactApproximation.kLagged,
}
GRIPPER_OPEN = 0.10  # m, opening after a reset
UPRIGHT_TOLERANCE = np.radians(10.0)  # body x this close to vertical counts as upright
WAVE_FALL_TIME = 0.35  # s simulated between pour waves
DIVERGED_STATE = 1e3  # m, m/s or rad/s: no state of the cell comes near this
CHUNK_STEPS = 10  # at most this many steps between looks at the state (sleeping off)
LEFT_CELL_BELOW = -0.2  # m: a domino this far under the table top fell off the table
LEFT_CELL_BEYOND = 3.0  # m from the robot base: flung out of the cell
# m/s, rad/s: every joint of the cell slower than this, and nothing commanded to move,
# is still (an arm holding after a trajectory is below it ~0.3 s after the end; the
# fingers at rest jitter at ~1e-7 m/s)
STILL_SPEED = 1e-5
# bytes: the least a process stepping the cell should keep off mmap (``step_block_size``)
STEP_BLOCK_MIN = 1 << 20
# Meshcat recording: 16 frames a simulated second play smoothly, and keep a whole run's
# scene.html to tens of MB (at Drake's default of 64 it is four times that)
MESHCAT_RECORDING_FPS = 16.0


@dataclass(frozen=True)
class WorldConfig:
    scenario_path: str | None = None  # None: dombot_description's default scenario
    time_step: float = 0.001  # s
    contact_approximation: str = "similar"
    contact_model: str = "hydroelastic"
    cameras: bool = True
    meshcat: bool = False
    domino_capacity: int = 30  # bodies in the plant; a larger reset rebuilds it
    # length, width, thickness [m]; another set (the wave benchmark's) keeps the density
    domino_size: tuple[float, float, float] = DOMINO_SIZE
    settle_limit: float = 10.0  # s simulated: a pile still moving after this is reported
    pour_wave_size: int = 6
    # while the cell is still (``CellWorld.still``) the clock advances without stepping
    skip_still: bool = True
    sleep: SleepSettings = field(default_factory=SleepSettings)
    arm_gains: ArmGains = field(default_factory=ArmGains)
    gripper: GripperSettings = field(default_factory=GripperSettings)

    def __post_init__(self) -> None:
        if not self.time_step > 0.0:
            raise ValueError(f"time_step must be positive, got {self.time_step}")
        if self.contact_approximation not in CONTACT_APPROXIMATIONS:
            raise ValueError(
                f"contact_approximation must be one of {sorted(CONTACT_APPROXIMATIONS)}, "
                f"got {self.contact_approximation!r}"
            )
        if self.contact_model not in CONTACT_MODELS:
            raise ValueError(
                f"contact_model must be one of {sorted(CONTACT_MODELS)}, got {self.contact_model!r}"
            )
        if len(self.domino_size) != 3 or not all(0.0 < x < 1.0 for x in self.domino_size):
            raise ValueError(f"domino_size must be 3 lengths in (0, 1) m, got {self.domino_size}")
        if self.domino_capacity < 0 or self.pour_wave_size < 1:
            raise ValueError("domino_capacity must be >= 0 and pour_wave_size >= 1")


@dataclass(frozen=True)
class ResetReport:
    domino_count: int
    seed: int
    settle_time: float  # s simulated from the first pour until everything was at rest
    settled: bool  # False: still moving at settle_limit
    wall_time: float  # s


@dataclass(frozen=True)
class DominoTruth:
    index: int
    name: str
    X_WD: np.ndarray  # 4x4
    velocity: np.ndarray  # [wx, wy, wz, vx, vy, vz] in world
    upright: bool
    asleep: bool
    in_use: bool  # False: parked off the table


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


class CellWorld:
    """One simulated cell. Not thread-safe: drive it from one thread."""

    def __init__(self, config: WorldConfig | None = None, scenario: Scenario | None = None):
        self.config = config or WorldConfig()
        self.scenario = scenario or load_scenario(self.config.scenario_path)
        self.meshcat = Meshcat() if self.config.meshcat else None
        self._in_use: list[int] = []
        self._root = None
        self.divergences = 0  # physics steps undone after diverging
        self.skip_still = self.config.skip_still
        self.skipped_time = 0.0  # s simulated advanced without stepping (``still``)
        self._skipped = False  # the simulator must be re-initialized before its next step
        self._commanded = False  # a command not yet followed by a step (``still``)
        self._diverged_last_step = False
        # hears what went wrong in the physics and what was done about it (the node logs it)
        self.trouble_listener: Callable[[str], None] | None = None
        self._build(self.config.domino_capacity)

    # ------------------------------------------------------------------ construction
    def _build(self, capacity: int) -> None:
        """(Re)build the diagram for ``capacity`` dominoes; simulated time carries on."""
        config, scenario = self.config, self.scenario
        now = 0.0 if self._root is None else self._root.get_time()
        builder = DiagramBuilder()
        plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=config.time_step)
        plant.set_discrete_contact_approximation(
            CONTACT_APPROXIMATIONS[config.contact_approximation]
        )
        plant.set_contact_model(CONTACT_MODELS[config.contact_model])
        # live output ports: a sampled plant also computes and stores every step's contact
        # results, reaction forces and accelerations, which nothing here reads; ~15 % of a
        # step with a domino in the pads, the states bit-identical (docs/SIM.md, *Stepping*).
        # ``joint_state`` then computes the efforts itself (``_efforts``)
        plant.SetUseSampledOutputPorts(False)
        models = add_cell(plant, scenario)
        domino_models = add_dominoes(plant, capacity, config.domino_size)
        # GetJointActuatorIndices(model_instance) is empty before Finalize: filter all of them.
        for actuator_index in plant.GetJointActuatorIndices():
            actuator = plant.get_mutable_joint_actuator(actuator_index)
            if actuator.model_instance() != models.arm:
                continue
            joint = scenario.arm_joints.index(actuator.joint().name())
            actuator.set_controller_gains(
                PdControllerGains(
                    p=config.arm_gains.stiffness[joint], d=config.arm_gains.damping[joint]
                )
            )
        plant.Finalize()
        _filter_arm_self_collisions(plant, scene_graph, models, scenario.gripper_joints)

        self._control_model = build_shadow_plant(scenario, grasp_opening=GRIPPER_OPEN)
        arm_source = ArmCommand(builder, scenario.home_position)
        feedforward = builder.AddSystem(InverseDynamics(self._control_model.plant))
        builder.Connect(arm_source.desired_state_port, feedforward.get_input_port(0))
        builder.Connect(arm_source.desired_acceleration_port, feedforward.get_input_port(1))
        builder.Connect(feedforward.get_output_port(), plant.get_actuation_input_port(models.arm))
        builder.Connect(
            arm_source.desired_state_port, plant.get_desired_state_input_port(models.arm)
        )
        gripper = builder.AddSystem(GripperController(config.gripper, GRIPPER_OPEN))
        builder.Connect(plant.get_state_output_port(models.gripper), gripper.get_input_port())
        builder.Connect(gripper.get_output_port(), plant.get_actuation_input_port(models.gripper))

        self._cameras = (
            RenderScene(scenario, capacity, config.domino_size) if config.cameras else None
        )
        if self.meshcat is not None:
            MeshcatVisualizer.AddToBuilder(
                builder, scene_graph, self.meshcat, MeshcatVisualizerParams(role=Role.kIllustration)
            )

        self._diagram = builder.Build()
        self._plant, self._scene_graph, self._models = plant, scene_graph, models
        self._links = LinkTree(plant, (models.arm, models.gripper, models.table))
        self._arm_source, self._gripper = arm_source, gripper
        self._actuation_inputs = [
            plant.get_actuation_input_port(model) for model in (models.arm, models.gripper)
        ]
        self._arm_pd = np.array([config.arm_gains.stiffness, config.arm_gains.damping])
        self._effort_limits = np.array(
            [
                plant.get_joint_actuator(index).effort_limit()
                for model in (models.arm, models.gripper)
                for index in plant.GetJointActuatorIndices(model)
            ]
        )
        self._domino_bodies = [plant.GetBodyByName("domino", m) for m in domino_models]
        self._domino_names = [plant.GetModelInstanceName(m) for m in domino_models]
        self._domino_xyz = np.array(  # each domino's position entries in the plant's q
            [b.floating_positions_start() + 4 + np.arange(3) for b in self._domino_bodies],
            dtype=int,
        ).reshape(-1, 3)
        robot_bodies = [
            plant.get_body(b)
            for model in (models.arm, models.gripper)
            for b in plant.GetBodyIndices(model)
        ]
        table_bodies = [plant.get_body(b) for b in plant.GetBodyIndices(models.table)]
        self._sleep = SleepManager(
            plant, scene_graph, self._domino_bodies, robot_bodies, table_bodies, config.sleep
        )
        self._simulator = Simulator(self._diagram)
        self._root = self._simulator.get_mutable_context()
        self._plant_context = plant.GetMyMutableContextFromRoot(self._root)
        self._state_owners = _state_owners(plant)
        self._capacity = capacity
        self._root.SetTime(now)
        self._go_home()
        self._park(range(capacity))
        self._simulator.Initialize()
        self._skipped = False

    # ------------------------------------------------------------------ state
    @property
    def time(self) -> float:
        return self._root.get_time()

    @property
    def domino_count(self) -> int:
        """Dominoes in the cell (the rest are parked)."""
        return len(self._in_use)

    @property
    def step_block_size(self) -> int:
        """Bytes under which the heap, not ``mmap``, should serve this plant's blocks: a
        physics step allocates and frees dense matrices of the plant's velocities (nv x nv
        doubles, 280 KiB with 30 dominoes) every step. Twice that, at least 1 MiB: at
        glibc's fixed 128 KiB each step mapped and faulted them in anew (docs/SIM.md)."""
        velocities = self._plant.num_velocities()
        return max(STEP_BLOCK_MIN, 2 * 8 * velocities * velocities)

    @property
    def arm_joint_names(self) -> tuple[str, ...]:
        return self.scenario.arm_joints

    def meshcat_url(self) -> str | None:
        return self.meshcat.web_url() if self.meshcat is not None else None

    def start_meshcat_recording(self, frames_per_second: float = MESHCAT_RECORDING_FPS) -> None:
        """Record what Meshcat shows from now on, as an animation (needs ``meshcat``)."""
        if self.meshcat is None:
            raise ValueError("Meshcat is off (WorldConfig.meshcat): nothing to record")
        self.meshcat.StartRecording(frames_per_second=frames_per_second)

    def save_meshcat_recording(self, path: Path) -> None:
        """Write the recording so far as one HTML file that plays it back offline."""
        if self.meshcat is None:
            raise ValueError("Meshcat is off (WorldConfig.meshcat): nothing to save")
        self.meshcat.StopRecording()
        self.meshcat.PublishRecording()
        path.parent.mkdir(parents=True, exist_ok=True)
        path.write_text(self.meshcat.StaticHtml())

    def _go_home(self) -> None:
        plant, context = self._plant, self._plant_context
        plant.SetPositions(context, self._models.arm, self.scenario.home_position)
        plant.SetVelocities(context, self._models.arm, np.zeros(7))
        plant.SetPositions(context, self._models.gripper, [GRIPPER_OPEN / 2] * 2)
        plant.SetVelocities(context, self._models.gripper, np.zeros(2))
        self._command_arm(lambda: self._arm_source.hold(self.scenario.home_position))
        self._gripper.command(GRIPPER_OPEN, 0.0, self.time, GRIPPER_OPEN)

    def _park(self, indices: Sequence[int]) -> None:
        for index in indices:
            self._set_pose(index, parking_pose(index))
        self._sleep.sleep(self._root, list(indices))

    def _set_pose(self, index: int, pose: np.ndarray | RigidTransform) -> None:
        body = self._domino_bodies[index]
        self._plant.SetFreeBodyPose(self._plant_context, body, _transform(pose))
        self._plant.SetFreeBodySpatialVelocity(
            self._plant_context, body, SpatialVelocity(np.zeros(3), np.zeros(3))
        )

    # ------------------------------------------------------------------ stepping
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

    # ------------------------------------------------------------------ dominoes
    def reset(self, domino_count: int, seed: int) -> ResetReport:
        """Arm home, gripper open, then pour ``domino_count`` dominoes (seeded) and settle them."""
        if domino_count < 0:
            raise ValueError(f"domino_count must be >= 0, got {domino_count}")
        if seed < 0:  # numpy's generators take none; checked before the world changes
            raise ValueError(f"seed must be >= 0, got {seed}")
        started = wallclock.perf_counter()
        if domino_count > self._capacity:
            self._build(domino_count)
        self._sleep.wake_all(self._root)
        self._go_home()
        self._park(range(self._capacity))
        self._in_use = list(range(domino_count))
        rng = np.random.default_rng(seed)
        settings = PourSettings(
            center=tuple(self.scenario.pile_center),
            radius=self.scenario.pile_radius,
            wave_size=self.config.pour_wave_size,
        )
        pour_start = self.time
        next_index = 0
        with self._sleep.waking_by_distance():
            for size in wave_sizes(domino_count, settings.wave_size):
                poses = pour_wave(rng, size, settings, self._pile_top())
                wave = list(range(next_index, next_index + size))
                self._sleep.wake(self._root, wave)
                for index, pose in zip(wave, poses, strict=True):
                    self._set_pose(index, pose)
                next_index += size
                self.advance(WAVE_FALL_TIME)
            settled = self.settle(self.config.settle_limit - (self.time - pour_start))
        return ResetReport(
            domino_count=domino_count,
            seed=seed,
            settle_time=self.time - pour_start,
            settled=settled,
            wall_time=wallclock.perf_counter() - started,
        )

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

    def _pile_top(self) -> float:
        heights = [
            self._domino_bodies[i].EvalPoseInWorld(self._plant_context).translation()[2]
            for i in self._in_use
            if not self._is_parked(i)
        ]
        return max(heights, default=0.0)

    def _is_parked(self, index: int) -> bool:
        return bool(
            self._domino_bodies[index].EvalPoseInWorld(self._plant_context).translation()[2] < -0.2
        )

    def set_domino_poses(self, poses: Mapping[int, np.ndarray | RigidTransform]) -> None:
        """Put dominoes exactly at these poses (at rest); every other domino is parked.

        Indices beyond the capacity rebuild the plant. Useful for tests and for building
        scenes by hand.
        """
        needed = max(poses, default=-1) + 1
        if needed > self._capacity:
            self._build(needed)
        self._sleep.wake_all(self._root)
        self._park(range(self._capacity))
        self._sleep.wake(self._root, list(poses))
        for index, pose in poses.items():
            self._set_pose(index, pose)
        self._in_use = sorted(poses)

    def kick_domino(self, index: int, velocity: SpatialVelocity) -> None:
        """Give a domino a spatial velocity (world frame, about its centre), waking it."""
        self._sleep.wake(self._root, [index])
        self._plant.SetFreeBodySpatialVelocity(
            self._plant_context, self._domino_bodies[index], velocity
        )

    def domino_truth(self) -> list[DominoTruth]:
        """Every domino in the plant (parked ones have ``in_use`` False)."""
        asleep = self._sleep.asleep
        truths = []
        for index, body in enumerate(self._domino_bodies):
            pose = body.EvalPoseInWorld(self._plant_context)
            velocity = body.EvalSpatialVelocityInWorld(self._plant_context)
            x_axis = pose.rotation().matrix()[:, 0]
            truths.append(
                DominoTruth(
                    index=index,
                    name=self._domino_names[index],
                    X_WD=pose.GetAsMatrix4(),
                    velocity=np.concatenate([velocity.rotational(), velocity.translational()]),
                    upright=bool(abs(x_axis[2]) >= np.cos(UPRIGHT_TOLERANCE)),
                    asleep=bool(asleep[index]),
                    in_use=index in self._in_use,
                )
            )
        return truths

    def fixed_frames(self) -> list[FrameTransform]:
        """The welds of arm, gripper and table, parent link → child link (constant)."""
        return self._links.fixed(self._plant_context)

    def link_frames(self) -> list[FrameTransform]:
        """Arm and gripper links, each in its parent link, at the current state."""
        return self._links.moving(self._plant_context)

    def domino_frames(self) -> list[FrameTransform]:
        """world → each domino in use (body frame, named as its model: ``domino_N``)."""
        return [
            FrameTransform(
                WORLD,
                self._domino_names[index],
                self._domino_bodies[index].EvalPoseInWorld(self._plant_context),
            )
            for index in self._in_use
        ]

    def deepest_penetration(self) -> tuple[float, str]:
        """Deepest overlap [m] of a domino with anything, and which pair; sleepers included."""
        inspector = self._scene_graph.model_inspector()
        query_port = self._scene_graph.get_query_output_port()
        with self._sleep.filters_lifted(self._root):
            query = query_port.Eval(self._scene_graph.GetMyContextFromRoot(self._root))
            pairs = query.ComputePointPairPenetration()
        deepest, where = 0.0, ""
        for pair in pairs:
            names = (inspector.GetName(pair.id_A), inspector.GetName(pair.id_B))
            if pair.depth > deepest and any("domino" in name for name in names):
                deepest, where = float(pair.depth), " / ".join(names)
        return deepest, where

    # ------------------------------------------------------------------ robot
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
        swing); with live output ports (``_build``) evaluating it solves a step again."""
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

    # ------------------------------------------------------------------ cameras
    @property
    def camera_names(self) -> tuple[str, ...]:
        return self._cameras.camera_names if self._cameras is not None else ()

    def render(
        self, names: Sequence[str] | None = None, labels: bool = True
    ) -> dict[str, CameraFrame]:
        """Colour, depth and (if ``labels``) label images of the named cameras, rendered now."""
        if self._cameras is None:
            raise RuntimeError("this world was built without cameras (WorldConfig.cameras=False)")
        positions = self._plant.GetPositions(self._plant_context)
        return self._cameras.render(positions, self.time, names, labels)


def _filter_arm_self_collisions(
    plant: MultibodyPlant, scene_graph: SceneGraph, models: CellModels, fingers: Sequence[str]
) -> None:
    """No contact between the arm's links and the gripper body: the planner keeps the arm
    clear of itself (its shadow plant checks these pairs), so the simulator need not look
    for them at every step. The fingers still meet the arm, and everything meets the
    table and the dominoes."""
    finger_bodies = {plant.GetJointByName(name).child_body().index() for name in fingers}
    chain = [
        plant.get_body(b)
        for model in (models.arm, models.gripper)
        for b in plant.GetBodyIndices(model)
        if b not in finger_bodies
    ]
    scene_graph.collision_filter_manager().Apply(
        CollisionFilterDeclaration().ExcludeWithin(plant.CollectRegisteredGeometries(chain))
    )


def _transform(pose: np.ndarray | RigidTransform) -> RigidTransform:
    if isinstance(pose, RigidTransform):
        return pose
    matrix = np.asarray(pose, dtype=float)
    return RigidTransform(RotationMatrix(matrix[:3, :3]), matrix[:3, 3])


def _state_owners(plant: MultibodyPlant) -> np.ndarray:
    """Per entry of the plant's state [q; v]: the model instance it belongs to."""
    names = plant.GetStateNames(add_model_instance_prefix=True)
    instances = sorted(
        (
            plant.GetModelInstanceName(ModelInstanceIndex(i))
            for i in range(plant.num_model_instances())
        ),
        key=len,
        reverse=True,
    )
    return np.array([next(m for m in instances if name.startswith(m + "_")) for name in names])

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

The cell is built here (its plant by ``cell_plant``, from a ``world_config.WorldConfig``),
and here dominoes are poured, placed by hand and reported; the clock and the physics
steps are ``world_stepping``'s, the arm and the gripper ``world_robot``'s.
"""

from __future__ import annotations

import time as wallclock
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass
from pathlib import Path

import numpy as np
from pydrake.geometry import Meshcat, MeshcatVisualizer, MeshcatVisualizerParams, Role
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.math import SpatialVelocity
from pydrake.systems.analysis import Simulator
from pydrake.systems.controllers import InverseDynamics
from pydrake.systems.framework import DiagramBuilder

from dombot_description.cell import build_shadow_plant
from dombot_description.scenario import Scenario, load_scenario
from dombot_sim.cameras import CameraFrame, RenderScene
from dombot_sim.cell_plant import add_cell_plant, state_owners
from dombot_sim.control import ArmCommand, GripperController
from dombot_sim.frames import WORLD, FrameTransform, LinkTree
from dombot_sim.pile import PourSettings, parking_pose, pour_wave, wave_sizes
from dombot_sim.sleeping import SleepManager
from dombot_sim.world_config import WorldConfig
from dombot_sim.world_robot import GRIPPER_OPEN, WorldRobot
from dombot_sim.world_stepping import WorldStepping

UPRIGHT_TOLERANCE = np.radians(10.0)  # body x this close to vertical counts as upright
WAVE_FALL_TIME = 0.35  # s simulated between pour waves
# bytes: the least a process stepping the cell should keep off mmap (``step_block_size``)
STEP_BLOCK_MIN = 1 << 20
# Meshcat recording: 16 frames a simulated second play smoothly, and keep a whole run's
# scene.html to tens of MB (at Drake's default of 64 it is four times that)
MESHCAT_RECORDING_FPS = 16.0


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


class CellWorld(WorldStepping, WorldRobot):
    """One simulated cell. Not thread-safe: drive it from one thread. Its clock and
    physics steps are ``WorldStepping``'s, its arm and gripper ``WorldRobot``'s."""

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
        plant, scene_graph, models, domino_models = add_cell_plant(
            builder, config, scenario, capacity
        )

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
        self._state_owners = state_owners(plant)
        self._capacity = capacity
        self._root.SetTime(now)
        self._go_home()
        self._park(range(capacity))
        self._simulator.Initialize()
        self._skipped = False

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


def _transform(pose: np.ndarray | RigidTransform) -> RigidTransform:
    if isinstance(pose, RigidTransform):
        return pose
    matrix = np.asarray(pose, dtype=float)
    return RigidTransform(RotationMatrix(matrix[:3, :3]), matrix[:3, 3])

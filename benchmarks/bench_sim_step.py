"""Benchmark what a simulated second costs: CPU seconds per simulated second of the cell
(``CellWorld`` as sim_node builds it, no camera rendered) in three scripted scenes over a
settled 40-domino pile,

* ``idle``: the arm holds its home pose for 2 s,
* ``swing``: the arm follows a 2 s free-space trajectory over the pile and back,
* ``pick_place``: it grasps a flat domino next to the pile, carries and places it (also
  per step of its script: down beside the pile, grip, lift, carry, place, release),
* ``pour``: the pile itself poured and settled in a fresh world (``world.reset``),

and, with ``--node`` (not ``pour``), the same scenes driven through a ``sim_node`` process at
``real_time_factor`` 0 over its actions (that process's CPU time, psutil).

Each scene also gives a digest of every domino's final pose and the arm's joints: two
runs of the same code print the same digests, and so must a change that leaves the
physics alone. ``--baseline DIR`` runs the scenes also with the ``dombot_sim`` package
found in DIR (e.g. ``git archive main src/dombot_sim/dombot_sim | tar -x -C DIR
--strip-components=2``), alternating with this tree's, and reports the ratios measured
side by side. ``--node-allocator`` sets glibc's allocator in the world scenes as sim_node
sets it (docs/SIM.md, *Memory allocator*). Prints one JSON object on stdout (progress on stderr).
"""

from __future__ import annotations

import argparse
import hashlib
import json
import os
import signal
import subprocess
import sys
import time
from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
import psutil
import rclpy
from builtin_interfaces.msg import Duration
from control_msgs.action import FollowJointTrajectory, GripperCommand
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.trajectories import PiecewisePolynomial
from rclpy.action import ActionClient
from rosgraph_msgs.msg import Clock
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from dombot_description import DOMINO_SIZE
from dombot_description.allocator import set_mmap_threshold, tune_allocator
from dombot_description.cell import build_shadow_plant
from dombot_description.scenario import Scenario, load_scenario
from dombot_sim.sim_node import GRIPPER_ACTION, TRAJECTORY_ACTION
from dombot_sim.world import CellWorld, WorldConfig

SEED = 2026
DOMINOES = 40
PICKED = DOMINOES  # the extra domino, lying flat next to the pile
SCENES = ("idle", "swing", "pick_place", "pour")
SETTLE = 0.1  # s held after each move
GRIP_FORCE = 20.0  # N
NODE_START_TIMEOUT = 600.0  # s wall for sim_node to pour the pile and publish /clock
NODE_WAIT_TIMEOUT = 300.0  # s wall for a goal or a span of simulated time
SAMPLE_PERIOD = 0.05  # s between a trajectory goal's points
NODE_ALLOCATOR = "BENCH_SIM_STEP_NODE_ALLOCATOR"  # environment: the world as sim_node allocates
NODE_DOMAIN = "88"  # ROS_DOMAIN_ID of the sim_node runs, unless one is set
SWING = np.array([-0.5, 0.15, 0.0, 0.25, 0.0, -0.1, 0.0])  # rad: over the pile, TCP high


def log(message: str) -> None:
    print(message, file=sys.stderr, flush=True)


@dataclass(frozen=True)
class Move:
    """A rest-to-rest joint move (cubic, zero end velocities) then SETTLE s held."""

    start: np.ndarray
    goal: np.ndarray
    duration: float


@dataclass(frozen=True)
class Grip:
    """Command the fingers and wait ``wait`` s."""

    opening: float
    force: float
    wait: float


@dataclass(frozen=True)
class Hold:
    duration: float


@dataclass(frozen=True)
class Pour:
    """Pour and settle a pile in a fresh world (``world.reset``)."""

    count: int
    seed: int


Step = Move | Grip | Hold | Pour
STEP_KINDS = {"move": Move, "grip": Grip, "hold": Hold, "pour": Pour}


def to_json(script: list[Step]) -> str:
    return json.dumps(
        [
            {"kind": kind, **{k: np.asarray(v).tolist() for k, v in vars(step).items()}}
            for step in script
            for kind, cls in STEP_KINDS.items()
            if isinstance(step, cls)
        ]
    )


def from_json(text: str) -> list[Step]:
    steps = []
    for entry in json.loads(text):
        kind = STEP_KINDS[entry.pop("kind")]
        steps.append(
            kind(**{k: np.array(v) if isinstance(v, list) else v for k, v in entry.items()})
        )
    return steps


def rest_to_rest(move: Move) -> PiecewisePolynomial:
    return PiecewisePolynomial.CubicWithContinuousSecondDerivatives(
        [0.0, move.duration], np.column_stack([move.start, move.goal]), np.zeros(7), np.zeros(7)
    )


def pick_pose() -> RigidTransform:
    """The picked domino: flat on the table between the pile and the build area."""
    return RigidTransform(RotationMatrix.MakeZRotation(0.3), [0.55, -0.12, DOMINO_SIZE[2] / 2])


def scene_script(scenario: Scenario, scene: str) -> list[Step]:
    """The scene's steps, from the arm at home."""
    from dombot_sim.physics_checks import tcp_ik  # this tree's, also for a baseline's run

    home = scenario.home_position
    if scene == "idle":
        return [Hold(2.0)]
    if scene == "pour":
        return [Pour(DOMINOES, SEED)]
    if scene == "swing":
        return [Move(home, home + SWING, 1.0), Move(home + SWING, home, 1.0)]
    shadow = build_shadow_plant(scenario, grasp_opening=DOMINO_SIZE[1])
    context = shadow.plant.CreateDefaultContext()
    pick = pick_pose()
    grip = pick.rotation() @ RotationMatrix.MakeXRotation(np.pi)
    place_grip = RotationMatrix.MakeZRotation(-0.6) @ grip

    def at(rotation: RotationMatrix, xyz: list[float], seed: np.ndarray) -> np.ndarray:
        return tcp_ik(shadow, context, RigidTransform(rotation, xyz), seed)

    x, y = pick.translation()[:2]
    above = at(grip, [x, y, 0.10], home)
    down = at(grip, [x, y, 0.0135], above)
    lifted = at(grip, [x, y, 0.12], down)
    over = at(place_grip, [0.45, 0.20, 0.12], lifted)
    placed = at(place_grip, [0.45, 0.20, 0.0145], over)
    return [
        Move(home, above, 1.5),
        Move(above, down, 1.0),
        Grip(0.0, GRIP_FORCE, 1.0),
        Move(down, lifted, 1.0),
        Move(lifted, over, 1.5),
        Move(over, placed, 1.0),
        Grip(0.05, GRIP_FORCE, 0.6),
        Move(placed, over, 1.0),
    ]


def prepare(world: CellWorld) -> None:
    """The settled seeded pile of DOMINOES, plus the picked domino flat beside it, asleep."""
    world.reset(DOMINOES, SEED)
    poses = {d.index: d.X_WD for d in world.domino_truth() if d.in_use}
    world.set_domino_poses({**poses, PICKED: pick_pose()})
    if not world.settle(2.0):
        raise RuntimeError("the pile did not fall asleep again")


def run_script(world: CellWorld, script: list[Step]) -> list[float]:
    """Run the steps; CPU s per simulated s of each."""
    ratios = []
    for step in script:
        start, cpu = world.time, cpu_seconds()
        run_step(world, step)
        ratios.append((cpu_seconds() - cpu) / (world.time - start))
    return ratios


def run_step(world: CellWorld, step: Step) -> None:
    if isinstance(step, Pour):
        world.reset(step.count, step.seed)
    elif isinstance(step, Move):
        world.advance_to(world.follow_trajectory(rest_to_rest(step)) + SETTLE)
    elif isinstance(step, Grip):
        world.command_gripper(step.opening, step.force)
        world.advance(step.wait)
    else:
        world.advance(step.duration)


def digest(world: CellWorld) -> str:
    """Every domino pose and the joint positions, bit for bit."""
    state = [d.X_WD for d in world.domino_truth()] + [world.joint_state().position]
    return hashlib.sha256(b"".join(np.ascontiguousarray(a).tobytes() for a in state)).hexdigest()


def cpu_seconds() -> float:
    times = os.times()
    return times.user + times.system


def world_scene(script: list[Step]) -> dict:
    """One scene in a fresh world (with cameras, as sim_node's, none rendered): CPU s per
    simulated s of the script alone. With NODE_ALLOCATOR set, glibc's allocator is set as
    that tree's sim_node sets it (a tree without ``step_block_size`` keeps 128 KiB)."""
    if os.environ.get(NODE_ALLOCATOR):
        tune_allocator()
    world = CellWorld(WorldConfig(cameras=True, domino_capacity=DOMINOES + 1))
    if os.environ.get(NODE_ALLOCATOR) and hasattr(world, "step_block_size"):
        set_mmap_threshold(world.step_block_size)
    if not any(isinstance(step, Pour) for step in script):
        prepare(world)
    start, cpu = world.time, cpu_seconds()
    steps = run_script(world, script)
    simulated, cpu = world.time - start, cpu_seconds() - cpu
    truth = world.domino_truth()
    return {
        "simulated_s": simulated,
        "cpu_s": cpu,
        "cpu_per_simulated_s": cpu / simulated,
        "steps_cpu_per_simulated_s": steps,
        "awake_at_end": int(sum(not d.asleep for d in truth if d.in_use)),
        "picked_domino_xyz": truth[PICKED].X_WD[:3, 3].round(4).tolist(),
        "digest": digest(world),
    }


def in_subprocess(script: list[Step], env: dict[str, str]) -> dict:
    """Run one world scene in a fresh interpreter."""
    out = subprocess.run(
        [sys.executable, __file__, "--one"],
        input=to_json(script),
        env=env,
        check=True,
        capture_output=True,
        text=True,
    ).stdout
    return json.loads(out)


class NodeDriver:
    """Drives a sim_node over its actions, in simulated time (/clock)."""

    def __init__(self, arm_joints: tuple[str, ...], name: str) -> None:
        self.node = rclpy.create_node(name)  # one per run: rosout keeps a name registered
        self.arm_joints = list(arm_joints)
        self.now = -1.0
        self.node.create_subscription(Clock, "/clock", self._on_clock, 10)
        self.arm = ActionClient(self.node, FollowJointTrajectory, TRAJECTORY_ACTION)
        self.gripper = ActionClient(self.node, GripperCommand, GRIPPER_ACTION)

    def _on_clock(self, message: Clock) -> None:
        self.now = message.clock.sec + 1e-9 * message.clock.nanosec

    def spin_until(self, done: Callable[[], bool], timeout: float, what: str) -> None:
        deadline = time.monotonic() + timeout
        while not done():
            if time.monotonic() > deadline:
                raise RuntimeError(f"sim_node: no {what} within {timeout} s")
            rclpy.spin_once(self.node, timeout_sec=0.1)

    def wait_until(self, simulated: float) -> None:
        self.spin_until(lambda: self.now >= simulated, NODE_WAIT_TIMEOUT, "simulated time")

    def run_goal(self, client: ActionClient, goal) -> None:
        sent = client.send_goal_async(goal)
        self.spin_until(sent.done, NODE_WAIT_TIMEOUT, "goal response")
        result = sent.result().get_result_async()
        self.spin_until(result.done, NODE_WAIT_TIMEOUT, "goal result")

    def run(self, script: list[Step]) -> None:
        for step in script:
            start = self.now
            if isinstance(step, Move):
                self.run_goal(self.arm, self.trajectory_goal(step))
                self.wait_until(self.now + SETTLE)
            elif isinstance(step, Grip):
                goal = GripperCommand.Goal()
                goal.command.position, goal.command.max_effort = step.opening, step.force
                self.run_goal(self.gripper, goal)
                self.wait_until(start + step.wait)
            else:
                self.wait_until(start + step.duration)

    def trajectory_goal(self, move: Move) -> FollowJointTrajectory.Goal:
        spline = rest_to_rest(move)
        goal = FollowJointTrajectory.Goal()
        goal.trajectory = JointTrajectory(joint_names=self.arm_joints)
        count = round(move.duration / SAMPLE_PERIOD)
        for t in (move.duration * k / count for k in range(count + 1)):
            goal.trajectory.points.append(
                JointTrajectoryPoint(
                    positions=spline.value(t).ravel().tolist(),
                    velocities=spline.EvalDerivative(t, 1).ravel().tolist(),
                    time_from_start=Duration(sec=int(t), nanosec=round(t % 1 * 1e9)),
                )
            )
        return goal


def node_scene(script: list[Step], env: dict[str, str]) -> dict:
    """One scene through a sim_node process at real_time_factor 0 (its pile: the seeded
    DOMINOES, without the picked domino, which ROS cannot lay there)."""
    parameters = {"domino_count": DOMINOES, "seed": SEED, "real_time_factor": 0.0}
    command = [sys.executable, "-m", "dombot_sim.sim_node", "--ros-args"]
    for name, value in parameters.items():
        command += ["-p", f"{name}:={value}"]
    process = subprocess.Popen(
        command, env=env, stdout=subprocess.DEVNULL, stderr=subprocess.DEVNULL
    )
    driver = NodeDriver(load_scenario().arm_joints, f"bench_sim_step_{process.pid}")
    try:
        driver.spin_until(lambda: driver.now >= 0.0, NODE_START_TIMEOUT, "/clock")
        driver.arm.wait_for_server(timeout_sec=NODE_WAIT_TIMEOUT)
        driver.gripper.wait_for_server(timeout_sec=NODE_WAIT_TIMEOUT)
        driver.wait_until(driver.now + 0.5)
        usage = psutil.Process(process.pid)
        start, cpu = driver.now, sum(usage.cpu_times()[:2])
        driver.run(script)
        simulated, cpu = driver.now - start, sum(usage.cpu_times()[:2]) - cpu
    finally:
        driver.node.destroy_node()
        process.send_signal(signal.SIGINT)
        try:
            process.wait(timeout=30)
        except subprocess.TimeoutExpired:
            process.kill()
            process.wait()
    return {"simulated_s": simulated, "cpu_s": cpu, "cpu_per_simulated_s": cpu / simulated}


def with_package(package_dir: str | None) -> dict[str, str]:
    """The environment with ``package_dir``'s dombot_sim ahead of the installed one."""
    env = dict(os.environ)
    if package_dir:
        env["PYTHONPATH"] = package_dir + os.pathsep + env.get("PYTHONPATH", "")
    return env


def compare(
    scenes: list[str], baseline: str | None, repeats: int, run: Callable[..., dict]
) -> dict:
    """Each scene ``repeats`` times per tree, the trees alternating; medians and ratios."""
    trees: dict[str, str | None] = {"this": None}
    if baseline:
        trees["baseline"] = baseline
    results: dict = {}
    scenario = load_scenario()
    for scene in scenes:
        script = scene_script(scenario, scene)
        runs: dict[str, list[dict]] = {tree: [] for tree in trees}
        for _ in range(repeats):
            for tree, package_dir in trees.items():
                runs[tree].append(run(script, with_package(package_dir)))
                log(f"{scene} {tree}: {runs[tree][-1]['cpu_per_simulated_s']:.3f} CPU s/sim s")
        row = {tree: summary(rows) for tree, rows in runs.items()}
        if baseline:
            row["cpu_ratio_this_over_baseline"] = (
                row["this"]["cpu_per_simulated_s_median"]
                / row["baseline"]["cpu_per_simulated_s_median"]
            )
            row["same_digest"] = row["this"]["digests"] == row["baseline"]["digests"]
        results[scene] = row
    return results


def summary(rows: list[dict]) -> dict:
    return {
        "cpu_per_simulated_s_median": float(np.median([r["cpu_per_simulated_s"] for r in rows])),
        "cpu_per_simulated_s": [round(r["cpu_per_simulated_s"], 4) for r in rows],
        "simulated_s": rows[0]["simulated_s"],
        **(
            {
                "steps_cpu_per_simulated_s_median": np.median(
                    [r["steps_cpu_per_simulated_s"] for r in rows], axis=0
                )
                .round(3)
                .tolist()
            }
            if "steps_cpu_per_simulated_s" in rows[0]
            else {}
        ),
        **{k: rows[0][k] for k in ("awake_at_end", "picked_domino_xyz") if k in rows[0]},
        "digests": sorted({r["digest"] for r in rows if "digest" in r}),
    }


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("--scenes", nargs="+", choices=SCENES, default=list(SCENES))
    parser.add_argument("--baseline", help="directory holding the dombot_sim to compare with")
    parser.add_argument("--repeats", type=int, default=1, help="runs per scene and tree")
    parser.add_argument("--node", action="store_true", help="also through sim_node processes")
    parser.add_argument(
        "--node-allocator", action="store_true", help="CellWorld with sim_node's malloc settings"
    )
    parser.add_argument("--one", action="store_true", help=argparse.SUPPRESS)  # script on stdin
    args = parser.parse_args()
    if args.node_allocator:
        os.environ[NODE_ALLOCATOR] = "1"  # the --one subprocesses inherit it
    if args.one:
        print(json.dumps(world_scene(from_json(sys.stdin.read()))))
        return
    report = {
        "benchmark": "sim_step",
        "seed": SEED,
        "dominoes": DOMINOES,
        "node_allocator": args.node_allocator,
        "cpu_count": os.cpu_count(),
        "load_average_at_start": os.getloadavg(),
        "world": compare(args.scenes, args.baseline, args.repeats, in_subprocess),
    }
    node_scenes = [scene for scene in args.scenes if scene != "pour"]
    if args.node and node_scenes:
        os.environ.setdefault("ROS_DOMAIN_ID", NODE_DOMAIN)
        os.environ.setdefault("ROS_AUTOMATIC_DISCOVERY_RANGE", "LOCALHOST")
        rclpy.init()
        report["node"] = compare(node_scenes, args.baseline, args.repeats, node_scene)
        rclpy.shutdown()
    report["load_average_at_end"] = os.getloadavg()
    print(json.dumps(report, indent=2))


if __name__ == "__main__":
    main()

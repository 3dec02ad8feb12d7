"""The task core's ``Cell`` in one process, without ROS: dombot_sim's ``CellWorld``,
dombot_perception's pipeline and dombot_planner's planners, called directly.

It answers as the nodes do (``cell_client`` asks them over ROS): perception looks with
the same cameras, the planner gets the arm's joints as its start, a trajectory is
checked and splined as sim_node's action server does and judged by the same
``goal_monitor``. Time is the world's: it moves only while the arm, the fingers or a
wait run (planning and perception take none), and frames are rendered when asked for.
``benchmarks/bench_pile_picks.py`` runs the real task loop through it.
"""

from __future__ import annotations

import time
from collections import defaultdict
from collections.abc import Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from dombot_bringup.task.cell import (
    Detection,
    Detections,
    GripperEvent,
    Later,
    Meanwhile,
    Motion,
    PlacementCheck,
    PlaceRequest,
    Plan,
    Pose,
    Posture,
    Seen,
    Segment,
    StrikeRequest,
    Trajectory,
    planner_request,
    planner_strike_request,
)
from dombot_perception.frames import CameraView
from dombot_perception.pipeline import PerceptionPipeline
from dombot_perception.placement_check import PlacementConfig, check_placements
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.pick_place_plan import PickPlacePlan
from dombot_planner.plan_segments import GRIPPER_CLOSE, GRIPPER_OPEN
from dombot_planner.plan_segments import Plan as PlannerPlan
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import arm_positions, finger_opening
from dombot_planner.strike import StrikePlanner
from dombot_sim.goal_monitor import (
    DEFAULT_GOAL_TOLERANCE,
    GripperMonitor,
    Outcome,
    Tolerances,
    TrajectoryMonitor,
    joint_tolerances,
    tracking_summary,
)
from dombot_sim.trajectory import TrajectoryError, build_trajectory
from dombot_sim.world import CellWorld

# perception_node's default cameras for each question
DETECT_CAMERAS = ("camera_0", "camera_1")
PLACEMENT_CAMERAS = ("camera_2", "camera_3")
IN_HAND_CAMERAS = ("camera_0", "camera_1", "camera_2", "camera_3")
TICK = 0.01  # s simulated between goal checks: sim_node's tick (joint_state_rate 100 Hz)
GOAL_TIME_TOLERANCE = 1.0  # s: what cell_client sends as goal_time_tolerance
GRIPPER_EVENTS = {GRIPPER_OPEN: GripperEvent.OPEN, GRIPPER_CLOSE: GripperEvent.CLOSE}


@dataclass(frozen=True)
class PlanRecord:
    """One planning request as answered (``SimCell.plans``), for a benchmark's figures."""

    kind: str  # "place" | "strike"
    error: ErrorCode
    wall_s: float
    regrasped: bool = False
    nudged: bool = False


class SimCell:
    """The ``Cell`` of a ``CellWorld`` (built with cameras), a perception pipeline and the
    planners; ``plans`` records every planning request."""

    def __init__(
        self,
        world: CellWorld,
        pipeline: PerceptionPipeline,
        planner: PickPlacePlanner,
        striker: StrikePlanner | None = None,
    ) -> None:
        self.world, self.pipeline, self.planner = world, pipeline, planner
        self.striker = striker or StrikePlanner(
            planner.scenario, planner.settings, plants=planner.plants
        )
        self.spent: dict[str, float] = defaultdict(float)
        self.plans: list[PlanRecord] = []

    @property
    def sim_time(self) -> float:
        return self.world.time

    @property
    def time_spent(self) -> Mapping[str, float]:
        return self.spent

    def _advance(self, seconds: float, activity: str) -> None:
        self.world.advance(seconds)
        self.spent[activity] += seconds

    def _advance_to(self, moment: float, activity: str = "waiting") -> None:
        if moment > self.world.time:
            self._advance(moment - self.world.time, activity)

    # ------------------------------------------------------------------ the world
    def reset(self, pile: int, seed: int) -> str:
        report = self.world.reset(pile, seed)
        return (
            f"poured {report.domino_count} dominoes (seed {report.seed}); "
            + ("settled" if report.settled else "STILL MOVING")
            + f" after {report.settle_time:.2f} s simulated ({report.wall_time:.1f} s wall)"
        )

    def wait_for_sim_time(self, seconds: float) -> None:
        self._advance(seconds, "waiting")

    def joints(self) -> tuple[list[str], list[float]]:
        state = self.world.joint_state()
        return list(state.names), state.position.tolist()

    def truth(self, newer_than: float) -> list[tuple[str, Pose]]:
        return [(t.name, t.X_WD) for t in self.world.domino_truth() if t.in_use]

    def picture(self, camera: str, not_before: float) -> np.ndarray:
        self._advance_to(not_before)
        return self.world.render([camera], labels=False)[camera].rgb

    # ------------------------------------------------------------------ perception
    def _views(self, cameras: Sequence[str], not_before: float) -> list[CameraView]:
        self._advance_to(not_before)
        frames = self.world.render(list(cameras), labels=False)
        return [CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC) for f in frames.values()]

    def detect(self, not_before: float) -> Detections:
        result = self.pipeline.run(self._views(DETECT_CAMERAS, not_before))
        return Detections(
            True,
            "; ".join([f"{len(result.detections)} dominoes found", *result.warnings]),
            tuple(
                Detection(
                    d.X_WD,
                    Posture(d.posture),
                    float(d.score),
                    float(d.clearance),
                    None if not np.any(d.grasp_pose[:3, 3]) else d.grasp_pose,
                )
                for d in result.detections
            ),
            result.unexplained.reshape(-1, 3),
        )

    def detect_later(self, not_before: float) -> Later[Detections]:
        """Looks at once (in-process perception takes no simulated time)."""
        answer = self.detect(not_before)
        return Later(lambda: answer)

    def check_placement(
        self, expected: Sequence[Pose], in_hand: bool = False, not_before: float = 0.0
    ) -> PlacementCheck:
        cameras = IN_HAND_CAMERAS if in_hand else PLACEMENT_CAMERAS
        views = self._views(cameras, not_before)
        config = PlacementConfig(in_hand=in_hand)
        placements = check_placements(list(expected), views, self.pipeline, config)
        return PlacementCheck(
            True,
            status=tuple(Seen(p.status) for p in placements),
            measured=tuple(p.measured for p in placements),
            position_error=tuple(p.position_error for p in placements),
            tilt=tuple(p.tilt for p in placements),
        )

    # ------------------------------------------------------------------ planning
    def _start(self, given: Mapping[str, float] | None = None) -> tuple[np.ndarray, float | None]:
        """The arm's joints as planner_node reads ``given`` (a request's start_state), or
        /joint_states when None, and the finger opening."""
        state, scenario = self.world.joint_state(), self.planner.scenario
        names, positions = list(state.names), state.position.tolist()
        if given is not None:
            names, positions = list(given), list(given.values())
        arm = arm_positions(
            names, positions, scenario.arm_joints, self.planner.lower, self.planner.upper
        )
        return arm, finger_opening(names, positions, scenario.gripper_joints)

    def plan_place(self, request: PlaceRequest) -> Plan:
        def planned() -> PickPlacePlan:
            return self.planner.plan(planner_request(request, self._start(request.start)[0]))

        return self._plan("place", planned)

    def plan_place_later(self, request: PlaceRequest) -> Later[Plan]:
        """Plans when the answer is asked for (one process: nothing to overlap)."""
        return Later(lambda: self.plan_place(request))

    def plan_strike(self, request: StrikeRequest) -> Plan:
        def planned() -> PlannerPlan:
            return self.striker.plan(planner_strike_request(request, *self._start()))

        return self._plan("strike", planned)

    def _plan(self, kind: str, planned) -> Plan:
        """``planned()``'s plan as the node answers it; a PlanningError as a refusal."""
        began = time.monotonic()
        try:
            plan = planned()
        except PlanningError as error:
            self.plans.append(PlanRecord(kind, error.code, time.monotonic() - began))
            return Plan(False, error.code, f"{error.code.name} at {error.stage}: {error.message}")
        place = isinstance(plan, PickPlacePlan)
        regrasped, nudged = place and plan.regrasped, place and plan.nudged
        record = PlanRecord(kind, ErrorCode.SUCCESS, time.monotonic() - began, regrasped, nudged)
        self.plans.append(record)
        notes = {"domino turned in place first": regrasped, "the pads nudge the pile": nudged}
        remark = "; ".join(words for words, applies in notes.items() if applies)
        return Plan(
            True,
            ErrorCode.SUCCESS,
            "planned" + (f" ({remark})" if remark else ""),
            self._segments(plan),
            plan.held_above_place.GetAsMatrix4() if place else None,
        )

    def _segments(self, plan: PlannerPlan) -> tuple[Segment, ...]:
        names = tuple(self.planner.scenario.arm_joints)
        return tuple(
            Segment(
                sampled.label,
                Trajectory(names, sampled.times, sampled.positions, sampled.velocities),
                GRIPPER_EVENTS.get(segment.gripper_after, GripperEvent.NONE),
                float(segment.gripper_position),
                float(segment.gripper_effort),
            )
            for segment, sampled in zip(
                plan.segments, plan.sampled(self.planner.settings.sample_period), strict=True
            )
        )

    # ------------------------------------------------------------------ motion
    def execute(
        self,
        trajectory: Trajectory,
        goal_tolerance: float = 0.0,
        path_tolerance: float = 0.0,
        *,
        meanwhile: Meanwhile | None = None,
    ) -> Motion:
        """As sim_node's FollowJointTrajectory server: the trajectory checked and splined
        from where the arm is, then followed until ``goal_monitor`` has its verdict,
        ``meanwhile`` called every tick."""
        world = self.world
        velocities = trajectory.velocities if len(trajectory.velocities) else None
        try:
            spline = build_trajectory(
                trajectory.joint_names,
                trajectory.times,
                trajectory.positions,
                velocities,
                world.joint_state().position[:7],
                world.arm_limits(),
            )
        except TrajectoryError as error:
            return Motion(False, str(error))
        names = list(world.arm_joint_names)
        tolerances = Tolerances(
            path=joint_tolerances(
                [(n, path_tolerance) for n in trajectory.joint_names], names, -1.0
            ),
            goal=joint_tolerances(
                [(n, goal_tolerance) for n in trajectory.joint_names], names, DEFAULT_GOAL_TOLERANCE
            ),
            settle=GOAL_TIME_TOLERANCE,
        )
        monitor = TrajectoryMonitor(names, world.follow_trajectory(spline), tolerances)
        while True:
            self._advance(TICK, "motion")
            if meanwhile is not None:
                meanwhile()
            verdict = monitor.check(
                world.time, world.joint_state().position[:7], world.desired_arm_state()[0]
            )
            if verdict.outcome is Outcome.RUNNING:
                continue
            if verdict.outcome is Outcome.PATH_TOLERANCE_VIOLATED:
                world.hold_arm()  # as sim_node: not pressing on towards the goal
            figures = tracking_summary(monitor.worst, verdict.error)
            ok = verdict.outcome is Outcome.SUCCEEDED
            return Motion(ok, f"{verdict.message or 'goal reached'}; {figures}")

    def gripper(
        self, position: float, max_effort: float, *, meanwhile: Meanwhile | None = None
    ) -> float:
        return self._gripper_later(position, max_effort, meanwhile)()

    def gripper_later(self, position: float, max_effort: float) -> Later[float]:
        return self._gripper_later(position, max_effort, None)

    def _gripper_later(
        self, position: float, max_effort: float, meanwhile: Meanwhile | None
    ) -> Later[float]:
        """As sim_node's GripperCommand server: the fingers move to ``position`` from now
        (while the arm runs a trajectory too); taking the answer advances until they reach
        it, stall on something at the force limit, or time out: where they stopped [m]
        (``meanwhile`` called every tick)."""
        world = self.world
        try:
            world.command_gripper(position, max_effort)
        except ValueError:
            opening = world.gripper_state().opening
            return Later(lambda: opening)
        monitor = GripperMonitor(position, world.time, world.gripper_stroke_time)

        def stopped() -> float:
            while True:
                self._advance(TICK, "gripper")
                if meanwhile is not None:
                    meanwhile()
                state = world.gripper_state()
                verdict = monitor.check(
                    world.time, state.opening, state.opening_rate, state.force, state.force_limit
                )
                if verdict.done:
                    return state.opening

        return Later(stopped)

"""Hostile requests for DOM-BOT's services and input topics, sent over real DDS and judged.

``Endpoint`` is one thing to fuzz: how to send a batch of requests (concurrently) and read
an *outcome* from each reply (an error code's name, or ``ok``/``refused`` for services that
answer with a success flag and a message). ``Case`` is one request with the outcomes that
are right for it (None: any outcome, as long as there is one with a message). ``Harness``
sends batches, records a ``Report`` (requests, outcome histogram, worst reply latency,
wrong outcomes, crashes, hangs, RSS per node) and checks that a valid request is served
after each batch. The strategies (hypothesis) start from a valid request and break one
thing at a time, so the right outcome is known; ``random_*`` ones break everything.

An action's reply is a ``GoalReply`` (the goal's final status and result, or REJECTED),
sent by ``action_sender``.
"""

from __future__ import annotations

import itertools
import math
import time
from collections import Counter
from collections.abc import Callable, Collection, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field, replace
from pathlib import Path
from subprocess import Popen

import numpy as np
from action_msgs.msg import GoalStatus
from builtin_interfaces.msg import Duration, Time
from control_msgs.action import FollowJointTrajectory, GripperCommand
from control_msgs.msg import GripperCommand as GripperTarget
from geometry_msgs.msg import Point, Pose, PoseStamped, Quaternion, Vector3
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st
from nav_msgs.msg import Path as PathMessage
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.action import ActionClient
from rclpy.node import Node
from sensor_msgs.msg import JointState
from std_msgs.msg import Float64
from trajectory_msgs.msg import JointTrajectory, JointTrajectoryPoint

from dombot_description.grasp import flat_pose, upright_pose
from dombot_description.scenario import load_scenario
from dombot_msgs.msg import WheelVelocities
from dombot_msgs.srv import CheckPlacement, DetectDominoes, PlanPlace, PlanStrike, ResetSim
from dombot_planner.errors import ErrorCode
from dombot_planner.request import MAX_PILE_DOMINOES, MAX_PILE_POINTS, MAX_STANDING
from support.planning_clock import UNHURRIED
from support.ros_processes import installed_node, spin_until

SCENARIO = load_scenario()
NON_FINITE = (math.nan, math.inf, -math.inf)
HUGE = (1e12, 1e300, -1e300)
INVALID = frozenset({"INVALID_REQUEST"})
VALID_BUDGET = UNHURRIED  # the valid plan after each batch: the search ends it, not the clock

# ------------------------------------------------------------------ cases and endpoints


@dataclass(frozen=True)
class Case:
    """One request, what was broken in it, and the outcomes that are right for it."""

    request: object
    what: str
    expect: frozenset[str] | None = None  # None: any outcome with a message


@dataclass
class Endpoint:
    """A service, action or topic under test. ``send(requests, timeout, alive)`` sends
    them at once and gives each reply (None: none within the timeout, or the serving
    process died: ``alive()`` turned false); ``outcome(reply)`` names
    it; ``problem(reply)`` says what is wrong with a reply regardless of the request."""

    name: str
    node: str  # the process serving it (Harness.processes key)
    send: Callable[[list, float, Callable[[], bool]], list]
    outcome: Callable[[object], str]
    valid: Case  # served after every batch
    problem: Callable[[object], str | None] = lambda reply: (
        None if reply.message else "empty message"
    )


def planner_outcome(reply) -> str:
    return ErrorCode(reply.error_code).name


def planner_problem(reply) -> str | None:
    if not reply.message:
        return "empty message"
    if reply.success != (reply.error_code == ErrorCode.SUCCESS):
        return f"success {reply.success} with {ErrorCode(reply.error_code).name}"
    return None


def flag_outcome(reply) -> str:
    return "ok" if reply.success else "refused"


def service_sender(node: Node, service_type, name: str) -> Callable:
    client = node.create_client(service_type, name)

    def send(requests: list, timeout: float, alive: Callable[[], bool]) -> list:
        assert spin_until(node, client.service_is_ready, timeout=60), f"{name} not available"
        futures = [client.call_async(request) for request in requests]
        spin_until(node, lambda: all(f.done() for f in futures) or not alive(), timeout)
        replies = [f.result() if f.done() else None for f in futures]
        for future in futures:
            if not future.done():
                client.remove_pending_request(future)
        return replies

    return send


@dataclass(frozen=True)
class GoalReply:
    """How an action goal ended: its GoalStatus and result (None when rejected)."""

    status: int
    result: object | None


def action_sender(node: Node, action_type, name: str) -> Callable:
    """Sends goals at once; each reply a GoalReply once the goal has ended."""
    client = ActionClient(node, action_type, name)

    def send(goals: list, timeout: float, alive: Callable[[], bool]) -> list:
        assert spin_until(node, client.server_is_ready, timeout=60), f"{name} not available"
        sent = [client.send_goal_async(goal) for goal in goals]
        results: list = [None] * len(goals)

        def ended() -> bool:
            for i, future in enumerate(sent):
                if results[i] is None and future.done():
                    handle = future.result()
                    results[i] = handle.get_result_async() if handle.accepted else REJECTED
            return all(r is REJECTED or (r is not None and r.done()) for r in results)

        spin_until(node, lambda: ended() or not alive(), timeout)
        return [
            r
            if r is REJECTED
            else (GoalReply(r.result().status, r.result().result) if r and r.done() else None)
            for r in results
        ]

    return send


REJECTED = GoalReply(GoalStatus.STATUS_UNKNOWN, None)  # the goal response said no

# ------------------------------------------------------------------ the harness


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return math.nan


@dataclass
class Report:
    requests: Counter = field(default_factory=Counter)  # per endpoint
    outcomes: dict[str, Counter] = field(default_factory=dict)  # endpoint → outcome → count
    worst_latency: dict[str, float] = field(default_factory=dict)  # s, per endpoint
    wrong: list[str] = field(default_factory=list)  # wrong outcomes and bad replies
    hangs: list[str] = field(default_factory=list)
    crashes: list[str] = field(default_factory=list)
    unserved: list[str] = field(default_factory=list)  # a valid request after a batch failed
    rss_mb: dict[str, dict[str, float]] = field(default_factory=dict)  # node → before/after

    def as_json(self) -> dict:
        return {
            "requests": dict(self.requests),
            "outcomes": {name: dict(counts) for name, counts in self.outcomes.items()},
            "worst_latency_s": {k: round(v, 3) for k, v in self.worst_latency.items()},
            "wrong": self.wrong[:50],
            "wrong_count": len(self.wrong),
            "hangs": self.hangs,
            "crashes": self.crashes,
            "unserved": self.unserved,
            "rss_mb": self.rss_mb,
        }


class Harness:
    """Sends batches of cases to endpoints served by ``processes`` (name → Popen)."""

    def __init__(self, processes: dict[str, Popen], timeout: float) -> None:
        self.processes = processes
        self.timeout = timeout  # s a reply may take (generous: a search ends before its budget)
        self.report = Report()

    def running(self, endpoint: Endpoint) -> Callable[[], bool]:
        process = self.processes[endpoint.node]
        return lambda: process.poll() is None

    def alive(self, endpoint: Endpoint) -> bool:
        process = self.processes[endpoint.node]
        if process.poll() is None:
            return True
        note = f"{endpoint.node} exited with {process.returncode} during {endpoint.name}"
        if note not in self.report.crashes:
            self.report.crashes.append(note)
        return False

    def rss(self, stage: str) -> None:
        for name, process in self.processes.items():
            if process.poll() is None:
                self.report.rss_mb.setdefault(name, {})[stage] = round(rss_mb(process.pid), 1)

    def warm_up(self, endpoint: Endpoint, timeout: float = 300.0) -> None:
        """Send the valid request until it is served (nodes start, cameras begin to
        publish); these requests are not counted."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and self.alive(endpoint):
            [reply] = endpoint.send([endpoint.valid.request], self.timeout, self.running(endpoint))
            if reply is not None and endpoint.outcome(reply) in endpoint.valid.expect:
                return
            time.sleep(1.0)
        raise AssertionError(f"{endpoint.name}: the valid request was not served in {timeout} s")

    def run(self, endpoint: Endpoint, cases: Sequence[Case]) -> list:
        """Send ``cases`` at once, judge every reply, then check a valid request is served."""
        replies = self._send(endpoint, list(cases))
        self._send(endpoint, [endpoint.valid], after_batch=True)
        return replies

    def _send(self, endpoint: Endpoint, cases: list[Case], after_batch: bool = False) -> list:
        if not self.alive(endpoint):  # counted: a crash ends a long run's loop too
            self.report.requests[endpoint.name] += len(cases)
            return [None] * len(cases)
        began = time.monotonic()
        requests = [case.request for case in cases]
        replies = endpoint.send(requests, self.timeout, self.running(endpoint))
        latency = time.monotonic() - began
        report = self.report
        report.requests[endpoint.name] += len(cases)
        worst = report.worst_latency.get(endpoint.name, 0.0)
        report.worst_latency[endpoint.name] = max(worst, latency)
        outcomes = report.outcomes.setdefault(endpoint.name, Counter())
        for case, reply in zip(cases, replies, strict=True):
            label = f"{endpoint.name} {case.what}"
            if reply is None:
                if self.alive(endpoint):
                    report.hangs.append(f"{label}: no reply within {self.timeout} s")
                outcomes["no reply"] += 1
                continue
            outcome = endpoint.outcome(reply)
            outcomes[outcome] += 1
            problem = endpoint.problem(reply)
            if problem is None and case.expect is not None and outcome not in case.expect:
                problem = f"{outcome}, expected {sorted(case.expect)}"
            if problem is not None:
                (report.unserved if after_batch else report.wrong).append(
                    f"{label}: {problem} ({getattr(reply, 'message', '')[:200]})"
                )
        return replies


# ------------------------------------------------------------------ values


def pose(x: float, y: float, z: float, q: Sequence[float] = (1.0, 0.0, 0.0, 0.0)) -> Pose:
    w, qx, qy, qz = q
    return Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(w=w, x=qx, y=qy, z=qz))


def pose_of(transform) -> Pose:
    q = transform.rotation().ToQuaternion()
    return pose(*transform.translation(), (q.w(), q.x(), q.y(), q.z()))


def any_float() -> st.SearchStrategy[float]:
    return st.one_of(st.sampled_from([*NON_FINITE, *HUGE, -1.0, 0.0]), st.floats())


def non_finite() -> st.SearchStrategy[float]:
    return st.sampled_from(NON_FINITE)


def bad_quaternion() -> st.SearchStrategy[tuple[float, float, float, float]]:
    """Zero, non-unit (beyond the 1e-3 tolerance) or non-finite quaternions."""
    scaled = st.tuples(
        st.one_of(st.floats(0.0, 0.99), st.floats(1.01, 1e6)),
        st.tuples(*[st.floats(-1, 1)] * 4).filter(lambda q: np.linalg.norm(q) > 0.1),
    ).map(lambda sq: tuple(sq[0] * np.array(sq[1]) / np.linalg.norm(sq[1])))
    broken = st.tuples(non_finite(), st.floats(-1, 1), st.floats(-1, 1), st.floats(-1, 1))
    return st.one_of(st.just((0.0, 0.0, 0.0, 0.0)), scaled, broken)


def broken_pose(base: Pose) -> st.SearchStrategy[Pose]:
    """``base`` with a non-finite coordinate or a bad quaternion."""

    def with_coordinate(args: tuple[int, float]) -> Pose:
        index, value = args
        xyz = [base.position.x, base.position.y, base.position.z]
        xyz[index] = value
        o = base.orientation
        return pose(*xyz, (o.w, o.x, o.y, o.z))

    p = base.position
    return st.one_of(
        st.tuples(st.integers(0, 2), non_finite()).map(with_coordinate),
        bad_quaternion().map(lambda q: pose(p.x, p.y, p.z, q)),
    )


def huge_count(most: int) -> st.SearchStrategy[int]:
    """Counts just over and far over a documented maximum (10k and more)."""
    return st.sampled_from([most + 1, 10_000])


# ------------------------------------------------------------------ /plan_place, /plan_strike

ARM = list(SCENARIO.arm_joints)
HOME = SCENARIO.home_position.tolist()
PICK = flat_pose(0.60, -0.28, 0.4)
PLACE = upright_pose(0.55, 0.15, 0.3)
RUN = [
    upright_pose(0.55 + i * 0.0288 * math.cos(0.3), 0.15 + i * 0.0288 * math.sin(0.3), 0.3)
    for i in range(3)
]


def home_state(fingers: bool = False) -> JointState:
    names = [*ARM, *SCENARIO.gripper_joints] if fingers else list(ARM)
    return JointState(name=names, position=[*HOME, *([0.017, 0.017] if fingers else [])])


def valid_place() -> PlanPlace.Request:
    return PlanPlace.Request(
        start_state=home_state(), domino_pose=pose_of(PICK), place_pose=pose_of(PLACE)
    )


def valid_strike() -> PlanStrike.Request:
    return PlanStrike.Request(
        start_state=home_state(fingers=True),
        domino_pose=pose_of(RUN[0]),
        standing_dominoes=[pose_of(p) for p in RUN[1:]],
    )


def changed(request, **fields):
    """A copy of a ROS request with ``fields`` replaced (messages are mutable)."""
    copy = type(request)()
    for name in request.get_fields_and_field_types():
        setattr(copy, name, fields.get(name, getattr(request, name)))
    return copy


def bad_start_states() -> st.SearchStrategy[tuple[str, JointState]]:
    """Wrong, missing or duplicate names, wrong lengths, beyond-limit positions and
    velocities, non-finite values."""
    names = st.sampled_from(["", "iiwa_joint_8", "joint_1", "wsg_left_finger_joint", "ä" * 300])

    def wrong_name(args: tuple[int, str]) -> JointState:
        i, name = args
        state = home_state()
        state.name[i] = name
        return state

    def duplicate(i: int) -> JointState:
        state = home_state()
        return JointState(name=[*state.name, ARM[i]], position=[*state.position, HOME[i]])

    def short(n: int) -> JointState:
        return JointState(name=ARM, position=HOME[:n])

    def beyond(args: tuple[int, float]) -> JointState:
        i, value = args
        position = list(HOME)
        position[i] = value
        return JointState(name=ARM, position=position)

    def velocities(values: list[float]) -> JointState:
        return JointState(name=ARM, position=HOME, velocity=values)

    return st.one_of(
        st.tuples(st.integers(0, 6), names).map(lambda a: ("wrong joint name", wrong_name(a))),
        st.integers(0, 6).map(lambda i: ("duplicate joint name", duplicate(i))),
        st.integers(0, 6).map(lambda n: ("positions shorter than names", short(n))),
        st.tuples(st.integers(0, 6), st.sampled_from([3.2, -3.2, 10.0, *NON_FINITE])).map(
            lambda a: ("position beyond limits", beyond(a))
        ),
        st.one_of(
            st.lists(st.floats(-1, 1), min_size=1, max_size=6),
            st.lists(st.sampled_from([20.0, -50.0, *NON_FINITE]), min_size=7, max_size=7),
        ).map(lambda v: ("velocities wrong length or beyond limits", velocities(v))),
    )


def bad_budget() -> st.SearchStrategy[float]:
    return st.one_of(st.sampled_from([*NON_FINITE, *HUGE, 3601.0]), st.floats(-1e300, -1e-9))


def place_cases() -> st.SearchStrategy[Case]:
    """/plan_place requests with one thing broken; the right code for each is known."""
    base = valid_place()
    domino = base.domino_pose

    def arrays(args: tuple[str, int]) -> Case:
        name, count = args
        if name == "pile_points":
            points = [Point(x=0.6, y=-0.28, z=0.01)] * count
            return Case(changed(base, pile_points=points), "pile_points over the maximum", INVALID)
        return Case(changed(base, **{name: [domino] * count}), f"{name} over the maximum", INVALID)

    def holding(offset: float) -> Case:
        request = changed(base, holding=True, domino_pose=pose_of(PLACE))
        request.domino_pose.position.x += offset
        # far enough off, it is also off the table: either refusal is right
        refused = INVALID | {"OUTSIDE_WORKSPACE"}
        return Case(request, "holding a domino far from the TCP", refused)

    return st.one_of(
        st.sampled_from(["domino_pose", "place_pose", "grasp_pose"]).flatmap(
            lambda name: broken_pose(domino).map(
                lambda p: Case(changed(base, **{name: p}), f"broken {name}", INVALID)
            )
        ),
        st.sampled_from(["standing_dominoes", "pile_dominoes"]).flatmap(
            lambda name: broken_pose(domino).map(
                lambda p: Case(changed(base, **{name: [p]}), f"broken {name}", INVALID)
            )
        ),
        bad_start_states().map(lambda s: Case(changed(base, start_state=s[1]), s[0], INVALID)),
        bad_budget().map(lambda b: Case(changed(base, time_budget=b), "bad time_budget", INVALID)),
        st.one_of(non_finite(), st.floats(-1e300, -1e-9), st.sampled_from([0.2, 1e300])).map(
            lambda w: Case(changed(base, grasp_width=w), "bad grasp_width", INVALID)
        ),
        st.one_of(
            st.tuples(st.just("standing_dominoes"), huge_count(MAX_STANDING)),
            st.tuples(st.just("pile_dominoes"), huge_count(MAX_PILE_DOMINOES)),
            st.tuples(st.just("pile_points"), st.sampled_from([MAX_PILE_POINTS + 1, 100_000])),
        ).map(arrays),
        st.floats(0.06, 0.3).map(holding),
        st.sampled_from([(-0.60, 0.0), (0.0, -0.9), (0.2, 0.0), (0.6, 0.0, 1.0)]).map(
            lambda xy: Case(
                changed(base, domino_pose=pose(*xy, *([0.004] if len(xy) == 2 else []))),
                "domino outside the workspace",
                frozenset({"OUTSIDE_WORKSPACE"}),
            )
        ),
    )


def strike_cases() -> st.SearchStrategy[Case]:
    base = valid_strike()

    def sweep(v: tuple[float, float, float]) -> Case:
        return Case(changed(base, sweep_direction=Vector3(x=v[0], y=v[1], z=v[2])), "bad sweep")

    return st.one_of(
        broken_pose(base.domino_pose).map(
            lambda p: Case(changed(base, domino_pose=p), "broken domino_pose", INVALID)
        ),
        broken_pose(base.domino_pose).map(
            lambda p: Case(changed(base, standing_dominoes=[p]), "broken standing", INVALID)
        ),
        bad_start_states().map(lambda s: Case(changed(base, start_state=s[1]), s[0], INVALID)),
        bad_budget().map(lambda b: Case(changed(base, time_budget=b), "bad time_budget", INVALID)),
        st.tuples(
            st.sampled_from(["push_distance", "push_speed"]),
            st.one_of(st.sampled_from([*NON_FINITE, *HUGE, 0.6]), st.floats(-1e300, -1e-9)),
        ).map(lambda a: Case(changed(base, **{a[0]: a[1]}), f"bad {a[0]}", INVALID)),
        st.one_of(
            st.tuples(non_finite(), st.floats(-1, 1), st.just(0.0)),
            st.tuples(st.floats(2, 1e6), st.just(0.0), st.just(0.0)),
            st.just((0.0, 0.0, 1.0)),
        ).map(lambda v: replace(sweep(v), expect=INVALID)),
        huge_count(MAX_STANDING).map(
            lambda n: Case(
                changed(base, standing_dominoes=[base.domino_pose] * n),
                "standing_dominoes over the maximum",
                INVALID,
            )
        ),
    )


def random_pose() -> st.SearchStrategy[Pose]:
    return st.tuples(*[any_float()] * 7).map(lambda v: pose(v[0], v[1], v[2], v[3:]))


def random_place() -> st.SearchStrategy[Case]:
    """Everything drawn freely: any code, but one with a message."""
    return st.builds(
        lambda d, p, g, w, b, h: Case(
            changed(
                valid_place(),
                domino_pose=d,
                place_pose=p,
                grasp_pose=g,
                grasp_width=w,
                time_budget=b,
                holding=h,
            ),
            "random",
        ),
        random_pose(),
        random_pose(),
        random_pose(),
        any_float(),
        any_float(),
        st.booleans(),
    )


# ------------------------------------------------------------------ perception, sim

FAR_FUTURE = Time(sec=2**31 - 1, nanosec=999_999_999)
CAMERAS = [camera.name for camera in SCENARIO.cameras]


def unknown_cameras() -> st.SearchStrategy[list[str]]:
    name = st.one_of(st.sampled_from(["camera_9", "", "CAMERA_0", "/camera_0"]), st.text())
    return st.lists(name, min_size=1, max_size=3).filter(lambda n: not set(n) <= set(CAMERAS))


def detect_cases() -> st.SearchStrategy[Case]:
    refused = frozenset({"refused"})
    return st.one_of(
        unknown_cameras().map(
            lambda n: Case(DetectDominoes.Request(cameras=n), "unknown camera", refused)
        ),
        st.just(
            Case(DetectDominoes.Request(not_before=FAR_FUTURE), "far-future not_before", refused)
        ),
        st.lists(st.sampled_from(CAMERAS[:2]), min_size=2, max_size=6).map(
            lambda n: Case(DetectDominoes.Request(cameras=n), "repeated cameras")
        ),
    )


def check_cases() -> st.SearchStrategy[Case]:
    refused = frozenset({"refused"})
    standing = pose_of(PLACE)

    def request(**fields) -> CheckPlacement.Request:
        return CheckPlacement.Request(expected=[standing], **fields)

    return st.one_of(
        broken_pose(standing).map(
            lambda p: Case(CheckPlacement.Request(expected=[p]), "broken expected", refused)
        ),
        unknown_cameras().map(lambda n: Case(request(cameras=n), "unknown camera", refused)),
        st.one_of(non_finite(), st.floats(-1e300, -1e-9)).map(
            lambda r: Case(request(search_radius=r), "bad search_radius", refused)
        ),
        st.sampled_from([1e300, 5.0]).map(lambda r: Case(request(search_radius=r), "huge radius")),
        st.just(Case(request(not_before=FAR_FUTURE), "far-future not_before", refused)),
        st.just(
            Case(
                CheckPlacement.Request(expected=[pose_of(PICK)], in_hand=True),
                "in_hand flat",
                refused,
            )
        ),
        huge_count(1000).map(
            lambda n: Case(
                CheckPlacement.Request(expected=[standing] * n),
                "expected over the maximum",
                refused,
            )
        ),
    )


def reset_cases() -> st.SearchStrategy[Case]:
    return st.one_of(
        st.integers(201, 2**32 - 1).map(
            lambda n: Case(
                ResetSim.Request(domino_count=n), "domino_count over 200", frozenset({"refused"})
            )
        ),
        st.tuples(st.integers(0, 2), st.integers(-(2**63), 2**63 - 1)).map(
            lambda a: Case(
                ResetSim.Request(domino_count=a[0], seed=a[1]),
                "any seed",
                frozenset({"ok" if a[1] >= 0 else "refused"}),
            )
        ),
    )


# ------------------------------------------------------------------ arm and gripper actions

TRAJECTORY_CODES = {
    value: name
    for name, value in vars(FollowJointTrajectory.Result).items()
    if name.isupper() and isinstance(value, int)
}
INVALID_GOAL = frozenset({"INVALID_GOAL"})
INVALID_JOINTS = frozenset({"INVALID_JOINTS"})


def duration(seconds: float) -> Duration:
    whole = math.floor(seconds)
    return Duration(sec=int(whole), nanosec=int((seconds - whole) * 1e9))


def trajectory_goal(
    names: Sequence[str], points: Sequence[tuple[float, Sequence[float]]], **fields
) -> FollowJointTrajectory.Goal:
    """A goal through ``points`` (time from start [s], positions); ``fields``: per-point
    lists set on every point (velocities, accelerations, effort)."""
    trajectory = JointTrajectory(joint_names=list(names))
    for seconds, positions in points:
        point = JointTrajectoryPoint(positions=list(positions), time_from_start=duration(seconds))
        for name, values in fields.items():
            setattr(point, name, list(values))
        trajectory.points.append(point)
    return FollowJointTrajectory.Goal(trajectory=trajectory)


def valid_trajectory() -> FollowJointTrajectory.Goal:
    """Home in 0.5 s: served from wherever the arm is after the fuzzed goals (none moves it)."""
    return trajectory_goal(ARM, [(0.5, HOME)])


def trajectory_outcome(reply: GoalReply) -> str:
    if reply.result is None:
        return "REJECTED"
    return TRAJECTORY_CODES.get(reply.result.error_code, str(reply.result.error_code))


def trajectory_problem(reply: GoalReply) -> str | None:
    """Aborted goals carry a code (or were preempted), succeeded ones SUCCESSFUL, all a text."""
    if reply.result is None:
        return None
    code, text = reply.result.error_code, reply.result.error_string
    if not text:
        return "empty error_string"
    succeeded = reply.status == GoalStatus.STATUS_SUCCEEDED
    if succeeded != (code == 0) and not (code == 0 and "preempted" in text):
        return f"status {reply.status} with error_code {code}"
    return None


def trajectory_cases() -> st.SearchStrategy[Case]:
    """Goals with one thing broken: the code is known for each; none moves the arm."""
    names = st.sampled_from(["", "elbow", "iiwa_joint_8", "wsg_left_finger_joint", "ä" * 300])

    def renamed(args: tuple[int, str]) -> Case:
        i, name = args
        wrong = [*ARM[:i], name, *ARM[i + 1 :]]
        return Case(trajectory_goal(wrong, [(1.0, HOME)]), "wrong joint name", INVALID_JOINTS)

    def twice(i: int) -> Case:
        goal = trajectory_goal([*ARM, ARM[i]], [(1.0, [*HOME, HOME[i]])])
        return Case(goal, "duplicate joint name", INVALID_JOINTS)

    def missing(n: int) -> Case:
        return Case(trajectory_goal(ARM[:n], [(1.0, HOME[:n])]), "missing joints", INVALID_JOINTS)

    def wrong_length(n: int) -> Case:
        return Case(trajectory_goal(ARM, [(1.0, HOME[:1] * n)]), f"{n} positions", INVALID_GOAL)

    def beyond(args: tuple[int, float]) -> Case:
        i, value = args
        position = list(HOME)
        position[i] = value
        return Case(trajectory_goal(ARM, [(1.0, position)]), "position beyond limits", INVALID_GOAL)

    def fast(args: tuple[int, float]) -> Case:
        i, value = args
        velocity = [0.0] * 7
        velocity[i] = value
        goal = trajectory_goal(ARM, [(1.0, HOME)], velocities=velocity)
        return Case(goal, "velocity beyond limits or not finite", INVALID_GOAL)

    def jump(i: int) -> Case:  # a 1 rad step in 10 ms: the interpolated speed is far over
        position = list(HOME)
        position[i] += 1.0 if position[i] < 0 else -1.0
        return Case(
            trajectory_goal(ARM, [(0.01, position)]), "too fast between points", INVALID_GOAL
        )

    def times(seconds: list[float]) -> Case:
        goal = trajectory_goal(ARM, [(t, HOME) for t in seconds])
        return Case(goal, "times not increasing", INVALID_GOAL)

    def ignored(args: tuple[str, list[float]]) -> Case:
        field_name, values = args
        goal = trajectory_goal(ARM, [(1.0, HOME)], **{field_name: values})
        return Case(goal, f"bad {field_name}", INVALID_GOAL)

    def huge(n: int) -> Case:
        goal = trajectory_goal(ARM, [(0.5 + 0.01 * i, HOME) for i in range(n)])
        return Case(goal, f"{n} points", INVALID_GOAL)

    far_start = [h + (0.5 if h < 0 else -0.5) for h in HOME]
    empty = Case(
        trajectory_goal([], []), "empty goal", frozenset({"INVALID_JOINTS", "INVALID_GOAL"})
    )
    multi_dof = trajectory_goal(ARM, [(1.0, HOME)])
    multi_dof.multi_dof_trajectory.joint_names = ["base"]
    return st.one_of(
        st.tuples(st.integers(0, 6), names).map(renamed),
        st.integers(0, 6).map(twice),
        st.integers(0, 6).map(missing),
        st.sampled_from([0, 1, 6, 8, 100_000]).map(wrong_length),
        st.tuples(st.integers(0, 6), st.sampled_from([3.2, -3.2, 10.0, 1e300, *NON_FINITE])).map(
            beyond
        ),
        st.tuples(st.integers(0, 6), st.sampled_from([20.0, -50.0, 1e300, *NON_FINITE])).map(fast),
        st.integers(0, 6).map(jump),
        st.one_of(
            st.lists(st.sampled_from([0.0, 0.5, 1.0]), min_size=2, max_size=5).filter(
                lambda t: any(b <= a for a, b in itertools.pairwise(t))
            ),
            st.just([-1.0, 1.0]),
        ).map(times),
        st.tuples(
            st.sampled_from(["accelerations", "effort"]),
            st.one_of(
                st.lists(st.floats(-100, -1), min_size=1, max_size=6),  # negative and short
                st.lists(st.sampled_from([*NON_FINITE, 1.0]), min_size=7, max_size=7).filter(
                    lambda v: not all(map(math.isfinite, v))
                ),
            ),
        ).map(ignored),
        st.sampled_from([10_001, 100_000]).map(huge),
        st.just(
            Case(trajectory_goal(ARM, [(0.0, far_start)]), "t = 0 far from here", INVALID_GOAL)
        ),
        st.just(Case(trajectory_goal(ARM, []), "no points", INVALID_GOAL)),
        st.just(empty),
        st.just(Case(multi_dof, "multi_dof_trajectory", INVALID_JOINTS)),
    )


def gripper_goal(position: float, max_effort: float = 0.0) -> GripperCommand.Goal:
    return GripperCommand.Goal(command=GripperTarget(position=position, max_effort=max_effort))


def gripper_outcome(reply: GoalReply) -> str:
    names = {v: k for k, v in vars(GoalStatus).items() if k.startswith("STATUS_")}
    return "REJECTED" if reply.result is None else names[reply.status].removeprefix("STATUS_")


def gripper_problem(reply: GoalReply) -> str | None:
    """GripperCommand's result has no text (the reason is in the node's log): an aborted
    goal must not claim it reached the opening."""
    if reply.result is not None and reply.status == GoalStatus.STATUS_ABORTED:
        return "aborted but reached_goal" if reply.result.reached_goal else None
    return None


def gripper_cases() -> st.SearchStrategy[Case]:
    """Openings outside the 0–0.11 m stroke or not finite, efforts negative or not finite."""
    aborted = frozenset({"ABORTED"})
    return st.one_of(
        st.one_of(
            st.sampled_from([*NON_FINITE, *HUGE, -1e-9, 0.111]), st.floats(-1e300, -1e-6)
        ).map(lambda p: Case(gripper_goal(p), "opening outside the stroke", aborted)),
        st.one_of(st.sampled_from([*NON_FINITE, -1e300]), st.floats(-1e300, -1e-6)).map(
            lambda e: Case(gripper_goal(0.05, e), "bad max_effort", aborted)
        ),
        st.sampled_from([1e6, 1e300]).map(
            lambda e: Case(
                gripper_goal(0.05, e), "huge max_effort (capped)", frozenset({"SUCCEEDED"})
            )
        ),
    )


def action_endpoints(node: Node) -> dict[str, tuple[Endpoint, Callable[[], st.SearchStrategy]]]:
    """sim_node's arm and gripper actions with their case strategies."""
    return {
        "/arm_controller/follow_joint_trajectory": (
            Endpoint(
                "/arm_controller/follow_joint_trajectory",
                "sim_node",
                action_sender(
                    node, FollowJointTrajectory, "/arm_controller/follow_joint_trajectory"
                ),
                trajectory_outcome,
                Case(valid_trajectory(), "valid", frozenset({"SUCCESSFUL"})),
                trajectory_problem,
            ),
            trajectory_cases,
        ),
        "/gripper_controller/gripper_cmd": (
            Endpoint(
                "/gripper_controller/gripper_cmd",
                "sim_node",
                action_sender(node, GripperCommand, "/gripper_controller/gripper_cmd"),
                gripper_outcome,
                Case(gripper_goal(0.05), "valid", frozenset({"SUCCEEDED"})),
                gripper_problem,
            ),
            gripper_cases,
        ),
    }


# ------------------------------------------------------------------ layer_node


class LayerProbe:
    """Publishes to layer_node's input topics and reads what its status stream says."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.status: list[WheelVelocities] = []
        node.create_subscription(WheelVelocities, "/layer/wheel_velocities", self.status.append, 50)
        self.radius_pub = node.create_publisher(Float64, "/layer/target_radius", 10)
        self.path_pub = node.create_publisher(PathMessage, "/layer/path", 10)
        self.sentinel = 1.0

    def _confirm(
        self,
        publish: Callable[[], None],
        seen: Callable[[WheelVelocities], bool],
        timeout: float,
        alive: Callable[[], bool],
    ) -> WheelVelocities | None:
        """Publish until a status ``seen`` arrives (a subscriber may join late)."""
        self.status.clear()

        def arrived() -> bool:
            if any(seen(s) for s in self.status) or not alive():
                return True
            publish()
            return False

        if not spin_until(self.node, arrived, timeout) or not alive():
            return None
        return next(s for s in self.status if seen(s))

    def radius(
        self, radius: float, timeout: float, alive: Callable[[], bool]
    ) -> WheelVelocities | None:
        def seen(s: WheelVelocities) -> bool:
            if math.isnan(radius):
                return s.status == WheelVelocities.STATUS_INVALID and "NaN" in s.message
            return s.deposit_radius == radius

        return self._confirm(
            lambda: self.radius_pub.publish(Float64(data=radius)), seen, timeout, alive
        )

    def path(
        self, path: PathMessage, timeout: float, alive: Callable[[], bool]
    ) -> WheelVelocities | None:
        """The status that answered ``path``: a sentinel radius published after it must
        arrive (the node handled the path and still serves); the answer is the last
        status about a path before the sentinel's."""
        self.status.clear()
        self.path_pub.publish(path)
        self.sentinel += 1e-6
        sentinel = self.radius(self.sentinel, timeout, alive)
        if sentinel is None:
            return None
        about = [s for s in self.status if s.message.startswith("path")]
        return about[-1] if about else sentinel


def layer_outcome(reply: WheelVelocities) -> str:
    names = {v: k for k, v in vars(WheelVelocities).items() if k.startswith("STATUS_")}
    return names.get(reply.status, str(reply.status))


def radius_cases() -> st.SearchStrategy[Case]:
    return st.one_of(
        st.just(Case(math.nan, "NaN radius", frozenset({"STATUS_INVALID"}))),
        st.one_of(
            st.sampled_from([math.inf, -math.inf, *HUGE, 0.0, -0.0, 1e-300]),
            st.floats(allow_nan=False),
        ).map(lambda r: Case(r, "any radius", frozenset({"STATUS_OK", "STATUS_UNREACHABLE"}))),
    )


def path_message(points: Sequence[tuple[float, float]]) -> PathMessage:
    path = PathMessage()
    path.header.frame_id = "layer_start"
    for x, y in points:
        stamped = PoseStamped()
        stamped.pose.position.x, stamped.pose.position.y = x, y
        path.poses.append(stamped)
    return path


def path_cases() -> st.SearchStrategy[Case]:
    coordinate = st.one_of(any_float(), st.floats(-2, 2))
    return st.one_of(
        st.lists(st.tuples(coordinate, coordinate), max_size=8).map(
            lambda p: Case(path_message(p), "random path")
        ),
        st.integers(0, 3).map(lambda n: Case(path_message([(0.0, 0.0)] * n), "degenerate path")),
        st.sampled_from([10_001, 100_000]).map(
            lambda n: Case(path_message([(0.001 * i, 0.0) for i in range(n)]), f"path of {n} poses")
        ),
    )


def layer_parameter_cases() -> st.SearchStrategy[Case]:
    names = st.sampled_from(
        [
            "forward_speed",
            "deposit_spacing",
            "command_rate",
            "geometry.d_tw",
            "geometry.wheel_radius",
        ]
    )
    return st.tuples(names, st.one_of(any_float(), st.just(-0.0))).map(
        lambda a: Case(
            Parameter(
                name=a[0],
                value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=a[1]),
            ),
            f"{a[0]} = {a[1]}",
            None if (math.isfinite(a[1]) and a[1] > 0) else frozenset({"refused"}),
        )
    )


def layer_endpoints(node: Node) -> list[Endpoint]:
    """/layer/target_radius, /layer/path, layer_node's parameters."""
    probe = LayerProbe(node)
    set_parameters = service_sender(node, SetParameters, "/layer_node/set_parameters")

    def one_by_one(send_one):
        return lambda items, timeout, alive: [send_one(item, timeout, alive) for item in items]

    def parameters(items, timeout, alive):
        requests = [SetParameters.Request(parameters=[p]) for p in items]
        replies = set_parameters(requests, timeout, alive)
        return [r.results[0] if r is not None else None for r in replies]

    restore = Parameter(
        name="forward_speed",
        value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=0.1),
    )
    no_problem = lambda reply: None  # noqa: E731  a status always carries a state
    return [
        Endpoint(
            "/layer/target_radius",
            "layer_node",
            one_by_one(probe.radius),
            layer_outcome,
            Case(0.5, "valid radius", frozenset({"STATUS_OK"})),
            no_problem,
        ),
        Endpoint(
            "/layer/path",
            "layer_node",
            one_by_one(probe.path),
            layer_outcome,
            Case(
                path_message([(0, 0), (0.1, 0), (0.2, 0)]), "valid path", frozenset({"STATUS_OK"})
            ),
            no_problem,
        ),
        Endpoint(
            "/layer_node/set_parameters",
            "layer_node",
            parameters,
            lambda r: "accepted" if r.successful else "refused",
            Case(restore, "restore forward_speed", frozenset({"accepted"})),
            lambda r: None if r.successful or r.reason else "refused without a reason",
        ),
    ]


def service_endpoints(node: Node) -> dict[str, tuple[Endpoint, Callable[[], st.SearchStrategy]]]:
    """Every service endpoint with its case strategy."""
    return {
        "/plan_place": (
            Endpoint(
                "/plan_place",
                "planner_node",
                service_sender(node, PlanPlace, "/plan_place"),
                planner_outcome,
                Case(
                    changed(valid_place(), time_budget=VALID_BUDGET),
                    "valid",
                    frozenset({"SUCCESS"}),
                ),
                planner_problem,
            ),
            lambda: st.one_of(place_cases(), random_place()),
        ),
        "/plan_strike": (
            Endpoint(
                "/plan_strike",
                "planner_node",
                service_sender(node, PlanStrike, "/plan_strike"),
                planner_outcome,
                Case(
                    changed(valid_strike(), time_budget=VALID_BUDGET),
                    "valid",
                    frozenset({"SUCCESS"}),
                ),
                planner_problem,
            ),
            strike_cases,
        ),
        "/perception/detect": (
            Endpoint(
                "/perception/detect",
                "perception_node",
                service_sender(node, DetectDominoes, "/perception/detect"),
                flag_outcome,
                Case(DetectDominoes.Request(), "valid", frozenset({"ok"})),
            ),
            detect_cases,
        ),
        "/perception/check_placement": (
            Endpoint(
                "/perception/check_placement",
                "perception_node",
                service_sender(node, CheckPlacement, "/perception/check_placement"),
                flag_outcome,
                Case(CheckPlacement.Request(expected=[pose_of(PLACE)]), "valid", frozenset({"ok"})),
            ),
            check_cases,
        ),
        "/sim/reset": (
            Endpoint(
                "/sim/reset",
                "sim_node",
                service_sender(node, ResetSim, "/sim/reset"),
                flag_outcome,
                Case(ResetSim.Request(domino_count=3, seed=1), "valid", frozenset({"ok"})),
            ),
            reset_cases,
        ),
    }


# ------------------------------------------------------------------ running


SIM_ARGUMENTS = ("domino_count:=3", "camera_rate:=2.0", "ground_truth_rate:=1.0")


FUZZED_NODES = {
    "planner_node": ("dombot_planner", ()),
    "sim_node": ("dombot_sim", SIM_ARGUMENTS),
    "perception_node": ("dombot_perception", ("use_sim_time:=true",)),
    "layer_node": ("dombot_layer", ()),
}
NEEDS = {"perception_node": {"sim_node"}}  # its images and clock


@contextmanager
def fuzzed_nodes(
    logs: Path, serving: Collection[str] = tuple(FUZZED_NODES)
) -> Iterator[dict[str, Popen]]:
    """The ``serving`` nodes and those they need: planner_node, sim_node (3 dominoes),
    perception_node (sim time), layer_node, each its own process, logging to
    ``logs``/NAME.log (a fuzzed node logs every refusal: a pipe nobody reads would fill up
    and block it)."""
    wanted = set(serving).union(*(NEEDS.get(name, set()) for name in serving))
    with ExitStack() as stack:
        processes = {}
        for name, (package, parameters) in FUZZED_NODES.items():
            if name not in wanted:
                continue
            arguments = ["--ros-args", *(a for p in parameters for a in ("-p", p))]
            log = stack.enter_context((logs / f"{name}.log").open("w"))
            processes[name] = stack.enter_context(
                installed_node(package, name, *arguments, output=log)
            )
        yield processes


def fuzz(
    harness: Harness,
    endpoint: Endpoint,
    cases: st.SearchStrategy[Case],
    batches: int,
    random_seed: int | None = None,
    most_at_once: int = 10,
    fewest_at_once: int = 1,
) -> None:
    """``batches`` batches of ``fewest_at_once`` to ``most_at_once`` cases sent at once;
    derandomized (the same cases every run) when ``random_seed`` is None, else drawn with
    that seed. No shrinking: the report keeps every failure."""
    chosen = settings(
        max_examples=batches,
        derandomize=random_seed is None,
        deadline=None,
        database=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )

    @chosen
    @given(batch=st.lists(cases, min_size=fewest_at_once, max_size=most_at_once))
    def run(batch: list[Case]) -> None:
        harness.run(endpoint, batch)

    if random_seed is not None:
        run = seed(random_seed)(run)
    run()

"""Strategies for /plan_place and /plan_strike: a valid request with one thing broken
(the right code is known), or everything drawn freely."""

from __future__ import annotations

import math
from dataclasses import replace

from geometry_msgs.msg import Point, Pose, Vector3
from hypothesis import strategies as st
from sensor_msgs.msg import JointState

from dombot_description.grasp import upright_pose
from dombot_msgs.srv import PlanPlace, PlanStrike
from dombot_planner.request import MAX_PILE_DOMINOES, MAX_PILE_POINTS, MAX_STANDING
from support.fuzz.harness import Case
from support.fuzz.values import (
    ARM,
    HOME,
    HUGE,
    NON_FINITE,
    PICK,
    PLACE,
    SCENARIO,
    any_float,
    broken_pose,
    huge_count,
    non_finite,
    pose,
    pose_of,
)
from support.planning_clock import UNHURRIED

INVALID = frozenset({"INVALID_REQUEST"})
VALID_BUDGET = UNHURRIED  # the valid plan after each batch: the search ends it, not the clock
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

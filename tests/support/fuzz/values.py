"""Values the strategies share: the scenario's arm, poses, floats that break things."""

from __future__ import annotations

import math
from collections.abc import Sequence

import numpy as np
from geometry_msgs.msg import Point, Pose, Quaternion
from hypothesis import strategies as st

from dombot_description.grasp import flat_pose, upright_pose
from dombot_description.scenario import load_scenario

SCENARIO = load_scenario()
NON_FINITE = (math.nan, math.inf, -math.inf)
HUGE = (1e12, 1e300, -1e300)
ARM = list(SCENARIO.arm_joints)
HOME = SCENARIO.home_position.tolist()
PICK = flat_pose(0.60, -0.28, 0.4)
PLACE = upright_pose(0.55, 0.15, 0.3)


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

"""Strategies for perception_node's services and /sim/reset."""

from __future__ import annotations

from builtin_interfaces.msg import Time
from hypothesis import strategies as st

from dombot_msgs.srv import CheckPlacement, DetectDominoes, ResetSim
from support.fuzz.harness import Case
from support.fuzz.values import PICK, PLACE, SCENARIO, broken_pose, huge_count, non_finite, pose_of

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

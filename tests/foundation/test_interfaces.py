"""dombot_msgs: every interface imports, has its documented constants, and round-trips."""

from __future__ import annotations

import math

import pytest
from rclpy.serialization import deserialize_message, serialize_message

from dombot_msgs.msg import (
    DominoDetection,
    DominoDetectionArray,
    DominoState,
    DominoStateArray,
    TrajectorySegment,
    WheelVelocities,
)
from dombot_msgs.srv import DetectDominoes, PlanPlace, ResetSim


def sample_detection() -> DominoDetection:
    detection = DominoDetection(id=3, posture=DominoDetection.POSTURE_UPRIGHT, score=0.75)
    detection.pose.position.x = 0.5
    detection.pose.orientation.z = math.sin(0.3)
    detection.pose.orientation.w = math.cos(0.3)
    detection.size.x, detection.size.y, detection.size.z = 0.048, 0.024, 0.0075
    detection.grasp_width = 0.03
    return detection


def sample_segment() -> TrajectorySegment:
    segment = TrajectorySegment(label="transfer", gripper_after=TrajectorySegment.GRIPPER_OPEN)
    segment.trajectory.joint_names = [f"iiwa_joint_{i}" for i in range(1, 8)]
    return segment


MESSAGES = [
    sample_detection(),
    DominoDetectionArray(detections=[sample_detection(), DominoDetection(id=4)]),
    DominoState(name="domino_7", upright=True),
    DominoStateArray(dominoes=[DominoState(name="domino_0")]),
    sample_segment(),
    WheelVelocities(left=3.5, right=4.0, wheel_speed_ratio=0.875, message="ok"),
    PlanPlace.Request(grasp_width=0.0075, time_budget=2.0),
    PlanPlace.Response(
        success=False, error_code=PlanPlace.Response.TIMEOUT, segments=[sample_segment()]
    ),
    DetectDominoes.Request(cameras=["camera_0", "camera_1"]),
    DetectDominoes.Response(success=True, message="2 dominoes"),
    ResetSim.Request(domino_count=30, seed=-7),
    ResetSim.Response(success=True, settle_time=1.25),
]


@pytest.mark.parametrize("message", MESSAGES, ids=lambda m: type(m).__name__)
def test_round_trip_through_cdr(message) -> None:
    data = serialize_message(message)
    assert deserialize_message(data, type(message)) == message


def test_round_trip_preserves_nested_values() -> None:
    array = DominoDetectionArray(detections=[sample_detection()])
    back = deserialize_message(serialize_message(array), DominoDetectionArray)
    assert back.detections[0].posture == DominoDetection.POSTURE_UPRIGHT
    assert back.detections[0].pose.orientation.w == pytest.approx(math.cos(0.3))
    assert back.detections[0].size.z == pytest.approx(0.0075)


def test_error_codes_are_distinct_and_named() -> None:
    names = [
        "SUCCESS",
        "INVALID_REQUEST",
        "NO_START_STATE",
        "OUTSIDE_WORKSPACE",
        "GRASP_UNREACHABLE",
        "PLACE_UNREACHABLE",
        "PLACE_IN_COLLISION",
        "PLANNING_FAILED",
        "TIMEOUT",
    ]
    codes = [getattr(PlanPlace.Response, name) for name in names]
    assert codes[0] == 0
    assert len(set(codes)) == len(codes)

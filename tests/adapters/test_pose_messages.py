"""Transforms, times and durations as the node adapters send them."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dombot_adapters.pose_messages import (
    duration_message,
    pose_matrix,
    pose_message,
    seconds_of,
    time_message,
)


def test_a_pose_survives_the_message_both_ways() -> None:
    matrix = np.eye(4)
    matrix[:3, :3] = Rotation.from_euler("xyz", [0.3, -1.2, 2.5]).as_matrix()
    matrix[:3, 3] = [0.55, -0.3, 0.004]
    assert np.allclose(pose_matrix(pose_message(matrix)), matrix)


@pytest.mark.parametrize("seconds", [0.0, 0.01, 1.5, 2.999999999, 7.0 + 1e-9, 1795514776.3])
def test_seconds_survive_a_duration_and_a_time(seconds: float) -> None:
    duration, time = duration_message(seconds), time_message(seconds)
    assert 0 <= duration.nanosec < 1_000_000_000  # never a whole second of nanoseconds
    assert seconds_of(duration) == pytest.approx(seconds, abs=1e-9, rel=1e-12)
    assert seconds_of(time) == pytest.approx(seconds, abs=1e-9, rel=1e-12)


def test_a_negative_time_is_unset() -> None:
    assert seconds_of(time_message(-3.0)) == 0.0

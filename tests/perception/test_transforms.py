"""The transform buffer perception reads camera extrinsics from: chains in both
directions, the newest transform wins, and clear errors for missing or loose frames."""

from __future__ import annotations

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dombot_perception.transforms import TransformBuffer


def transform(rotvec, translation) -> np.ndarray:
    x = np.eye(4)
    x[:3, :3] = Rotation.from_rotvec(rotvec).as_matrix()
    x[:3, 3] = translation
    return x


X_WR = transform([0.0, 0.0, 0.7], [1.0, 0.0, 0.5])
X_RC = transform([0.3, -2.0, 0.1], [0.1, 0.2, 0.0])
X_WT = transform([0.0, 0.4, 0.0], [0.0, -1.0, 0.0])


@pytest.fixture
def buffer() -> TransformBuffer:
    buffer = TransformBuffer()
    buffer.set("world", "rig", X_WR)
    buffer.set("rig", "camera_optical", X_RC)
    buffer.set("world", "table", X_WT)
    return buffer


def test_a_chain_composes_down_up_and_across(buffer: TransformBuffer) -> None:
    assert np.allclose(buffer.lookup("world", "camera_optical"), X_WR @ X_RC)
    assert np.allclose(buffer.lookup("camera_optical", "world"), np.linalg.inv(X_WR @ X_RC))
    across = np.linalg.inv(X_WT) @ X_WR @ X_RC
    assert np.allclose(buffer.lookup("table", "camera_optical"), across)
    assert np.allclose(buffer.lookup("rig", "rig"), np.eye(4))


def test_the_newest_transform_of_a_frame_wins(buffer: TransformBuffer) -> None:
    moved = transform([0.0, 0.0, 0.0], [0.0, 0.0, 0.01])
    buffer.set("rig", "camera_optical", X_RC @ moved)
    assert np.allclose(buffer.lookup("world", "camera_optical"), X_WR @ X_RC @ moved)


def test_unknown_and_unconnected_frames_are_named(buffer: TransformBuffer) -> None:
    with pytest.raises(LookupError, match="camera_9"):
        buffer.lookup("world", "camera_9")
    buffer.set("odom", "base", np.eye(4))
    with pytest.raises(LookupError, match="'odom'"):
        buffer.lookup("world", "base")
    buffer.set("rig", "world", np.eye(4))  # world → rig → world
    with pytest.raises(LookupError, match="loop"):
        buffer.lookup("world", "camera_optical")

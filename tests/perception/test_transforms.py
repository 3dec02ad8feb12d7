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


def put(buffer: TransformBuffer, parent: str, child: str, x: np.ndarray) -> None:
    """As tf sends it: translation and quaternion (x, y, z, w)."""
    buffer.set(parent, child, tuple(x[:3, 3]), tuple(Rotation.from_matrix(x[:3, :3]).as_quat()))


@pytest.fixture
def buffer() -> TransformBuffer:
    buffer = TransformBuffer()
    put(buffer, "world", "rig", X_WR)
    put(buffer, "rig", "camera_optical", X_RC)
    put(buffer, "world", "table", X_WT)
    return buffer


def test_a_chain_composes_down_up_and_across(buffer: TransformBuffer) -> None:
    assert np.allclose(buffer.lookup("world", "camera_optical"), X_WR @ X_RC)
    assert np.allclose(buffer.lookup("camera_optical", "world"), np.linalg.inv(X_WR @ X_RC))
    across = np.linalg.inv(X_WT) @ X_WR @ X_RC
    assert np.allclose(buffer.lookup("table", "camera_optical"), across)
    assert np.allclose(buffer.lookup("rig", "rig"), np.eye(4))


def test_the_newest_transform_of_a_frame_wins(buffer: TransformBuffer) -> None:
    moved = transform([0.0, 0.0, 0.0], [0.0, 0.0, 0.01])
    put(buffer, "rig", "camera_optical", X_RC @ moved)
    assert np.allclose(buffer.lookup("world", "camera_optical"), X_WR @ X_RC @ moved)


def test_a_quaternion_off_unit_length_is_normalised() -> None:
    buffer = TransformBuffer()
    buffer.set("world", "camera", (1.0, 2.0, 3.0), (0.0, 0.0, 2.0, 0.0))  # half turn about z
    expected = np.diag([-1.0, -1.0, 1.0, 1.0])
    expected[:3, 3] = [1.0, 2.0, 3.0]
    assert np.allclose(buffer.lookup("world", "camera"), expected)


def test_unknown_and_unconnected_frames_are_named(buffer: TransformBuffer) -> None:
    with pytest.raises(LookupError, match="camera_9"):
        buffer.lookup("world", "camera_9")
    put(buffer, "odom", "base", np.eye(4))
    with pytest.raises(LookupError, match="'odom'"):
        buffer.lookup("world", "base")
    put(buffer, "rig", "world", np.eye(4))  # world → rig → world
    with pytest.raises(LookupError, match="loop"):
        buffer.lookup("world", "camera_optical")

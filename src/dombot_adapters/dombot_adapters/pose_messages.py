"""4x4 homogeneous transforms ↔ ``geometry_msgs/Pose``: the one conversion every node
adapter needs between the plain modules (numpy) and their messages; and seconds ↔
``builtin_interfaces/Time`` and ``Duration``."""

from __future__ import annotations

import numpy as np
from builtin_interfaces.msg import Duration, Time
from geometry_msgs.msg import Point, Pose, Quaternion
from scipy.spatial.transform import Rotation


def pose_matrix(pose: Pose) -> np.ndarray:
    """The transform of ``pose`` (its quaternion normalised by scipy)."""
    q = pose.orientation
    matrix = np.eye(4)
    matrix[:3, :3] = Rotation.from_quat([q.x, q.y, q.z, q.w]).as_matrix()
    matrix[:3, 3] = [pose.position.x, pose.position.y, pose.position.z]
    return matrix


def pose_message(matrix: np.ndarray) -> Pose:
    x, y, z = (float(v) for v in matrix[:3, 3])
    qx, qy, qz, qw = (float(v) for v in Rotation.from_matrix(matrix[:3, :3]).as_quat())
    return Pose(position=Point(x=x, y=y, z=z), orientation=Quaternion(x=qx, y=qy, z=qz, w=qw))


def time_message(seconds: float) -> Time:
    """``seconds`` (e.g. simulated) as a ROS time; negative: zero, i.e. unset."""
    nanoseconds = max(round(seconds * 1e9), 0)
    return Time(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def duration_message(seconds: float) -> Duration:
    """``seconds`` (≥ 0) as a ROS duration, e.g. a trajectory point's time_from_start."""
    nanoseconds = round(seconds * 1e9)
    return Duration(sec=nanoseconds // 1_000_000_000, nanosec=nanoseconds % 1_000_000_000)


def seconds_of(stamp: Duration | Time) -> float:
    """A ROS duration or time in seconds."""
    return stamp.sec + stamp.nanosec * 1e-9

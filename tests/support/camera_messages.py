"""Rendered views as the messages a camera driver publishes; tf transforms ↔ 4x4 matrices."""

from __future__ import annotations

import numpy as np
from geometry_msgs.msg import Point, Pose, Transform, TransformStamped, Vector3
from sensor_msgs.msg import CameraInfo, Image

from dombot_adapters.pose_messages import pose_matrix, pose_message


def image_messages(
    view, stamp, depth_encoding: str = "32FC1", frame_id: str | None = None
) -> tuple[Image, Image, CameraInfo]:
    """Colour, depth and camera_info of ``view`` stamped ``stamp``, in ``frame_id``
    (default ``<camera>_optical``, sim_node's name)."""
    height, width = view.depth.shape
    color = Image(height=height, width=width, encoding="rgb8", step=width * 3)
    color.data = view.rgb.tobytes()
    depth = Image(height=height, width=width, encoding=depth_encoding, step=width * 4)
    depth.data = view.depth.astype(np.float32).tobytes()
    info = CameraInfo(height=height, width=width, k=view.K.ravel().tolist())
    for message in (color, depth, info):
        message.header.stamp = stamp
        message.header.frame_id = frame_id or f"{view.name}_optical"
    return color, depth, info


def transform_stamped(parent: str, child: str, matrix: np.ndarray) -> TransformStamped:
    """``child``'s pose ``matrix`` (4x4) in ``parent`` as a tf transform."""
    pose = pose_message(matrix)
    p = pose.position
    stamped = TransformStamped(child_frame_id=child)
    stamped.header.frame_id = parent
    stamped.transform = Transform(
        translation=Vector3(x=p.x, y=p.y, z=p.z), rotation=pose.orientation
    )
    return stamped


def transform_matrix(transform: Transform) -> np.ndarray:
    """The 4x4 matrix of a tf transform."""
    t = transform.translation
    return pose_matrix(Pose(position=Point(x=t.x, y=t.y, z=t.z), orientation=transform.rotation))

"""perception_node's ROS messages: the few images kept of each camera and their pairing
by stamp, images to arrays, detections and the debug picture to messages, and the
placement check's request checked and its response filled."""

from __future__ import annotations

import math
from collections import deque
from dataclasses import dataclass, field

import numpy as np
from geometry_msgs.msg import Vector3
from sensor_msgs.msg import CameraInfo, Image

from dombot_adapters.pose_messages import pose_matrix, pose_message
from dombot_description import tilt_from_vertical
from dombot_msgs.msg import DominoDetection, DominoDetectionArray
from dombot_msgs.srv import CheckPlacement
from dombot_perception.debug_image import draw_detections, mask_overlay
from dombot_perception.frames import CameraView, Detection
from dombot_perception.pipeline import PipelineResult
from dombot_perception.placement_check import Placement, PlacementConfig

DEFAULT_SEARCH_RADIUS = PlacementConfig().search_radius
MAX_IN_HAND_TILT = math.degrees(PlacementConfig().max_tilt)  # expected poses when in_hand
MAX_EXPECTED = 500  # poses a placement check takes (a run in the build area has < 200)
SYNC_BUFFER = 5  # messages kept per stream to find matching colour/depth stamps
STAMP_SLACK = 1e-3  # s: stamps this much before not_before still count (rounding)
DEPTH_ENCODINGS = {"32FC1": (np.float32, 1.0), "16UC1": (np.uint16, 0.001)}  # → metres
WORLD_FRAME = "world"


@dataclass
class CameraInput:
    """The last few messages of one camera and when a colour image last arrived."""

    colors: deque = field(default_factory=lambda: deque(maxlen=SYNC_BUFFER))
    depths: deque = field(default_factory=lambda: deque(maxlen=SYNC_BUFFER))
    info: CameraInfo | None = None
    received: float = -math.inf

    def latest_pair(
        self, tolerance: float, not_before: float = -math.inf
    ) -> tuple[Image, Image] | None:
        """The newest colour and depth images whose stamps agree within ``tolerance`` s,
        stamped at or after ``not_before``. Read from copies: the input callbacks append
        on another thread, and a deque changed while iterated raises."""
        depths = list(self.depths)[::-1]
        for color in list(self.colors)[::-1]:
            stamp = stamp_seconds(color.header.stamp)
            if stamp < not_before - STAMP_SLACK:
                return None
            for depth in depths:
                if abs(stamp_seconds(depth.header.stamp) - stamp) <= tolerance:
                    return color, depth
        return None


def stamp_seconds(stamp) -> float:
    return stamp.sec + stamp.nanosec * 1e-9


def not_before_of(request) -> float:
    """A request's not_before [s]; zero (unset): any frame, the latest."""
    return stamp_seconds(request.not_before) or -math.inf


def rgb_array(message: Image) -> np.ndarray:
    if message.encoding not in ("rgb8", "bgr8"):
        raise ValueError(f"colour encoding {message.encoding!r} is not rgb8 or bgr8")
    rows = _rows(message, np.uint8, 3)
    return rows[:, :, ::-1] if message.encoding == "bgr8" else rows


def depth_array(message: Image) -> np.ndarray:
    """Depth in metres (float32); 16UC1 millimetres are converted, 0 becomes NaN."""
    if message.encoding not in DEPTH_ENCODINGS:
        raise ValueError(f"depth encoding {message.encoding!r} is not 32FC1 or 16UC1")
    dtype, scale = DEPTH_ENCODINGS[message.encoding]
    depth = _rows(message, dtype, 1)[:, :, 0].astype(np.float32) * np.float32(scale)
    depth[depth <= 0] = np.nan
    return depth


def _rows(message: Image, dtype: type, channels: int) -> np.ndarray:
    """The image as an HxWxC array, honouring the row step; ValueError when inconsistent."""
    item = np.dtype(dtype).itemsize * channels
    if message.height == 0 or message.width == 0:
        raise ValueError("empty image")
    if message.step < message.width * item or len(message.data) < message.step * message.height:
        raise ValueError(
            f"{message.width}x{message.height} {message.encoding} image has step "
            f"{message.step} and {len(message.data)} bytes"
        )
    data = np.frombuffer(bytes(message.data), dtype=np.uint8).reshape(message.height, -1)
    row_bytes = data[:, : message.width * item].copy()
    return row_bytes.view(dtype).reshape(message.height, message.width, channels)


def detection_array(detections: list[Detection], stamp) -> DominoDetectionArray:
    array = DominoDetectionArray()
    array.header.frame_id = WORLD_FRAME
    array.header.stamp = stamp
    array.detections = [detection_message(i, d) for i, d in enumerate(detections)]
    return array


def detection_message(index: int, detection: Detection) -> DominoDetection:
    return DominoDetection(
        id=index,
        pose=pose_message(detection.X_WD),
        size=_vector(detection.size),
        posture=detection.posture,
        score=float(detection.score),
        fit_error=float(detection.fit_error),
        clearance=float(detection.clearance),
        num_points=int(detection.num_points),
        num_cameras=len(detection.cameras),
        grasp_pose=pose_message(detection.grasp_pose),
        grasp_width=float(detection.grasp_width),
    )


def _vector(values: np.ndarray) -> Vector3:
    return Vector3(x=float(values[0]), y=float(values[1]), z=float(values[2]))


def debug_image(views: list[CameraView], result: PipelineResult, stamp) -> Image:
    """The views side by side, each with its masks and the detected boxes drawn in."""
    tiles = [
        draw_detections(
            mask_overlay(view, result.masks.get(view.name, [])), view, result.detections
        )
        for view in views
    ]
    height = max(tile.shape[0] for tile in tiles)
    tiles = [np.pad(t, ((0, height - t.shape[0]), (0, 0), (0, 0))) for t in tiles]
    picture = np.concatenate(tiles, axis=1)
    message = Image(height=picture.shape[0], width=picture.shape[1], encoding="rgb8")
    message.header.frame_id = WORLD_FRAME
    message.header.stamp = stamp
    message.step = picture.shape[1] * 3
    message.data = picture.tobytes()
    return message


def expected_poses_problem(request: CheckPlacement.Request) -> str | None:
    """What is wrong with a placement check's search radius and expected poses (None:
    nothing)."""
    if not math.isfinite(request.search_radius) or request.search_radius < 0:
        return f"search_radius must be >= 0, got {request.search_radius}"
    if len(request.expected) > MAX_EXPECTED:
        return f"{len(request.expected)} expected poses, at most {MAX_EXPECTED} are checked"
    for index, pose in enumerate(request.expected):
        q = pose.orientation
        values = [pose.position.x, pose.position.y, pose.position.z, q.x, q.y, q.z, q.w]
        if not all(math.isfinite(v) for v in values):
            return f"expected pose {index} is not finite"
        if abs(math.sqrt(q.x**2 + q.y**2 + q.z**2 + q.w**2) - 1.0) > 1e-3:
            return f"expected pose {index}: quaternion is not unit length (within 1e-3)"
        if request.in_hand:  # fitted from the expected foot up to below the pads
            tilt = math.degrees(tilt_from_vertical(pose_matrix(pose)))
            if tilt > MAX_IN_HAND_TILT:
                return (
                    f"in_hand: expected pose {index} is not upright "
                    f"(body x {tilt:.0f}° from vertical)"
                )
    return None


def placement_config(request: CheckPlacement.Request) -> PlacementConfig:
    return PlacementConfig(
        search_radius=request.search_radius or DEFAULT_SEARCH_RADIUS, in_hand=request.in_hand
    )


def fill_placement_response(
    response: CheckPlacement.Response, placements: list[Placement], warnings: list[str]
) -> CheckPlacement.Response:
    """A successful check's response: each expected pose's status, measured pose, position
    error and tilt, and the counts of each status with the warnings as its message."""
    response.success = True
    response.status = [p.status for p in placements]
    response.measured = [pose_message(p.measured) for p in placements]
    response.position_error = [p.position_error for p in placements]
    response.tilt = [p.tilt for p in placements]
    counts = np.bincount(response.status, minlength=4)
    response.message = "; ".join(
        [
            f"{counts[0]} standing, {counts[1]} fallen, {counts[2]} missing, {counts[3]} not seen",
            *warnings,
        ]
    )
    return response

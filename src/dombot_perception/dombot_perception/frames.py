"""The pipeline's input (one RGB-D view) and output (one detected domino) types.

Both are plain dataclasses so the pipeline runs from the simulator library, from a
recorded file or from ROS messages alike.
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

POSTURE_FLAT = 0  # body z vertical (values match dombot_msgs/DominoDetection)
POSTURE_ON_EDGE = 1  # body y vertical
POSTURE_UPRIGHT = 2  # body x vertical
POSTURE_TILTED = 3
POSTURE_NAMES = {
    POSTURE_FLAT: "flat",
    POSTURE_ON_EDGE: "on_edge",
    POSTURE_UPRIGHT: "upright",
    POSTURE_TILTED: "tilted",
}


@dataclass
class CameraView:
    """One synchronised colour + depth frame with its calibration.

    ``depth`` is in metres, NaN or 0 where the camera got no return; ``K`` is the 3x3
    pinhole matrix of the (aligned) depth image; ``X_WC`` is the 4x4 pose of the
    optical frame (z forward, x right, y down) in world.
    """

    name: str
    rgb: np.ndarray  # HxWx3 uint8
    depth: np.ndarray  # HxW float32, m
    K: np.ndarray
    X_WC: np.ndarray

    def check(self) -> str | None:
        """Why this view cannot be used, or None when it can."""
        if self.depth.ndim != 2 or self.depth.size == 0:
            return f"{self.name}: depth image must be a non-empty HxW array"
        if self.rgb.shape[:2] != self.depth.shape:
            return f"{self.name}: colour {self.rgb.shape[:2]} and depth {self.depth.shape} differ"
        if self.K.shape != (3, 3) or not np.all(np.isfinite(self.K)) or self.K[0, 0] <= 0:
            return f"{self.name}: camera matrix K is not a valid pinhole matrix"
        if self.X_WC.shape != (4, 4) or not np.all(np.isfinite(self.X_WC)):
            return f"{self.name}: camera pose X_WC is not a finite 4x4 transform"
        rotation = self.X_WC[:3, :3]
        if not np.allclose(rotation @ rotation.T, np.eye(3), atol=1e-4):
            return f"{self.name}: camera pose rotation is not orthonormal"
        return None


@dataclass
class Detection:
    """One domino: body frame in world (x length, y width, z thickness) and its grasp."""

    X_WD: np.ndarray  # 4x4
    size: np.ndarray  # measured length, width, thickness [m]
    posture: int
    fit_error: float  # RMS point-to-box distance [m]
    num_points: int
    cameras: tuple[str, ...]
    score: float = 0.0
    clearance: float = 0.0
    grasp_pose: np.ndarray = field(default_factory=lambda: np.eye(4))
    grasp_width: float = 0.0
    score_terms: dict[str, float] = field(default_factory=dict)
    points: np.ndarray | None = field(default=None, repr=False)  # fused cloud, world

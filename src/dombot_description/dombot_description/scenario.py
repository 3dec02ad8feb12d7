"""The scenario file: the cell's models (Drake model directives) plus the named
regions, cameras and joint names that simulator, perception, planner and bring-up
share."""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import numpy as np
import yaml

from dombot_description import PACKAGE_DIR

DEFAULT_SCENARIO = PACKAGE_DIR / "scenarios" / "default.yaml"


class ScenarioError(ValueError):
    """The scenario file is missing a field or has a bad value; the message names it."""


@dataclass(frozen=True)
class CameraSpec:
    name: str
    position: np.ndarray  # m, world
    look_at: np.ndarray  # m, world
    width: int
    height: int
    fov_y: float  # rad
    depth_range: tuple[float, float]  # m

    @property
    def focal_length(self) -> float:
        """Pixels (square pixels): f = (h/2) / tan(fov_y/2)."""
        return (self.height / 2.0) / np.tan(self.fov_y / 2.0)

    @property
    def intrinsics(self) -> np.ndarray:
        """3x3 K with the principal point at the image centre, (w − 1)/2 and (h − 1)/2:
        pixel (0, 0) is the centre of the first pixel, the convention Drake renders with."""
        f = self.focal_length
        return np.array(
            [[f, 0.0, (self.width - 1) / 2.0], [0.0, f, (self.height - 1) / 2.0], [0.0, 0.0, 1.0]]
        )

    def pose(self) -> np.ndarray:
        """4x4 X_WC of the optical frame (z forward, x right, y down), looking at ``look_at``."""
        forward = self.look_at - self.position
        forward = forward / np.linalg.norm(forward)
        right = np.cross(forward, [0.0, 0.0, 1.0])
        right = right / np.linalg.norm(right)
        down = np.cross(forward, right)
        pose = np.eye(4)
        pose[:3, :3] = np.column_stack([right, down, forward])
        pose[:3, 3] = self.position
        return pose


@dataclass(frozen=True)
class Scenario:
    path: Path
    directives_path: Path  # Drake model directives (a .dmd.yaml file)
    arm_joints: tuple[str, ...]
    gripper_joints: tuple[str, ...]
    tcp_frame: str
    home_position: np.ndarray
    pile_center: np.ndarray
    pile_radius: float
    drop_height: tuple[float, float]
    build_x: tuple[float, float]
    build_y: tuple[float, float]
    build_reach: tuple[float, float]
    cameras: tuple[CameraSpec, ...]


def load_scenario(path: Path | str | None = None) -> Scenario:
    """Read and check a scenario file (default: the package's ``scenarios/default.yaml``)."""
    path = Path(path) if path is not None else DEFAULT_SCENARIO
    try:
        data = yaml.safe_load(path.read_text())
    except OSError as error:
        raise ScenarioError(f"cannot read scenario {path}: {error.strerror}") from None
    except yaml.YAMLError as error:
        raise ScenarioError(f"scenario {path} is not valid YAML: {error}") from None
    try:
        return _parse(path, data)
    except (KeyError, TypeError, ValueError) as error:
        raise ScenarioError(f"scenario {path}: bad or missing field {error}") from None


def _existing(path: Path) -> Path:
    if not path.is_file():
        raise ValueError(f"'model_directives': no file {path}")
    return path


def _parse(path: Path, data: dict) -> Scenario:
    intrinsics = data["camera_intrinsics"]
    cameras = tuple(
        CameraSpec(
            name=str(camera["name"]),
            position=np.asarray(camera["position"], dtype=float),
            look_at=np.asarray(camera["look_at"], dtype=float),
            width=int(intrinsics["width"]),
            height=int(intrinsics["height"]),
            fov_y=float(np.radians(intrinsics["fov_y_deg"])),
            depth_range=tuple(float(v) for v in intrinsics["depth_range"]),
        )
        for camera in data["cameras"]
    )
    home = np.asarray(data["home_position"], dtype=float)
    if home.shape != (len(data["arm_joints"]),):
        raise ValueError("'home_position' needs one value per arm joint")
    return Scenario(
        path=path,
        directives_path=_existing(path.parent / data["model_directives"]),
        arm_joints=tuple(data["arm_joints"]),
        gripper_joints=tuple(data["gripper_joints"]),
        tcp_frame=str(data["tcp_frame"]),
        home_position=home,
        pile_center=np.asarray(data["pile_area"]["center"], dtype=float),
        pile_radius=float(data["pile_area"]["radius"]),
        drop_height=tuple(float(v) for v in data["pile_area"]["drop_height"]),
        build_x=tuple(float(v) for v in data["build_area"]["x"]),
        build_y=tuple(float(v) for v in data["build_area"]["y"]),
        build_reach=tuple(float(v) for v in data["build_area"]["reach"]),
        cameras=cameras,
    )

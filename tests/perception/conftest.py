"""A small simulated cell (3 dominoes) that renders dominoes exactly where a test puts them.

The ROS node test is collected only where the ROS interfaces are importable.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from dombot_perception.frames import CameraView

PILE_CAMERAS = ("camera_0", "camera_1")
PLACEMENT_CAMERAS = ("camera_2", "camera_3")  # perception_node's placement_cameras: the run
collect_ignore = [] if importlib.util.find_spec("dombot_msgs") else ["test_perception_node.py"]


@pytest.fixture(scope="session")
def world():
    from dombot_sim.world import CellWorld, WorldConfig

    return CellWorld(WorldConfig(cameras=True, domino_capacity=3))


def renderer(world, cameras: tuple[str, ...] | None):
    """Render dominoes at exact poses: {index: 4x4} -> a CameraView per camera named in
    ``cameras`` (None: every camera), only those cameras rendered."""

    def render(poses: dict[int, np.ndarray]) -> list[CameraView]:
        world.set_domino_poses(poses)
        frames = world.render(list(cameras) if cameras else None)
        return [CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC) for f in frames.values()]

    return render


@pytest.fixture(scope="session")
def render_scene(world):
    """Dominoes at exact poses, seen by the pile cameras."""
    return renderer(world, PILE_CAMERAS)


@pytest.fixture(scope="session")
def render_build_area(world):
    """Dominoes at exact poses, seen by the placement cameras (camera_2, camera_3)."""
    return renderer(world, PLACEMENT_CAMERAS)


@pytest.fixture(scope="session")
def render_camera_2(world):
    """Dominoes at exact poses, seen by camera_2 alone (the run from its end)."""
    return renderer(world, ("camera_2",))


@pytest.fixture(scope="session")
def render_every_camera(world):
    """Dominoes at exact poses, seen by every camera."""
    return renderer(world, None)

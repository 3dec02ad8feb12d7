"""A small simulated cell (3 dominoes) that renders dominoes exactly where a test puts them.

The ROS node test is collected only where the ROS interfaces are importable.
"""

from __future__ import annotations

import importlib.util

import numpy as np
import pytest

from dombot_perception.frames import CameraView

PILE_CAMERAS = ("camera_0", "camera_1")  # camera_2 watches the build area
collect_ignore = [] if importlib.util.find_spec("dombot_msgs") else ["test_perception_node.py"]


@pytest.fixture(scope="session")
def world():
    from dombot_sim.world import CellWorld, WorldConfig

    return CellWorld(WorldConfig(cameras=True, domino_capacity=3))


def renderer(world, pile: bool | None):
    """Render dominoes at exact poses: {index: 4x4} -> a CameraView per pile camera
    (``pile``), per build-area camera (not ``pile``) or per camera (None)."""

    def render(poses: dict[int, np.ndarray]) -> list[CameraView]:
        world.set_domino_poses(poses)
        return [
            CameraView(f.name, f.rgb, f.depth, f.K, f.X_WC)
            for f in world.render().values()
            if pile is None or (f.name in PILE_CAMERAS) == pile
        ]

    return render


@pytest.fixture(scope="session")
def render_scene(world):
    """Dominoes at exact poses, seen by the pile cameras."""
    return renderer(world, pile=True)


@pytest.fixture(scope="session")
def render_build_area(world):
    """Dominoes at exact poses, seen by the build-area camera (camera_2)."""
    return renderer(world, pile=False)


@pytest.fixture(scope="session")
def render_every_camera(world):
    """Dominoes at exact poses, seen by every camera."""
    return renderer(world, pile=None)

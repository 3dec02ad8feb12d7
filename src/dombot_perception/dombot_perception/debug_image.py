"""Pictures for people: masks over the colour image, detected boxes drawn on top.

Plain numpy (no OpenCV here): masks are blended in seeded random colours, each
detected box's 12 edges are projected into the image and drawn as dotted lines,
green for the best grasp, then yellow, then red for unpickable ones.
"""

from __future__ import annotations

import numpy as np

from dombot_perception.domino_model import HALF_SIZE
from dombot_perception.frames import CameraView, Detection

EDGES = [(a, b) for a in range(8) for b in range(a + 1, 8) if bin(a ^ b).count("1") == 1]
CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])
BEST, PICKABLE, UNPICKABLE = (40, 230, 40), (250, 210, 0), (230, 40, 40)


def mask_overlay(view: CameraView, masks: list[np.ndarray], seed: int = 0) -> np.ndarray:
    """The colour image with each mask blended in its own colour (HxWx3 uint8)."""
    image = view.rgb.reshape(-1, 3).astype(np.float32)
    colours = np.random.default_rng(seed).integers(40, 255, size=(len(masks), 3))
    for mask, colour in zip(masks, colours, strict=True):
        image[mask] = 0.45 * image[mask] + 0.55 * colour
    return image.reshape(view.rgb.shape).astype(np.uint8)


def draw_detections(image: np.ndarray, view: CameraView, detections: list[Detection]) -> np.ndarray:
    """``image`` with every detection's box outline projected through ``view``'s camera."""
    out = image.copy()
    height, width = out.shape[:2]
    steps = np.linspace(0.0, 1.0, 60)[:, None]
    for rank, detection in enumerate(detections):
        colour = BEST if rank == 0 else PICKABLE if detection.score > 0 else UNPICKABLE
        corners = (CORNERS * HALF_SIZE) @ detection.X_WD[:3, :3].T + detection.X_WD[:3, 3]
        camera = (corners - view.X_WC[:3, 3]) @ view.X_WC[:3, :3]
        if np.any(camera[:, 2] <= 0):
            continue
        pixels = camera[:, :2] / camera[:, 2:] * view.K[[0, 1], [0, 1]] + view.K[[0, 1], [2, 2]]
        for a, b in EDGES:
            line = np.round(pixels[a] + steps * (pixels[b] - pixels[a])).astype(int)
            inside = (
                (line[:, 0] >= 0) & (line[:, 0] < width) & (line[:, 1] >= 0) & (line[:, 1] < height)
            )
            out[line[inside, 1], line[inside, 0]] = colour
    return out

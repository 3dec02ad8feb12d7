"""The one interface every segmentation backend implements, and the factory that picks one.

A backend turns one camera view into masks, each the flat pixel indices of one
domino candidate. Masks may overlap (SAM's do); later stages cope.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from dombot_perception.backprojection import OrganisedCloud
from dombot_perception.frames import CameraView
from dombot_perception.geometric_segmentation import GeometricSegmenter, GeometricSegmenterConfig

BACKENDS = ("geometric", "sam")


class Segmenter(Protocol):
    name: str

    def segment(self, view: CameraView, cloud: OrganisedCloud | None) -> list[np.ndarray]:
        """Flat pixel indices (row * width + col) of each mask.

        ``cloud`` is the view back-projected and cropped to the work region (None when
        nothing there is seen); backends that use depth geometry read it, others ignore it.
        """


class SegmenterError(ValueError):
    """A backend cannot be built from the given settings; the message says why."""


def make_segmenter(
    backend: str,
    geometric: GeometricSegmenterConfig | None = None,
    sam_checkpoint: str = "",
    sam_model_type: str = "vit_b",
    sam_points_per_side: int = 32,
) -> Segmenter:
    """The backend named ``backend`` ('geometric' or 'sam')."""
    if backend == "geometric":
        return GeometricSegmenter(geometric)
    if backend == "sam":
        from dombot_perception.sam_segmentation import SamSegmenter, load_sam  # needs torch

        if not sam_checkpoint:
            raise SegmenterError("backend 'sam' needs a checkpoint path (sam_checkpoint)")
        return SamSegmenter(load_sam(sam_model_type, sam_checkpoint), sam_points_per_side)
    raise SegmenterError(f"unknown segmentation backend {backend!r}; choose one of {BACKENDS}")

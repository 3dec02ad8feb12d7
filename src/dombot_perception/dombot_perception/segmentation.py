"""The one interface every segmentation backend implements (the pipeline picks one).

A backend turns each camera view into masks, each the flat pixel indices of one
domino candidate. Masks may overlap (SAM's do); later stages cope. Backends import
this module, never the pipeline, so no import runs in a circle.
"""

from __future__ import annotations

from typing import Protocol

import numpy as np

from dombot_perception.backprojection import OrganisedCloud
from dombot_perception.frames import CameraView


class Segmenter(Protocol):
    name: str

    def segment(self, view: CameraView, cloud: OrganisedCloud | None) -> list[np.ndarray]:
        """Flat pixel indices (row * width + col) of each mask.

        ``cloud`` is the view back-projected and cropped to the work region (None when
        nothing there is seen); backends that use depth geometry read it, others ignore it.
        """

    def segment_views(
        self, views: list[CameraView], clouds: list[OrganisedCloud | None]
    ) -> list[list[np.ndarray]]:
        """``segment`` of each view (the frames of one instant): a backend may share work
        between the views."""


class SegmenterError(ValueError):
    """A backend cannot be built from the given settings; the message says why."""

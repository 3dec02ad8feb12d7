"""Segment Anything backend: automatic masks from a grid of point prompts (as the paper).

Used when the user gives a SAM checkpoint (none can be downloaded here; see
docs/PERCEPTION.md for where to get one). Runs on the CPU with torch alone:

* ``segment_anything``'s package ``__init__`` imports its predictor, whose resize
  helper imports torchvision, and its automatic mask generator imports torchvision's
  NMS. PyPI's torchvision does not load beside this project's CPU torch ("operator
  torchvision::nms does not exist"), so this module imports only the torchvision-free
  parts (``modeling``, ``build_sam``, ``utils.amg``) and does the two remaining steps
  itself: the longest-side resize (``torch.nn.functional.interpolate``) and box NMS.
* Prompts are laid only on pixels that see the work region above the table (from the
  organised cloud), so the table, the arm and the background cost nothing.
"""

from __future__ import annotations

import importlib.util
import sys
import types
from pathlib import Path

import numpy as np
import torch
import torch.nn.functional as F  # noqa: N812 (torch's own convention)

from dombot_perception.backprojection import OrganisedCloud
from dombot_perception.frames import CameraView
from dombot_perception.segmentation import SegmenterError


def _segment_anything_without_init() -> None:
    """Register the ``segment_anything`` package without running its ``__init__``."""
    if "segment_anything" in sys.modules:
        return
    spec = importlib.util.find_spec("segment_anything")
    if spec is None or not spec.submodule_search_locations:
        raise SegmenterError("the segment_anything package is not installed")
    package = types.ModuleType("segment_anything")
    package.__path__ = list(spec.submodule_search_locations)
    package.__spec__ = spec
    sys.modules["segment_anything"] = package


_segment_anything_without_init()
from segment_anything.build_sam import sam_model_registry  # noqa: E402
from segment_anything.modeling import Sam  # noqa: E402
from segment_anything.utils.amg import (  # noqa: E402
    batched_mask_to_box,
    build_point_grid,
    calculate_stability_score,
)


def load_sam(model_type: str, checkpoint: str) -> Sam:
    """A SAM model of ``model_type`` (vit_b, vit_l, vit_h) with weights from ``checkpoint``."""
    if model_type not in sam_model_registry or model_type == "default":
        raise SegmenterError(f"unknown SAM model type {model_type!r}; choose vit_b, vit_l or vit_h")
    path = Path(checkpoint)
    if not path.is_file():
        raise SegmenterError(f"SAM checkpoint {path} does not exist")
    try:
        model = sam_model_registry[model_type](checkpoint=str(path))
    except (RuntimeError, KeyError, OSError) as error:
        raise SegmenterError(f"cannot load {path} as a {model_type} checkpoint: {error}") from None
    return model.eval()


class SamSegmenter:
    """SAM's automatic mask generation (point grid → masks → quality filters → NMS)."""

    name = "sam"

    def __init__(
        self,
        model: Sam,
        points_per_side: int = 32,
        points_per_batch: int = 64,
        pred_iou_threshold: float = 0.88,
        stability_threshold: float = 0.92,
        nms_threshold: float = 0.7,
        min_pixels: int = 25,
    ) -> None:
        if points_per_side < 1:
            raise SegmenterError(f"points_per_side must be at least 1, got {points_per_side}")
        self.model = model.eval()
        self.grid = build_point_grid(points_per_side)
        self.points_per_batch = points_per_batch
        self.pred_iou_threshold = pred_iou_threshold
        self.stability_threshold = stability_threshold
        self.nms_threshold = nms_threshold
        self.min_pixels = min_pixels

    def segment_views(
        self, views: list[CameraView], clouds: list[OrganisedCloud | None]
    ) -> list[list[np.ndarray]]:
        """Each view on its own: SAM embeds one image at a time."""
        return [self.segment(view, cloud) for view, cloud in zip(views, clouds, strict=True)]

    @torch.inference_mode()
    def segment(self, view: CameraView, cloud: OrganisedCloud | None) -> list[np.ndarray]:
        height, width = view.depth.shape
        prompts = self._prompts(cloud, height, width)
        if prompts.shape[0] == 0:
            return []
        embedding, input_size, scale = self._embed(view.rgb)
        masks, scores = [], []
        for start in range(0, prompts.shape[0], self.points_per_batch):
            batch = prompts[start : start + self.points_per_batch]
            batch_masks, batch_scores = self._predict(
                embedding, batch * scale, input_size, (height, width)
            )
            masks.append(batch_masks)
            scores.append(batch_scores)
        masks_t, scores_t = torch.cat(masks), torch.cat(scores)
        if masks_t.shape[0] == 0:
            return []
        keep = box_nms(batched_mask_to_box(masks_t).float(), scores_t, self.nms_threshold)
        flat = masks_t[keep].reshape(len(keep), -1).numpy()
        return [np.flatnonzero(row) for row in flat if row.sum() >= self.min_pixels]

    def _prompts(self, cloud: OrganisedCloud | None, height: int, width: int) -> np.ndarray:
        """Grid points (x, y pixels) that fall on the work region's valid pixels."""
        points = self.grid * np.array([width, height])
        if cloud is None:
            return points[:0]
        cols = np.clip(points[:, 0].astype(int), 0, width - 1)
        rows = np.clip(points[:, 1].astype(int), 0, height - 1)
        flat = cloud.crop_index(rows * width + cols)
        local_rows, local_cols = rows - cloud.top, cols - cloud.left
        inside = (
            (local_rows >= 0)
            & (local_rows < cloud.valid.shape[0])
            & (local_cols >= 0)
            & (local_cols < cloud.valid.shape[1])
        )
        usable = np.zeros(points.shape[0], dtype=bool)
        usable[inside] = cloud.valid.ravel()[flat[inside]]
        return points[usable]

    def _embed(self, rgb: np.ndarray) -> tuple[torch.Tensor, tuple[int, int], float]:
        """Image embedding after SAM's longest-side resize; also the resized size and scale."""
        target = self.model.image_encoder.img_size
        height, width = rgb.shape[:2]
        scale = target / max(height, width)
        size = (int(height * scale + 0.5), int(width * scale + 0.5))
        image = torch.as_tensor(rgb).permute(2, 0, 1)[None].float()
        resized = F.interpolate(image, size=size, mode="bilinear", antialias=True)
        resized = resized.round().clamp(0, 255)
        embedding = self.model.image_encoder(self.model.preprocess(resized[0])[None])
        return embedding, size, scale

    def _predict(
        self,
        embedding: torch.Tensor,
        points: np.ndarray,
        input_size: tuple[int, int],
        original_size: tuple[int, int],
    ) -> tuple[torch.Tensor, torch.Tensor]:
        """Masks (N, H, W bool) and scores of one prompt batch, quality-filtered."""
        coords = torch.as_tensor(points, dtype=torch.float32)[:, None, :]
        labels = torch.ones(coords.shape[0], 1, dtype=torch.int)
        sparse, dense = self.model.prompt_encoder(points=(coords, labels), boxes=None, masks=None)
        low_res, iou = self.model.mask_decoder(
            image_embeddings=embedding,
            image_pe=self.model.prompt_encoder.get_dense_pe(),
            sparse_prompt_embeddings=sparse,
            dense_prompt_embeddings=dense,
            multimask_output=True,
        )
        logits = self.model.postprocess_masks(low_res, input_size, original_size).flatten(0, 1)
        iou = iou.flatten()
        threshold = self.model.mask_threshold
        stability = calculate_stability_score(logits, threshold, 1.0)
        keep = (iou > self.pred_iou_threshold) & (stability >= self.stability_threshold)
        return logits[keep] > threshold, iou[keep]


def box_nms(boxes: torch.Tensor, scores: torch.Tensor, threshold: float) -> torch.Tensor:
    """Greedy non-maximum suppression (torchvision.ops.nms semantics), indices best first."""
    order = torch.argsort(scores, descending=True)
    boxes = boxes[order]
    areas = (boxes[:, 2] - boxes[:, 0]) * (boxes[:, 3] - boxes[:, 1])
    top_left = torch.maximum(boxes[:, None, :2], boxes[None, :, :2])
    bottom_right = torch.minimum(boxes[:, None, 2:], boxes[None, :, 2:])
    overlap = (bottom_right - top_left).clamp(min=0).prod(dim=2)
    iou = overlap / (areas[:, None] + areas[None, :] - overlap).clamp(min=1e-9)
    suppressed = torch.zeros(len(order), dtype=torch.bool)
    kept = []
    for index in range(len(order)):
        if suppressed[index]:
            continue
        kept.append(index)
        suppressed |= iou[index] > threshold
    return order[torch.as_tensor(kept, dtype=torch.long)]

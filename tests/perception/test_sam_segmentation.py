"""The SAM backend's code path with a small randomly initialised model (no checkpoint can
be downloaded here): prompts, batching, quality filters, NMS, masks into the pipeline."""

from __future__ import annotations

from typing import TYPE_CHECKING

import numpy as np
import pytest

from dombot_description.scenario import load_scenario
from dombot_perception.backprojection import organised_cloud
from dombot_perception.pipeline import PerceptionPipeline, config_for_scenario, make_segmenter
from dombot_perception.segmentation import SegmenterError
from support.perception_scenes import PILE_CENTRE, flat

if TYPE_CHECKING:
    from segment_anything.modeling import Sam

    from dombot_perception.sam_segmentation import SamSegmenter

# torch, and the SAM code that needs it, are imported by the tests, not here: every
# pytest-xdist worker collects this module, and torch's import takes seconds.


def tiny_sam(seed: int = 0, width: int = 32, image_size: int = 128) -> Sam:
    """SAM's architecture at toy size (a few thousand weights), randomly initialised."""
    import torch

    import dombot_perception.sam_segmentation  # noqa: F401 (sets segment_anything up)

    # isort: split
    from segment_anything.modeling import (
        ImageEncoderViT,
        MaskDecoder,
        PromptEncoder,
        Sam,
        TwoWayTransformer,
    )

    torch.manual_seed(seed)
    grid = image_size // 16
    return Sam(
        image_encoder=ImageEncoderViT(
            depth=1,
            embed_dim=width,
            img_size=image_size,
            mlp_ratio=2,
            num_heads=2,
            patch_size=16,
            qkv_bias=True,
            use_rel_pos=True,
            global_attn_indexes=[0],
            window_size=4,
            out_chans=width,
        ),
        prompt_encoder=PromptEncoder(
            embed_dim=width,
            image_embedding_size=(grid, grid),
            input_image_size=(image_size, image_size),
            mask_in_chans=4,
        ),
        mask_decoder=MaskDecoder(
            num_multimask_outputs=3,
            transformer=TwoWayTransformer(depth=1, embedding_dim=width, mlp_dim=64, num_heads=2),
            transformer_dim=width,
            iou_head_depth=1,
            iou_head_hidden_dim=16,
        ),
        pixel_mean=[123.675, 116.28, 103.53],
        pixel_std=[58.395, 57.12, 57.375],
    ).eval()


@pytest.fixture(scope="module")
def scene(render_scene):
    return render_scene({0: flat(*PILE_CENTRE, yaw=0.2)})


@pytest.fixture(scope="module")
def region_config():
    return config_for_scenario(load_scenario())


def permissive(model: Sam) -> SamSegmenter:
    """Random weights predict poor masks: keep them all so every step runs."""
    from dombot_perception.sam_segmentation import SamSegmenter

    return SamSegmenter(
        model,
        points_per_side=32,
        points_per_batch=16,
        pred_iou_threshold=-1.0,
        stability_threshold=-1.0,
    )


def test_masks_are_pixel_indices_and_repeat_for_the_same_seed(scene, region_config) -> None:
    view = scene[0]
    cloud = organised_cloud(view, region_config.region, region_config.depth_range)
    first = permissive(tiny_sam(seed=1)).segment(view, cloud)
    again = permissive(tiny_sam(seed=1)).segment(view, cloud)
    assert first, "a permissive run keeps at least one mask"
    pixels = view.depth.size
    for mask in first:
        assert mask.dtype.kind == "i" and mask.min() >= 0 and mask.max() < pixels
        assert np.all(np.diff(mask) > 0)
    assert [m.tolist() for m in first] == [m.tolist() for m in again]


def test_prompts_only_where_the_work_region_is_seen(scene) -> None:
    segmenter = permissive(tiny_sam())
    assert segmenter.segment(scene[0], None) == []


def test_strict_quality_filters_can_reject_everything(scene, region_config) -> None:
    view = scene[0]
    cloud = organised_cloud(view, region_config.region, region_config.depth_range)
    from dombot_perception.sam_segmentation import SamSegmenter

    strict = SamSegmenter(tiny_sam(), points_per_side=32, pred_iou_threshold=2.0)
    assert strict.segment(view, cloud) == []


def test_sam_masks_flow_through_the_whole_pipeline(scene, region_config) -> None:
    result = PerceptionPipeline(permissive(tiny_sam()), region_config).run(scene)
    assert set(result.masks) == {"camera_0", "camera_1"}
    assert result.timings["segmentation"] > 0
    assert all(d.fit_error <= region_config.filtering.max_fit_error for d in result.detections)


def test_box_nms_keeps_the_best_of_overlapping_boxes() -> None:
    import torch

    from dombot_perception.sam_segmentation import box_nms

    boxes = torch.tensor([[0, 0, 10, 10], [1, 1, 10, 10], [20, 20, 30, 30]], dtype=torch.float)
    scores = torch.tensor([0.8, 0.9, 0.5])
    assert box_nms(boxes, scores, 0.7).tolist() == [1, 2]


def test_missing_checkpoint_or_model_type_is_a_clear_error(tmp_path) -> None:
    from dombot_perception.sam_segmentation import load_sam

    with pytest.raises(SegmenterError, match="does not exist"):
        load_sam("vit_b", str(tmp_path / "sam_vit_b.pth"))
    with pytest.raises(SegmenterError, match="model type"):
        load_sam("vit_x", str(tmp_path / "sam.pth"))
    with pytest.raises(SegmenterError, match="checkpoint"):
        make_segmenter("sam")
    with pytest.raises(SegmenterError, match="unknown"):
        make_segmenter("magic")

"""perception_node's parameters without a node: a wrong value is named, and the node's
fallback is the declared defaults (its scenario and cameras kept: already in use)."""

from __future__ import annotations

from dataclasses import replace

import pytest

from dombot_description.scenario import load_scenario
from dombot_perception.perception_parameters import (
    PerceptionParameters,
    configured_pipeline,
    default_settings,
)


@pytest.mark.parametrize("value", [0.0, -1.0, float("nan"), True, "10"])
def test_a_fresh_frame_timeout_that_is_no_positive_number_is_named(value: object) -> None:
    wrong = replace(PerceptionParameters(), fresh_frame_timeout=value)
    with pytest.raises(ValueError, match="fresh_frame_timeout must be a positive number"):
        configured_pipeline(load_scenario(), wrong)


def test_the_fallback_is_the_defaults_with_the_cameras_and_scenario_in_use() -> None:
    wrong = replace(
        PerceptionParameters(), cameras=("camera_0",), fresh_frame_timeout=-1.0, rate=-2.0
    )
    fallback = default_settings(wrong)
    assert fallback == replace(PerceptionParameters(), cameras=("camera_0",))
    assert fallback.fresh_frame_timeout == 10.0
    configured_pipeline(load_scenario(), fallback)  # no error

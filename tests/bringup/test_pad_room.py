"""The fingers' room at each slot, told before the build (``pad_room``, no ROS).

A new user's spiral of 35 mm pitch (centre 0.55 0.16, inner radius 0.04, 16 dominoes,
seed 3838) had slots 13, 15 and 16 refused during the build: every place pose put the
pads into the inner turn. The planner's own test, asked of the layout, foresees two of
them; a pitch the pads fit leaves nothing to say, as the benchmarks' layouts do."""

from __future__ import annotations

import pytest

from dombot_bringup import layouts
from dombot_bringup.bringup import cycle_layouts, parse_args
from dombot_bringup.pad_room import crowded_slots, crowded_words
from dombot_description.scenario import load_scenario

SPIRAL = ["--layout", "spiral", "--center", "0.55", "0.16", "--inner-radius", "0.04"]


def spiral(pitch: float) -> list[layouts.DominoPlacement]:
    return layouts.spiral((0.55, 0.16), 0.04, pitch, 16)


def test_a_spiral_too_tight_for_the_pads_names_the_outer_slots_and_the_inner_dominoes() -> None:
    crowded = crowded_slots(spiral(0.035))
    assert sorted(crowded) == [14, 15]  # slots 15 and 16
    assert crowded_words(crowded) == [
        "domino 15 has no room for the fingers beside dominoes 1, 2, 3 standing: expect it "
        "refused (space the run wider there)",
        "domino 16 has no room for the fingers beside dominoes 1, 2, 3, 4 standing: expect it "
        "refused (space the run wider there)",
    ]


@pytest.mark.parametrize("pitch", [0.045, 0.06])
def test_a_spiral_the_pads_fit_has_nothing_to_say(pitch: float) -> None:
    assert crowded_slots(spiral(pitch)) == {}


def test_the_bringup_says_so_before_anything_moves(capsys) -> None:
    scenario = load_scenario()
    area = layouts.BuildArea(*scenario.build_x, *scenario.build_y, *scenario.build_reach)
    cycle_layouts(parse_args([*SPIRAL, "--pitch", "0.035", "--count", "16"]), area)
    out = capsys.readouterr().out.splitlines()
    assert [line.split(" has ")[0] for line in out] == [
        "[bringup] layout: domino 15",
        "[bringup] layout: domino 16",
    ]
    cycle_layouts(parse_args([*SPIRAL, "--pitch", "0.035", "--count", "16", "--cycles", "3"]), area)
    assert len(capsys.readouterr().out.splitlines()) == 2  # one layout, said once
    cycle_layouts(parse_args([*SPIRAL, "--pitch", "0.05", "--count", "16"]), area)
    assert capsys.readouterr().out == ""

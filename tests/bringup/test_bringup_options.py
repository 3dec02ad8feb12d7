"""The bring-up's options are checked before any node starts."""

from __future__ import annotations

import pytest

from dombot_bringup import layouts
from dombot_bringup.bringup import main, make_layout, parse_args, run_arm
from dombot_bringup.layouts import LayoutError
from dombot_description.scenario import load_scenario


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--pile-core-shrink", "13", r"--pile-core-shrink must be 0\.\.12 mm"),
        ("--in-hand-tolerance", "-1", r"--in-hand-tolerance must be 0\.\.3 mm"),
        ("--place-lead", "4", r"--place-lead must be 0\.\.3 mm"),
        ("--spreads", "-1", r"--spreads must be 0\.\.5"),
        ("--pile", "5", r"a run of 10 needs at least as many dominoes"),
    ],
)
def test_a_bad_option_value_is_refused_with_its_name(option: str, value: str, message: str) -> None:
    with pytest.raises(LayoutError, match=message):
        run_arm(parse_args([option, value]))


@pytest.mark.parametrize("layout", ["line", "arc", "circle", "spiral", "s-curve"])
def test_every_layout_with_its_defaults_fits_the_build_area(layout: str) -> None:
    args = parse_args(["--layout", layout])
    scenario = load_scenario()
    area = layouts.BuildArea(*scenario.build_x, *scenario.build_y, *scenario.build_reach)
    placements = make_layout(args, area)
    layouts.validate(placements, area)
    assert 1 < len(placements) <= args.pile


def test_a_directory_as_csv_is_a_usage_error_without_a_traceback(tmp_path, capsys) -> None:
    assert main(["--layout", "csv", "--csv", str(tmp_path)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("bringup: layout rejected: cannot read --csv")
    assert "it is a directory" in error

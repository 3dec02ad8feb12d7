"""The bring-up's options are checked before any node starts."""

from __future__ import annotations

import pytest

from dombot_bringup.bringup import parse_args, run_arm
from dombot_bringup.layouts import LayoutError


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--pile-core-shrink", "13", r"--pile-core-shrink must be 0\.\.12 mm"),
        ("--in-hand-tolerance", "-1", r"--in-hand-tolerance must be 0\.\.3 mm"),
        ("--place-lead", "4", r"--place-lead must be 0\.\.3 mm"),
        ("--spreads", "-1", r"--spreads must be 0\.\.5"),
        ("--plan-budget", "0", r"--plan-budget must be 0\.\.3600 s, not 0"),
        ("--pile", "5", r"a run of 10 needs at least as many dominoes"),
    ],
)
def test_a_bad_option_value_is_refused_with_its_name(option: str, value: str, message: str) -> None:
    with pytest.raises(LayoutError, match=message):
        run_arm(parse_args([option, value]))

"""The bring-up's options are checked before any node starts."""

from __future__ import annotations

import io

import pytest

from dombot_bringup import layouts
from dombot_bringup.arm_job import hold_viewer, recorder_command
from dombot_bringup.bringup import (
    circle_count,
    cycle_layouts,
    domain_problem,
    main,
    make_layout,
    parse_args,
    run_arm,
)
from dombot_bringup.layouts import LayoutError
from dombot_bringup.task.settings import ArmJobSettings
from dombot_description.scenario import load_scenario


@pytest.mark.parametrize(
    ("option", "value", "message"),
    [
        ("--pile-core-shrink", "13", r"--pile-core-shrink must be 0\.\.12 mm"),
        ("--in-hand-tolerance", "-1", r"--in-hand-tolerance must be 0\.\.3 mm"),
        ("--place-lead", "4", r"--place-lead must be 0\.\.3 mm"),
        ("--spreads", "-1", r"--spreads must be 0\.\.5"),
        ("--plan-budget", "0", r"--plan-budget must be 0\.\.3600 s, not 0"),
        ("--record-image-rate", "-1", r"--record-image-rate must be 0\.\.100 Hz"),
        ("--pile", "5", r"a run of 10 needs at least as many dominoes"),
    ],
)
def test_a_bad_option_value_is_refused_with_its_name(option: str, value: str, message: str) -> None:
    with pytest.raises(LayoutError, match=message):
        run_arm(parse_args([option, value]))


@pytest.mark.parametrize("domain", ["233", "999", "one", "-1"])
def test_a_domain_fast_dds_cannot_open_is_refused_before_any_node_starts(
    capsys, monkeypatch, domain: str
) -> None:
    """Each node would fail on its own ("Calculated port number is too high") and the job
    wait for them: refused at once, exit 2, saying what a domain may be."""
    monkeypatch.setenv("ROS_DOMAIN_ID", domain)
    monkeypatch.setattr("dombot_bringup.bringup.run_arm", lambda args: pytest.fail("started"))
    assert main(["--count", "4"]) == 2
    assert f"ROS_DOMAIN_ID='{domain}' cannot work: a domain is a whole number 0-232" in (
        capsys.readouterr().err
    )
    assert domain_problem({"ROS_DOMAIN_ID": "232"}) is None
    assert domain_problem({}) is None


def test_foxglove_without_the_sdk_says_how_to_install_it(capsys, monkeypatch) -> None:
    monkeypatch.setattr("dombot_bringup.bringup.foxglove_available", lambda: False)
    assert main(["--foxglove"]) == 2
    assert "pip install foxglove-sdk" in capsys.readouterr().err


def test_record_and_foxglove_start_the_recorder_with_their_options(tmp_path) -> None:
    def command(package: str, executable: str, parameters: dict) -> list[str]:
        return [
            f"{package}/{executable}",
            "--ros-args",
            *(f"{k}:={v}" for k, v in parameters.items()),
        ]

    assert recorder_command(tmp_path, ArmJobSettings(), command) == []
    settings = ArmJobSettings(record=True, record_image_rate=0.5, foxglove_port=9000)
    assert recorder_command(tmp_path, settings, command) == [
        "dombot_bringup/record",
        "-o",
        str(tmp_path / "run.mcap"),
        "--image-rate",
        "0.5",
        "--foxglove-port",
        "9000",
        "--ros-args",
        "use_sim_time:=True",
    ]


def test_the_viewer_is_held_only_on_a_terminal(capsys) -> None:
    class Terminal(io.StringIO):
        def isatty(self) -> bool:
            return True

    hold_viewer("http://localhost:7000", io.StringIO("\n"))  # a pipe: no wait, no prompt
    assert "press Enter" not in capsys.readouterr().out
    terminal = Terminal("\n")
    hold_viewer("http://localhost:7000", terminal)
    assert (
        "[bringup] Meshcat stays at http://localhost:7000; press Enter" in capsys.readouterr().out
    )
    assert terminal.tell() == 1  # the Enter was read
    hold_viewer("http://localhost:7000", Terminal(""))  # end of input counts as Enter


@pytest.mark.parametrize("layout", ["line", "arc", "circle", "spiral", "s-curve"])
def test_every_layout_with_its_defaults_fits_the_build_area(layout: str) -> None:
    args = parse_args(["--layout", layout])
    scenario = load_scenario()
    area = layouts.BuildArea(*scenario.build_x, *scenario.build_y, *scenario.build_reach)
    placements = make_layout(args, area)
    layouts.validate(placements, area)
    assert 1 < len(placements) <= args.pile


def test_a_circle_says_how_many_it_takes_and_that_count_does_not_set_it(capsys) -> None:
    """Around 0.1 m at the default 28.8 mm spacing 21 fit: --count 14 is not used."""
    args = parse_args(["--layout", "circle", "--count", "14"])
    scenario = load_scenario()
    area = layouts.BuildArea(*scenario.build_x, *scenario.build_y, *scenario.build_reach)
    ((name, placements),) = cycle_layouts(args, area)
    assert name == "circle" and len(placements) == 21
    assert capsys.readouterr().out == (
        "[bringup] circle: 21 dominoes, as many as fit around its radius of 0.100 m at a "
        "spacing of 28.8 mm, one gap left for the strike; --count 14 is not used (a circle's "
        "count follows --radius and --spacing)\n"
    )
    assert "not used" not in circle_count(0.14, 0.0288, 30, 30)  # as asked: nothing to say
    make_layout(args, area)  # benchmarks print JSON with it: no line of its own
    assert capsys.readouterr().out == ""


def test_a_directory_as_csv_is_a_usage_error_without_a_traceback(tmp_path, capsys) -> None:
    assert main(["--layout", "csv", "--csv", str(tmp_path)]) == 2
    error = capsys.readouterr().err
    assert error.startswith("bringup: layout rejected: cannot read --csv")
    assert "it is a directory" in error


@pytest.mark.parametrize(
    ("options", "probe", "asked"),
    [
        ([], "gap_probe_dominoes", ArmJobSettings.gap_probe_dominoes),
        (["--gaps-as-laid-out"], "gap_probe_dominoes", 0),
        ([], "order_probe_dominoes", ArmJobSettings.order_probe_dominoes),
        (["--run-order"], "order_probe_dominoes", 0),
    ],
)
def test_the_gaps_and_where_each_stretch_starts_are_asked_of_the_planner_unless_turned_off(
    monkeypatch, options: list[str], probe: str, asked: int
) -> None:
    settings = []
    monkeypatch.setattr(
        "dombot_bringup.bringup.run_arm_job", lambda out, chosen, s, command: settings.append(s)
    )
    run_arm(parse_args(options))
    assert getattr(settings[0], probe) == asked

"""The bring-up's vehicle job end to end: real node processes over DDS, a report on disk."""

from __future__ import annotations

import json
import subprocess
from pathlib import Path

import pytest

from support.ros_processes import executable_path


def bringup(*args: str, timeout: float = 900) -> subprocess.CompletedProcess[str]:
    executable = executable_path("dombot_bringup", "bringup")
    return subprocess.run(
        [str(executable), "--job", "layer", *args], capture_output=True, text=True, timeout=timeout
    )


@pytest.mark.slow
def test_vehicle_lays_an_arc_on_the_requested_radius(tmp_path: Path) -> None:
    result = bringup("--out", str(tmp_path), "--speed", "0.4")
    assert result.returncode == 0, result.stdout[-3000:] + result.stderr[-3000:]
    report = json.loads((tmp_path / "layer_report.json").read_text())
    assert report["success"]
    assert abs(report["dominoes_laid"] - report["dominoes_expected"]) <= 1
    assert report["settled_radius_error_m"] <= 1e-4
    assert abs(report["spacing_min_m"] - 0.03) < 1e-3
    assert (tmp_path / "layer_run.png").stat().st_size > 10_000
    assert "[layer_node]" in result.stdout and "[vehicle_sim_node]" in result.stdout


@pytest.mark.slow
def test_an_arc_tighter_than_the_vehicle_can_lay_is_refused_clearly(tmp_path: Path) -> None:
    result = bringup("--out", str(tmp_path), "--radius", "0.02", "--sweep", "90")
    assert result.returncode == 1
    assert "minimum laying radius" in result.stderr
    assert "Traceback" not in result.stderr
    assert not (tmp_path / "layer_report.json").exists()


def test_bad_arguments_exit_2(tmp_path: Path) -> None:
    result = bringup("--out", str(tmp_path), "--speed", "-1")
    assert result.returncode == 2
    assert "--speed must be positive" in result.stderr

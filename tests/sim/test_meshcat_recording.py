"""Meshcat's recording of the cell, written as one HTML page that plays it offline
(sim_node's ``meshcat_recording_path``)."""

from __future__ import annotations

from pathlib import Path

import pytest

from dombot_sim.sim_parameters import SimParameters
from dombot_sim.world import CellWorld, WorldConfig


def test_the_recording_is_written_with_its_animation(tmp_path: Path) -> None:
    world = CellWorld(WorldConfig(cameras=False, meshcat=True, domino_capacity=1))
    world.start_meshcat_recording()
    world.advance(0.5)
    path = tmp_path / "scenes" / "scene.html"
    world.save_meshcat_recording(path)
    page = path.read_text()
    assert page.startswith("<!DOCTYPE html>")
    assert "set_animation" in page


def test_without_meshcat_there_is_nothing_to_record(tmp_path: Path) -> None:
    world = CellWorld(WorldConfig(cameras=False, domino_capacity=1))
    with pytest.raises(ValueError, match="Meshcat is off"):
        world.start_meshcat_recording()
    with pytest.raises(ValueError, match=r"^meshcat_recording_path needs meshcat:=true$"):
        SimParameters(meshcat=False, meshcat_recording_path="a.html")

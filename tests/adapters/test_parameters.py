"""A settings dataclass as ROS parameters: declared with defaults and descriptions, read
back as the dataclass, an update judged by the dataclass's own checks."""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import dataclass

import pytest
import rclpy
from rclpy.node import Node
from rclpy.parameter import Parameter

from dombot_adapters.parameters import DataclassParameters, described


@dataclass(frozen=True)
class Settings:
    speed: float = described(0.5, "how fast [m/s]")
    names: tuple[str, ...] = described(("a", "b"), "who")
    region: tuple[float, float] = (0.0, 1.0)
    steps: int = 3

    def __post_init__(self) -> None:
        if self.speed <= 0:
            raise ValueError(f"speed must be positive, got {self.speed}")


@pytest.fixture
def node() -> Iterator[Node]:
    rclpy.init()
    node = Node("parameters_test")
    yield node
    node.destroy_node()
    rclpy.shutdown()


def test_fields_are_declared_with_defaults_and_descriptions(node: Node) -> None:
    parameters = DataclassParameters(node, Settings, prefix="drive.", description="see docs")
    assert parameters.names == ["drive.speed", "drive.names", "drive.region", "drive.steps"]
    assert node.get_parameter("drive.names").value == ["a", "b"]
    described_ = node.describe_parameters(["drive.speed", "drive.steps"])
    assert [d.description for d in described_] == ["how fast [m/s]", "see docs"]
    assert parameters.read() == Settings()


def test_an_update_is_laid_over_the_current_values_and_tuples_come_back(node: Node) -> None:
    parameters = DataclassParameters(node, Settings)
    update = [Parameter("region", value=[2.0, 3.0]), Parameter("someone_else", value=1)]
    settings = parameters.read(update)
    assert settings == Settings(region=(2.0, 3.0))
    assert parameters.owns("region") and not parameters.owns("someone_else")
    assert node.get_parameter("region").value == [0.0, 1.0]  # read does not set


def test_the_dataclass_refuses_a_bad_update(node: Node) -> None:
    parameters = DataclassParameters(node, Settings)
    with pytest.raises(ValueError, match=r"speed must be positive, got -1\.0"):
        parameters.read([Parameter("speed", value=-1.0)])


def test_a_field_without_a_default_cannot_be_a_parameter(node: Node) -> None:
    @dataclass(frozen=True)
    class Incomplete:
        needed: float

    with pytest.raises(TypeError, match=r"Incomplete\.needed needs a default"):
        DataclassParameters(node, Incomplete)


def test_a_list_default_is_refused_for_a_tuple() -> None:
    with pytest.raises(TypeError, match="use a tuple"):
        described([1, 2], "shared between instances")

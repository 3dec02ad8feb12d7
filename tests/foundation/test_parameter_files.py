"""Each node's parameter file (share/<pkg>/config/<node>.yaml) is a ros2 params file that
rcl accepts for that node and that holds exactly the node's declared defaults."""

from __future__ import annotations

from pathlib import Path

import pytest
import rclpy
from ament_index_python.packages import get_package_share_directory
from rcl_interfaces.msg import ParameterType, ParameterValue
from rcl_interfaces.srv import GetParameters, ListParameters
from rclpy.parameter import parameter_value_to_python

from dombot_sim.sim_parameters import SimParameters
from support.ros_processes import call_service, installed_node, spin_until

pytestmark = pytest.mark.slow  # starts every node

NODES = [
    ("dombot_sim", "sim_node"),
    ("dombot_perception", "perception_node"),
    ("dombot_planner", "planner_node"),
    ("dombot_layer", "layer_node"),
    ("dombot_layer", "vehicle_sim_node"),
]
RCLPY_OWN = {"start_type_description_service"}  # read-only, set by rclpy for every node
# Started with these instead of their defaults: sim_node answers only once it has poured
# its pile, 30 dominoes by default (minutes on a loaded machine), none with this. Each must
# read back as started; its default is the one of the dataclass the node declares from.
STARTED_WITH = {"sim_node": {"domino_count": 0}}
DECLARED_FROM = {"sim_node": SimParameters()}


def parameter_file(package: str, node: str) -> Path:
    return Path(get_package_share_directory(package)) / "config" / f"{node}.yaml"


def plain(value: ParameterValue):
    python = parameter_value_to_python(value)
    return (
        value.type,
        list(python) if hasattr(python, "__len__") and not isinstance(python, str) else python,
    )


def as_loaded_by_rcl(path: Path, node_name: str) -> dict[str, tuple]:
    """The parameters a node named ``node_name`` gets from ``--ros-args --params-file``."""
    context = rclpy.Context()
    rclpy.init(args=["--ros-args", "--params-file", str(path)], context=context)
    try:
        node = rclpy.create_node(
            node_name, context=context, automatically_declare_parameters_from_overrides=True
        )
        loaded = {
            name: plain(parameter.get_parameter_value())
            for name, parameter in node._parameters.items()
            if name not in RCLPY_OWN
        }
        node.destroy_node()
        return loaded
    finally:
        rclpy.shutdown(context=context)


def declared_defaults(package: str, executable: str) -> dict[str, tuple]:
    """Every set parameter of the real node, over its services (those in STARTED_WITH: the
    default it declares them with)."""
    started_with = STARTED_WITH.get(executable, {})
    arguments = ["--ros-args"] if started_with else []
    for name, value in started_with.items():
        arguments += ["-p", f"{name}:={value}"]
    rclpy.init()
    try:
        with installed_node(package, executable, *arguments) as process:
            node = rclpy.create_node("parameter_file_probe")
            lister = node.create_client(ListParameters, f"/{executable}/list_parameters")
            getter = node.create_client(GetParameters, f"/{executable}/get_parameters")
            assert spin_until(node, getter.service_is_ready, 120), process.poll()
            listed = call_service(node, lister, ListParameters.Request(), timeout=60, tries=6)
            assert listed is not None, "no answer from list_parameters"
            values = {}
            for name in sorted(set(listed.result.names) - RCLPY_OWN):
                got = call_service(node, getter, GetParameters.Request(names=[name]), timeout=30)
                assert got is not None, f"no answer from get_parameters for {name}"
                values[name] = got.values  # empty for one declared without a value
            node.destroy_node()
    finally:
        rclpy.shutdown()
    reported = {
        name: plain(value[0])
        for name, value in values.items()
        if value and value[0].type != ParameterType.PARAMETER_NOT_SET
    }
    for name, value in started_with.items():
        assert reported[name][1] == value, (name, reported[name])
        reported[name] = (reported[name][0], getattr(DECLARED_FROM[executable], name))
    return reported


@pytest.mark.parametrize(("package", "executable"), NODES, ids=[n for _, n in NODES])
def test_the_parameter_file_holds_the_declared_defaults_and_rcl_accepts_it(
    package: str, executable: str
) -> None:
    path = parameter_file(package, executable)
    assert path.is_file(), f"{path} is not installed"
    loaded = as_loaded_by_rcl(path, executable)
    defaults = declared_defaults(package, executable)
    assert loaded == defaults

"""The installed ``*.launch.py`` files (for a system ROS 2 with launch, which is not
installable here) parse, and name executables, parameter files and parameters that
exist. They are read as source, never imported."""

from __future__ import annotations

import ast
from pathlib import Path

import pytest
from ament_index_python.packages import get_package_share_directory
from rclpy.parameter import parameter_dict_from_yaml_file

from support.ros_processes import executable_path

LAUNCH_DIR = Path(get_package_share_directory("dombot_bringup")) / "launch"
LAUNCH_FILES = sorted(LAUNCH_DIR.glob("*.launch.py"))


def constant(tree: ast.Module, name: str, default=None):
    """The literal value assigned to a module-level ``name``."""
    for statement in tree.body:
        if isinstance(statement, ast.Assign) and any(
            isinstance(target, ast.Name) and target.id == name for target in statement.targets
        ):
            return ast.literal_eval(statement.value)
    return default


def test_the_bring_ups_launch_files_are_installed() -> None:
    assert {path.name for path in LAUNCH_FILES} == {
        "arm_cell.launch.py",
        "layer_vehicle.launch.py",
    }


@pytest.mark.parametrize("path", LAUNCH_FILES, ids=[path.name for path in LAUNCH_FILES])
def test_a_launch_file_names_nodes_config_files_and_parameters_that_exist(path: Path) -> None:
    tree = ast.parse(path.read_text(), filename=str(path))
    functions = {node.name for node in tree.body if isinstance(node, ast.FunctionDef)}
    assert "generate_launch_description" in functions
    nodes = constant(tree, "NODES")
    assert nodes, "no NODES table"
    for package, executable, overrides in nodes:
        assert executable_path(package, executable).is_file()
        config = Path(get_package_share_directory(package)) / "config" / f"{executable}.yaml"
        declared = set(parameter_dict_from_yaml_file(str(config))) | {"use_sim_time"}
        assert set(overrides) <= declared, f"{executable}: unknown {set(overrides) - declared}"
    arguments = constant(tree, "ARGUMENTS", {})
    sim_config = Path(get_package_share_directory("dombot_sim")) / "config" / "sim_node.yaml"
    assert set(arguments) <= set(parameter_dict_from_yaml_file(str(sim_config)))

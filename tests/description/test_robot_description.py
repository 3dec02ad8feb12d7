"""/robot_description's document: one URDF of arm and gripper that a URDF parser reads,
with the scenario's joints and the same kinematics as the cell the simulator builds."""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree

import numpy as np
from pydrake.multibody.parsing import Parser
from pydrake.multibody.plant import MultibodyPlant

from dombot_description.cell import add_cell
from dombot_description.robot_description import robot_urdf
from dombot_description.scenario import load_scenario

SCENARIO = load_scenario()


def test_one_tree_rooted_at_the_arm_base_with_the_tcp() -> None:
    root = ElementTree.fromstring(robot_urdf(SCENARIO))
    links = {link.get("name") for link in root.findall("link")}
    children = {joint.find("child").get("link") for joint in root.findall("joint")}
    assert links - children == {"iiwa_link_0"}
    assert {"wsg_body", "wsg_tcp", "iiwa_link_ee"} <= links
    movable = [j.get("name") for j in root.findall("joint") if j.get("type") != "fixed"]
    assert sorted(movable) == sorted(SCENARIO.arm_joints + SCENARIO.gripper_joints)


def set_joints(plant: MultibodyPlant, context, values: dict[str, float]) -> None:
    q = plant.GetPositions(context)
    for name, value in values.items():
        q[plant.GetJointByName(name).position_start()] = value
    plant.SetPositions(context, q)


def test_the_document_has_the_cells_kinematics() -> None:
    """Parsed by Drake, the tool centre point sits where the cell (directives) puts it."""
    robot = MultibodyPlant(time_step=0.0)
    Parser(robot).AddModelsFromString(robot_urdf(SCENARIO), "urdf")
    robot.WeldFrames(robot.world_frame(), robot.GetFrameByName("iiwa_link_0"))
    robot.Finalize()
    cell = MultibodyPlant(time_step=0.0)
    add_cell(cell, SCENARIO)
    cell.Finalize()
    robot_context, cell_context = robot.CreateDefaultContext(), cell.CreateDefaultContext()
    rng = np.random.default_rng(5)
    names = SCENARIO.arm_joints + SCENARIO.gripper_joints
    for _ in range(5):
        q = np.concatenate([rng.uniform(-1.5, 1.5, 7), rng.uniform(0.0, 0.055, 2)])
        set_joints(robot, robot_context, dict(zip(names, q, strict=True)))
        set_joints(cell, cell_context, dict(zip(names, q, strict=True)))
        for frame in (SCENARIO.tcp_frame, "wsg_left_finger"):
            got = robot.GetFrameByName(frame).CalcPoseInWorld(robot_context)
            expected = cell.GetFrameByName(frame).CalcPoseInWorld(cell_context)
            assert np.allclose(got.GetAsMatrix4(), expected.GetAsMatrix4(), atol=1e-9)

"""The robot (arm + gripper) as one URDF document: what ``/robot_description`` carries.

The scenario's model directives add the arm and the gripper from two URDF files and weld
the gripper to the arm's flange. RViz, robot_state_publisher and MoveIt want one
document, so this joins the two files' links and joints and turns the weld into a fixed
joint ``wsg_mount`` (parent ``iiwa_link_ee``, child ``wsg_body``) with the directives'
transform. Its root link is ``iiwa_link_0``; the cell places it in ``world``
(``/tf_static``). ROS-free.
"""

from __future__ import annotations

import xml.etree.ElementTree as ElementTree

from pydrake.math import RigidTransform, RollPitchYaw
from pydrake.multibody.parsing import LoadModelDirectives, PackageMap

from dombot_description import PACKAGE_DIR
from dombot_description.scenario import Scenario

ARM_MODEL = "iiwa"
GRIPPER_MODEL = "wsg"
ROBOT_NAME = "dombot"
MOUNT_JOINT = "wsg_mount"
DRAKE_NAMESPACE = "http://drake.mit.edu"
PARTS = ("material", "link", "joint", "transmission")


def robot_urdf(scenario: Scenario) -> str:
    """One URDF of the arm with the gripper on its flange, from the scenario's directives."""
    files, weld = _arm_and_gripper(scenario)
    ElementTree.register_namespace("drake", DRAKE_NAMESPACE)
    robot = ElementTree.Element("robot", {"name": ROBOT_NAME})
    materials: set[str] = set()
    for model in (ARM_MODEL, GRIPPER_MODEL):
        for element in ElementTree.parse(files[model]).getroot():
            if element.tag not in PARTS:
                continue
            if element.tag == "material":  # one definition per name in the joined document
                if element.get("name") in materials:
                    continue
                materials.add(element.get("name"))
            robot.append(element)
    robot.append(_fixed_joint(MOUNT_JOINT, *weld))
    ElementTree.indent(robot)
    return ElementTree.tostring(robot, encoding="unicode")


def _arm_and_gripper(scenario: Scenario) -> tuple[dict[str, str], tuple[str, str, RigidTransform]]:
    """The two models' files and the weld (parent link, child link, X_PC) between them."""
    packages = PackageMap()
    packages.Add("dombot_description", str(PACKAGE_DIR))
    files: dict[str, str] = {}
    weld = None
    for directive in LoadModelDirectives(str(scenario.directives_path)).directives:
        if directive.add_model and directive.add_model.name in (ARM_MODEL, GRIPPER_MODEL):
            files[directive.add_model.name] = packages.ResolveUrl(directive.add_model.file)
        joined = directive.add_weld
        if (
            joined
            and joined.parent.startswith(f"{ARM_MODEL}::")
            and joined.child.startswith(f"{GRIPPER_MODEL}::")
        ):
            x_pc = joined.X_PC.GetDeterministicValue() if joined.X_PC else RigidTransform()
            weld = (_link(joined.parent), _link(joined.child), x_pc)
    if len(files) != 2 or weld is None:
        raise ValueError(
            f"{scenario.directives_path}: needs models '{ARM_MODEL}' and '{GRIPPER_MODEL}' "
            "and a weld from the arm to the gripper"
        )
    return files, weld


def _link(scoped_name: str) -> str:
    return scoped_name.split("::")[-1]


def _fixed_joint(name: str, parent: str, child: str, x_pc: RigidTransform) -> ElementTree.Element:
    joint = ElementTree.Element("joint", {"name": name, "type": "fixed"})
    ElementTree.SubElement(joint, "parent", {"link": parent})
    ElementTree.SubElement(joint, "child", {"link": child})
    xyz = " ".join(f"{v:.17g}" for v in x_pc.translation())
    rpy = " ".join(f"{v:.17g}" for v in RollPitchYaw(x_pc.rotation()).vector())
    ElementTree.SubElement(joint, "origin", {"xyz": xyz, "rpy": rpy})
    return joint

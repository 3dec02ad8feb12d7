"""The tf tree from the plant, without ROS: each link in its parent link, chains that
compose to Drake's forward kinematics, camera optical frames as the cameras render."""

from __future__ import annotations

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.plant import MultibodyPlant

from dombot_description.cell import add_cell
from dombot_description.scenario import load_scenario
from dombot_sim.frames import WORLD, FrameTransform, LinkTree, camera_transforms

SCENARIO = load_scenario()


@pytest.fixture(scope="module")
def cell():
    plant = MultibodyPlant(time_step=0.0)
    models = add_cell(plant, SCENARIO)
    plant.Finalize()
    return plant, models, LinkTree(plant, (models.arm, models.gripper, models.table))


def chain(frames: list[FrameTransform], parent: str, child: str) -> RigidTransform:
    """X_parent_child composed by walking up from ``child``, as a tf listener does."""
    by_child = {frame.child: frame for frame in frames}
    assert len(by_child) == len(frames), "a frame with two parents"
    x = RigidTransform()
    while child != parent:
        frame = by_child[child]
        x = frame.X_PC @ x
        child = frame.parent
    return x


def test_every_link_has_one_parent_and_welds_are_static(cell) -> None:
    plant, models, tree = cell
    context = plant.CreateDefaultContext()
    fixed, moving = tree.fixed(context), tree.moving(context)
    links = {
        plant.get_body(b).name()
        for m in (models.arm, models.gripper, models.table)
        for b in plant.GetBodyIndices(m)
    }
    assert {f.child for f in fixed + moving} == links
    assert {(f.parent, f.child) for f in fixed} == {
        (WORLD, "iiwa_link_0"),
        (WORLD, "table_top"),
        ("iiwa_link_7", "iiwa_link_ee"),
        ("iiwa_link_ee", "wsg_body"),
        ("wsg_body", "wsg_tcp"),
    }
    assert {f.child for f in moving} == {f"iiwa_link_{i}" for i in range(1, 8)} | {
        "wsg_left_finger",
        "wsg_right_finger",
    }


def test_the_chain_world_to_tcp_is_drakes_forward_kinematics(cell) -> None:
    plant, models, tree = cell
    context = plant.CreateDefaultContext()
    rng = np.random.default_rng(3)
    for _ in range(5):
        plant.SetPositions(context, models.arm, rng.uniform(-1.5, 1.5, 7))
        plant.SetPositions(context, models.gripper, rng.uniform(0.0, 0.055, 2))
        frames = tree.fixed(context) + tree.moving(context)
        x_wt = chain(frames, WORLD, SCENARIO.tcp_frame)
        expected = plant.GetFrameByName(SCENARIO.tcp_frame).CalcPoseInWorld(context)
        assert np.allclose(x_wt.GetAsMatrix4(), expected.GetAsMatrix4(), atol=1e-9)
        left = chain(frames, "wsg_body", "wsg_left_finger").translation()
        assert left == pytest.approx([0.0, plant.GetPositions(context, models.gripper)[0], 0.0])


def test_camera_optical_frames_look_along_z_with_y_down() -> None:
    names = [frame.child for frame in camera_transforms(SCENARIO.cameras)]
    assert names == [f"camera_{i}_optical" for i in range(4)]  # pile 0, 1; build area 2, 3
    for frame, spec in zip(camera_transforms(SCENARIO.cameras), SCENARIO.cameras, strict=True):
        assert (frame.parent, frame.child) == (WORLD, f"{spec.name}_optical")
        rotation = frame.X_PC.rotation().matrix()
        forward = (spec.look_at - spec.position) / np.linalg.norm(spec.look_at - spec.position)
        assert rotation[:, 2] == pytest.approx(forward)  # z forward
        assert rotation[2, 0] == pytest.approx(0.0, abs=1e-12)  # x right: horizontal
        assert rotation[:, 1] @ [0.0, 0.0, 1.0] < 0.0  # y down
        assert frame.X_PC.translation() == pytest.approx(spec.position)

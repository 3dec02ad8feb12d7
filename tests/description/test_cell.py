"""The cell's models and scenario: kinematics, limits, gripper, domino, cameras, shadow plant."""

from __future__ import annotations

import math
import os
import subprocess
import sys

import numpy as np
import pytest
from pydrake.math import RigidTransform
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph
from pydrake.systems.framework import DiagramBuilder

from dombot_description import DOMINO_MASS, DOMINO_SIZE
from dombot_description.cell import add_cell, add_dominoes, build_shadow_plant
from dombot_description.scenario import ScenarioError, load_scenario

SCENARIO = load_scenario()


@pytest.fixture(scope="module")
def cell():
    builder = DiagramBuilder()
    plant, _ = AddMultibodyPlantSceneGraph(builder, time_step=0.001)
    add_cell(plant, SCENARIO)
    dominoes = add_dominoes(plant, 2)
    plant.Finalize()
    return plant, dominoes


def test_arm_has_the_iiwa14_kinematic_chain_and_limits(cell) -> None:
    plant, _ = cell
    context = plant.CreateDefaultContext()
    flange = plant.GetFrameByName("iiwa_link_ee").CalcPoseInWorld(context).translation()
    # Straight up: 0.36 (base→J2) + 0.42 (J2→J4) + 0.40 (J4→J6) + 0.126 (J6→flange).
    assert flange == pytest.approx([0.0, 0.0, 1.306], abs=1e-6)
    arm = [plant.GetJointByName(name) for name in SCENARIO.arm_joints]
    upper = np.degrees([joint.position_upper_limits()[0] for joint in arm])
    assert upper == pytest.approx([170, 120, 170, 120, 170, 120, 175], abs=1e-3)
    velocity = np.degrees([joint.velocity_upper_limits()[0] for joint in arm])
    assert velocity == pytest.approx([85, 85, 100, 75, 130, 135, 135], abs=1e-3)
    efforts = [plant.get_joint_actuator(i).effort_limit() for i in plant.GetJointActuatorIndices()]
    assert efforts[:7] == pytest.approx([320, 320, 176, 176, 110, 40, 40])
    arm_mass = sum(
        plant.get_body(b).default_mass()
        for b in plant.GetBodyIndices(plant.GetModelInstanceByName("iiwa"))
    )
    assert 28.0 < arm_mass < 33.0  # the LBR iiwa 14 weighs ~30 kg


def test_gripper_stroke_and_tcp_between_the_pads(cell) -> None:
    plant, _ = cell
    context = plant.CreateDefaultContext()
    for name in SCENARIO.gripper_joints:
        joint = plant.GetJointByName(name)
        assert (joint.position_lower_limits()[0], joint.position_upper_limits()[0]) == (0.0, 0.055)
        joint.set_translation(context, 0.012)
    left = plant.GetBodyByName("wsg_left_finger").EvalPoseInWorld(context).translation()
    right = plant.GetBodyByName("wsg_right_finger").EvalPoseInWorld(context).translation()
    tcp = plant.GetFrameByName(SCENARIO.tcp_frame).CalcPoseInWorld(context).translation()
    assert np.linalg.norm(left - right) == pytest.approx(0.024, abs=1e-9)  # opening = q_l + q_r
    assert np.linalg.norm(tcp[:2] - (left[:2] + right[:2]) / 2) < 1e-9


def test_domino_size_mass_and_inertia(cell) -> None:
    plant, dominoes = cell
    body = plant.GetBodyByName("domino", dominoes[0])
    assert body.default_mass() == DOMINO_MASS
    inertia = body.default_spatial_inertia().CalcRotationalInertia().CopyToFullMatrix3()
    a, b, c = DOMINO_SIZE
    expected = DOMINO_MASS / 12 * np.array([b * b + c * c, a * a + c * c, a * a + b * b])
    assert np.diag(inertia) == pytest.approx(expected, rel=1e-3)
    assert [plant.GetModelInstanceName(d) for d in dominoes] == ["domino_0", "domino_1"]


def test_another_domino_set_keeps_the_density_and_gets_its_box() -> None:
    builder = DiagramBuilder()
    plant, scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.001)
    size = (0.044, 0.022, 0.007)
    body = plant.GetBodyByName("domino", add_dominoes(plant, 1, size)[0])
    plant.Finalize()
    assert body.default_mass() == pytest.approx(DOMINO_MASS * np.prod(size) / np.prod(DOMINO_SIZE))
    inspector = scene_graph.model_inspector()
    shapes = [inspector.GetShape(g) for g in plant.GetCollisionGeometriesForBody(body)]
    assert [(s.width(), s.depth(), s.height()) for s in shapes] == [size]


def test_each_camera_sees_what_it_looks_at_in_the_middle_of_the_image() -> None:
    for camera in SCENARIO.cameras:
        target = np.array([*camera.look_at, 1.0])
        in_camera = np.linalg.inv(camera.pose()) @ target
        pixel = camera.intrinsics @ (in_camera[:3] / in_camera[2])
        centre = [(camera.width - 1) / 2, (camera.height - 1) / 2]  # Drake's pixel-centre grid
        assert pixel[:2] == pytest.approx(centre, abs=1e-6)
        assert in_camera[2] > 0.3  # in front of the camera, inside the depth range
        assert camera.intrinsics[1, 1] == pytest.approx(240 / math.tan(math.radians(22.5)))
    pile = np.array([*SCENARIO.pile_center, 0.0])
    pile_cameras = [c.name for c in SCENARIO.cameras if np.allclose(c.look_at, pile)]
    assert pile_cameras == ["camera_0", "camera_1"]  # the paper's two, on the pile


def test_two_cameras_see_every_reachable_place_of_the_build_area() -> None:
    """camera_2 (the placement checks) and camera_3 (49° round from it, for the held
    domino the gripper hides from camera_2) see every place of the build area within the
    arm's reach, up to a held domino's height."""
    build = [c for c in SCENARIO.cameras if not np.allclose(c.look_at[:2], SCENARIO.pile_center)]
    assert [c.name for c in build] == ["camera_2", "camera_3"]
    xs, ys = np.meshgrid(np.linspace(*SCENARIO.build_x, 25), np.linspace(*SCENARIO.build_y, 25))
    reach = np.hypot(xs, ys).ravel()
    inner, outer = SCENARIO.build_reach
    places = np.column_stack([xs.ravel(), ys.ravel()])[(reach >= inner) & (reach <= outer)]
    for camera in build:
        for height in (0.0, 0.12):
            points = np.column_stack([places, np.full(len(places), height), np.ones(len(places))])
            in_camera = (np.linalg.inv(camera.pose()) @ points.T)[:3]
            u, v = (camera.intrinsics @ (in_camera / in_camera[2]))[:2]
            assert np.all(in_camera[2] > 0.3)
            assert np.all((u >= 0) & (u < camera.width) & (v >= 0) & (v < camera.height))


def test_shadow_plant_has_only_the_arm_and_the_obstacles() -> None:
    obstacle = RigidTransform([0.5, 0.1, 0.024])
    shadow = build_shadow_plant(SCENARIO, grasp_opening=0.024, obstacle_poses=[obstacle])
    plant = shadow.plant
    assert plant.num_positions() == 7
    context = plant.GetMyContextFromRoot(shadow.builder_diagram.CreateDefaultContext())
    plant.SetPositions(context, SCENARIO.home_position)
    left = plant.GetBodyByName("wsg_left_finger").EvalPoseInWorld(context).translation()
    right = plant.GetBodyByName("wsg_right_finger").EvalPoseInWorld(context).translation()
    assert np.linalg.norm(left - right) == pytest.approx(0.024, abs=1e-9)
    inspector = shadow.scene_graph.model_inspector()
    names = [inspector.GetName(g) for g in inspector.GetAllGeometryIds()]
    assert "standing_domino_0" in names
    assert not any("domino_0::" in name for name in names)


def test_home_pose_points_the_gripper_down_clear_of_the_table() -> None:
    shadow = build_shadow_plant(SCENARIO, grasp_opening=0.1)
    root = shadow.builder_diagram.CreateDefaultContext()
    plant = shadow.plant
    plant.SetPositions(plant.GetMyContextFromRoot(root), SCENARIO.home_position)
    tcp = plant.GetFrameByName(SCENARIO.tcp_frame).CalcPoseInWorld(plant.GetMyContextFromRoot(root))
    assert tcp.rotation().matrix()[:, 2] @ [0, 0, -1] > 0.99
    query = shadow.scene_graph.get_query_output_port().Eval(
        shadow.scene_graph.GetMyContextFromRoot(root)
    )
    assert all(
        pair.distance > 0.05 for pair in query.ComputeSignedDistancePairwiseClosestPoints(0.05)
    )


def test_shadow_plant_refuses_an_opening_beyond_the_stroke() -> None:
    with pytest.raises(ValueError, match="stroke"):
        build_shadow_plant(SCENARIO, grasp_opening=0.2)


# Builds shadow plants one after another in a fresh interpreter, as the planner does when
# requests bring new grasp widths, and prints the resident set growth per plant built and
# dropped after the first few (allocators reach their working size) in KiB.
CHURN = """
import gc
from pathlib import Path
from dombot_description.allocator import release_memory, tune_allocator
from dombot_description.cell import build_shadow_plant
from dombot_description.scenario import load_scenario

def rss_kib():
    status = Path("/proc/self/status").read_text()
    return int(next(l for l in status.splitlines() if l.startswith("VmRSS:")).split()[1])

def settle():
    gc.collect()
    release_memory()
    return rss_kib()

tune_allocator()
scenario = load_scenario()
for i in range(8):
    build_shadow_plant(scenario, 0.010 + 0.001 * i)
before = settle()
for i in range(24):
    build_shadow_plant(scenario, 0.020 + 0.001 * i)
print((settle() - before) / 24)
"""


def test_shadow_plants_built_and_dropped_give_their_memory_back() -> None:
    """pydrake's AddMultibodyPlantSceneGraph kept ~310 KiB of every diagram built with it
    (Drake issue 24529); build_shadow_plant wires the two itself and keeps ~40."""
    env = dict(os.environ, PYTHONMALLOC="malloc")  # as planner_node runs
    done = subprocess.run(
        [sys.executable, "-c", CHURN], env=env, capture_output=True, text=True, timeout=600
    )
    assert done.returncode == 0, done.stderr
    assert float(done.stdout) < 120.0  # KiB per plant


def test_bad_scenario_names_the_field(tmp_path) -> None:
    broken = tmp_path / "broken.yaml"
    broken.write_text(SCENARIO.path.read_text().replace("home_position", "home_pose"))
    with pytest.raises(ScenarioError, match="home_position"):
        load_scenario(broken)
    with pytest.raises(ScenarioError, match="cannot read"):
        load_scenario(tmp_path / "missing.yaml")

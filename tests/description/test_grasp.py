"""The grasp definition checked against the real gripper, table and domino models.

Distances come from Drake geometry queries on a plant holding the WSG model as a free
body (fingers welded at the opening under test), the table and domino boxes; nothing here
reuses the arithmetic of grasp.py.
"""

from __future__ import annotations

import itertools
import math

import numpy as np
import pytest
from pydrake.common.eigen_geometry import Quaternion
from pydrake.geometry import Box
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.plant import AddMultibodyPlantSceneGraph, CoulombFriction
from pydrake.systems.framework import DiagramBuilder

from dombot_bringup.layouts import line
from dombot_description import DOMINO_SIZE, PACKAGE_DIR
from dombot_description.cell import make_parser, weld_fingers
from dombot_description.grasp import (
    FINGER_SWAP,
    PREGRASP_CLEARANCE,
    SYMMETRIES,
    WSG_URDF,
    BoxArray,
    Grasp,
    OrientedBox,
    canonical_grasp,
    domino_in_tcp,
    flat_pose,
    gripper_geometry,
    nearest_distance,
    pick_grasps,
    place_grasps,
    upright_pose,
)
from dombot_description.scenario import load_scenario

SCENARIO = load_scenario()
SPACING = 0.6 * DOMINO_SIZE[0]  # the bring-up's default centre spacing
HALF = np.array(DOMINO_SIZE) / 2


class FreeGripper:
    """The WSG on its own in world, fingers welded, with the table and anchored dominoes."""

    def __init__(self, opening: float, dominoes: dict[str, RigidTransform]) -> None:
        builder = DiagramBuilder()
        self.plant, self.scene_graph = AddMultibodyPlantSceneGraph(builder, time_step=0.0)
        parser = make_parser(self.plant)
        parser.AddModels(str(WSG_URDF))
        parser.AddModels(str(PACKAGE_DIR / "models" / "table.sdf"))
        self.plant.WeldFrames(self.plant.world_frame(), self.plant.GetFrameByName("table_top"))
        weld_fingers(self.plant, SCENARIO, opening)
        for name, pose in dominoes.items():
            self.plant.RegisterCollisionGeometry(
                self.plant.world_body(), pose, Box(*DOMINO_SIZE), name, CoulombFriction(0.5, 0.4)
            )
        self.plant.Finalize()
        self.diagram = builder.Build()
        self.context = self.diagram.CreateDefaultContext()

    def distances(self, tcp_pose: RigidTransform) -> dict[tuple[str, str], float]:
        """Signed distance per (gripper body, obstacle) with the TCP at tcp_pose."""
        plant_context = self.plant.GetMyMutableContextFromRoot(self.context)
        tcp = self.plant.GetFrameByName(SCENARIO.tcp_frame)
        body = self.plant.GetBodyByName("wsg_body")
        body_in_tcp = self.plant.CalcRelativeTransform(plant_context, tcp, body.body_frame())
        self.plant.SetFreeBodyPose(plant_context, body, tcp_pose @ body_in_tcp)
        query = self.scene_graph.get_query_output_port().Eval(
            self.scene_graph.GetMyContextFromRoot(self.context)
        )
        inspector = query.inspector()
        result: dict[tuple[str, str], float] = {}
        for pair in query.ComputeSignedDistancePairwiseClosestPoints(1.0):
            names = []
            for geometry in (pair.id_A, pair.id_B):
                frame = inspector.GetName(inspector.GetFrameId(geometry)).split("::")[-1]
                names.append(inspector.GetName(geometry) if frame == "world" else frame)
            robot = next(n for n in names if n.startswith("wsg"))
            other = next(n for n in names if not n.startswith("wsg"))
            other = "table" if "table" in other else other
            result[robot, other] = min(result.get((robot, other), math.inf), pair.distance)
        return result


def pads(distances: dict[tuple[str, str], float], other: str) -> float:
    return min(distances[f"wsg_{side}_finger", other] for side in ("left", "right"))


def box_corners(domino_pose: RigidTransform) -> np.ndarray:
    signs = np.array(list(itertools.product((-1, 1), repeat=3)))
    return np.array(sorted(map(tuple, np.round((domino_pose @ (signs * HALF).T).T, 9))))


def test_gripper_geometry_is_read_from_the_urdf() -> None:
    geometry = gripper_geometry()
    assert geometry.pad_size == pytest.approx([0.016, 0.008, 0.060])
    assert geometry.tcp_offset == pytest.approx([0.0, 0.0, 0.1085])
    assert geometry.max_opening == pytest.approx(0.11)
    # TCP 9 mm in from the pad tips, as the architecture states.
    tip = geometry.pad_center[2] + geometry.pad_size[2] / 2
    assert tip - geometry.tcp_offset[2] == pytest.approx(0.009)


def test_pad_boxes_are_where_the_plant_puts_the_pads() -> None:
    grasp = pick_grasps(flat_pose(0.55, -0.3, 0.4))[0]
    for opening in (grasp.closed_opening, grasp.pregrasp_opening):
        gripper = FreeGripper(opening, {})
        gripper.distances(grasp.pose)
        context = gripper.plant.GetMyContextFromRoot(gripper.context)
        for box, side in zip(grasp.pad_boxes(opening), ("left", "right"), strict=True):
            finger = gripper.plant.GetBodyByName(f"wsg_{side}_finger").EvalPoseInWorld(context)
            mirror = np.array([1.0, 1.0 if side == "left" else -1.0, 1.0])
            centre = finger @ (gripper_geometry().pad_center * mirror)
            assert box.pose.translation() == pytest.approx(centre, abs=1e-9)


def test_flat_domino_is_picked_with_the_pads_clear_of_the_table() -> None:
    domino_pose = flat_pose(0.5, -0.3, 1.1)
    grasp = pick_grasps(domino_pose)[0]
    closed = FreeGripper(grasp.closed_opening, {"domino": domino_pose}).distances(grasp.pose)
    assert pads(closed, "table") >= 0.0015
    assert closed["wsg_body", "table"] >= 0.010
    assert pads(closed, "domino") == pytest.approx(0.0, abs=1e-9)  # pads on its side faces
    open_ = FreeGripper(grasp.pregrasp_opening, {"domino": domino_pose}).distances(grasp.pose)
    assert pads(open_, "domino") == pytest.approx(PREGRASP_CLEARANCE, abs=1e-9)
    assert pads(open_, "table") == pytest.approx(pads(closed, "table"))


def test_pads_press_a_patch_of_the_side_faces() -> None:
    """Sample the pad's inner face; at least 35 mm² of it lies on the domino's side face."""
    held_in_tcp = canonical_grasp().inverse()
    pad = gripper_geometry().pad_boxes_in_tcp(DOMINO_SIZE[1])[0]
    u, v = np.meshgrid(np.linspace(-0.5, 0.5, 81), np.linspace(-0.5, 0.5, 241))
    face = np.column_stack(
        [u.ravel() * pad.size[0], -pad.size[1] / 2 + 0 * u.ravel(), v.ravel() * pad.size[2]]
    )
    in_domino = (held_in_tcp.inverse() @ (pad.pose @ face.T)).T
    on_face = np.all(np.abs(in_domino[:, [0, 2]]) <= HALF[[0, 2]], axis=1)
    assert np.abs(np.abs(in_domino[:, 1]) - HALF[1]) == pytest.approx(0.0, abs=1e-12)
    area_mm2 = on_face.mean() * pad.size[0] * pad.size[2] * 1e6
    assert area_mm2 >= 35.0


@pytest.mark.parametrize("neighbours", [(-1,), (-1, 1)], ids=["behind", "both_sides"])
def test_upright_placement_keeps_clear_of_standing_neighbours(neighbours) -> None:
    heading = 0.7
    place_pose = upright_pose(0.6, 0.1, heading)
    forward = np.array([math.cos(heading), math.sin(heading), 0.0])
    standing = {
        f"neighbour_{side}": upright_pose(
            *(place_pose.translation()[:2] + side * SPACING * forward[:2]), heading
        )
        for side in neighbours
    }
    held_in_tcp = domino_in_tcp(
        pick_grasps(flat_pose(0.5, -0.3, 0.0))[0].pose, flat_pose(0.5, -0.3, 0.0)
    )
    tcp_pose = place_grasps(place_pose, held_in_tcp)[0]
    distances = FreeGripper(DOMINO_SIZE[1], {"held": place_pose, **standing}).distances(tcp_pose)
    assert tcp_pose.rotation().matrix()[2, 2] < -math.cos(math.radians(28))  # 27° from vertical
    assert pads(distances, "held") == pytest.approx(0.0, abs=1e-9)
    assert pads(distances, "table") >= 0.010
    assert distances["wsg_body", "table"] >= 0.030
    for name in standing:
        assert pads(distances, name) >= 0.0035
        assert distances["wsg_body", name] >= 0.030
    # The gripper leans over the run's free side: its body is ahead of the held domino.
    body_ahead = (tcp_pose.translation() - place_pose.translation()) @ forward
    assert body_ahead > 0.0


def test_symmetries_map_the_domino_box_onto_itself() -> None:
    domino_pose = flat_pose(0.1, 0.2, 0.3)
    reference = box_corners(domino_pose)
    for symmetry in SYMMETRIES:
        assert box_corners(domino_pose @ RigidTransform(symmetry)) == pytest.approx(reference)
    for a, b in itertools.product(SYMMETRIES, repeat=2):
        product = (a @ b).matrix()
        assert any(np.allclose(product, s.matrix(), atol=1e-12) for s in SYMMETRIES)


def test_all_pick_grasps_hold_the_same_physical_domino() -> None:
    domino_pose = flat_pose(0.52, -0.27, 2.2)
    tcp_in_domino = canonical_grasp()
    grasps = pick_grasps(domino_pose)
    assert len(grasps) == 8
    for grasp in grasps:
        for swap in (RigidTransform(), FINGER_SWAP):
            held = grasp.pose @ swap.inverse() @ tcp_in_domino.inverse()
            if box_corners(held) == pytest.approx(box_corners(domino_pose)):
                break
        else:
            pytest.fail(f"grasp {grasp.pose} does not hold the domino at {domino_pose}")
    assert len({tuple(np.round(g.pose.GetAsMatrix4().ravel(), 9)) for g in grasps}) == 8


def test_pick_grasps_rank_from_above_and_leaning_outward_first() -> None:
    domino_pose = flat_pose(0.55, -0.30, 0.9)
    grasps = pick_grasps(domino_pose)
    approach = [g.approach for g in grasps]
    assert all(a[2] < 0 for a in approach[:4]) and all(a[2] > 0 for a in approach[4:])
    outward = domino_pose.translation()[:2] / np.linalg.norm(domino_pose.translation()[:2])
    assert approach[0][:2] @ outward > 0
    assert approach[0][2] == pytest.approx(-math.cos(math.radians(63)))


def test_flipped_flat_domino_is_still_grasped_from_above() -> None:
    domino_pose = flat_pose(0.55, -0.30, 0.0) @ RigidTransform(
        RotationMatrix.MakeXRotation(math.pi)
    )
    assert pick_grasps(domino_pose)[0].approach[2] == pytest.approx(-math.cos(math.radians(63)))


def test_oriented_box_signed_distance() -> None:
    pad = pick_grasps(flat_pose(0.5, -0.3, 0.0))[0].pad_boxes()[0]
    centre = pad.pose.translation()
    axis_x = pad.pose.rotation().matrix()[:, 0]
    points = np.array([centre, centre + axis_x * (pad.size[0] / 2 + 0.01)])
    assert pad.signed_distance(points) == pytest.approx([-pad.size[1] / 2, 0.01])


def test_pad_paths_cover_the_approach_and_the_closing_stroke() -> None:
    grasp = pick_grasps(flat_pose(0.5, -0.3, 0.4))[0]
    paths = grasp.pad_paths(0.05)
    for open_pad, closed_pad in zip(
        grasp.pad_boxes(grasp.pregrasp_opening), grasp.pad_boxes(), strict=True
    ):
        stroke = closed_pad.pose.translation() - open_pad.pose.translation()
        inward = stroke / np.linalg.norm(stroke)
        above = open_pad.pose.translation() - grasp.approach * 0.03
        # in the gap between the open pad's inner face and the domino's long face
        gap = open_pad.pose.translation() + inward * (open_pad.size[1] / 2 + PREGRASP_CLEARANCE / 2)
        assert open_pad.signed_distance(gap[None])[0] == pytest.approx(PREGRASP_CLEARANCE / 2)
        for point in (above, gap, closed_pad.pose.translation()):
            assert min(path.signed_distance(point[None])[0] for path in paths) < 0.0
    beside = grasp.pose.translation() + grasp.pose.rotation().matrix()[:, 1] * 0.05
    assert min(path.signed_distance(beside[None])[0] for path in paths) > 0.0


def test_pad_paths_follow_the_approach_line_given() -> None:
    grasp = pick_grasps(flat_pose(0.5, -0.3, 0.4))[0]  # approach tilted 63° from vertical
    up = np.array([0.0, 0.0, 1.0])
    vertical, along_tcp = grasp.pad_paths(0.05, up), grasp.pad_paths(0.05)
    pad = grasp.pad_boxes(grasp.pregrasp_opening)[0].pose.translation()

    def inside(paths: list, point: np.ndarray) -> bool:
        return min(path.signed_distance(point[None])[0] for path in paths) < 0.0

    above, up_the_tcp_axis = pad + 0.04 * up, pad - 0.04 * grasp.approach
    assert inside(vertical, above) and not inside(vertical, up_the_tcp_axis)
    assert inside(along_tcp, up_the_tcp_axis) and not inside(along_tcp, above)


def test_oblique_sweep_overhangs_the_swept_volume_by_less_than_a_step() -> None:
    pad = pick_grasps(flat_pose(0.5, -0.3, 0.4))[0].pad_boxes()[0]
    move = np.array([0.0, 0.0, 0.03])
    pieces = pad.sweep(move, step=0.002)
    assert len(pieces) == 15
    # the exact swept volume's distance: nearest over finely spaced copies of the pad
    rng = np.random.default_rng(0)
    points = pad.pose.translation() + move / 2 + rng.uniform(-0.03, 0.03, (2000, 3))
    copies = [
        OrientedBox(
            RigidTransform(pad.pose.rotation(), pad.pose.translation() + t * move), pad.size
        )
        for t in np.linspace(0.0, 1.0, 301)
    ]
    exact = np.min([c.signed_distance(points) for c in copies], axis=0)
    covered = np.min([p.signed_distance(points) for p in pieces], axis=0)
    assert np.all(covered <= exact + 1e-6)  # covers it
    assert np.all(exact - covered < 0.002)  # by less than a step
    straight = pad.sweep(pad.pose.rotation().matrix()[:, 0] * 0.03)
    assert len(straight) == 1  # along an axis the one box is exact


def test_finger_swapped_twins_sweep_the_same_space() -> None:
    """Perception scores one of each twin (same TCP position and approach): its pads'
    paths must be the other's, box for box."""
    grasps = pick_grasps(flat_pose(0.5, -0.3, 0.4))
    for grasp in grasps:
        twin = Grasp(grasp.pose @ FINGER_SWAP, grasp.closed_opening, grasp.pregrasp_opening)
        ours, theirs = (g.pad_path_array(0.05, np.array([0.0, 0.0, 1.0])) for g in (grasp, twin))
        half = len(ours) // 2  # the pads trade places
        assert np.allclose(ours.centres, np.roll(theirs.centres, half, axis=0), atol=1e-12)
        assert np.allclose(ours.sizes, np.roll(theirs.sizes, half, axis=0), atol=1e-12)
        assert np.allclose(np.abs(ours.rotations), np.abs(theirs.rotations), atol=1e-12)


def test_nearest_distance_is_the_smallest_signed_distance_to_any_box() -> None:
    """To the last bit: the bounds only choose which distances to measure."""
    grasp = pick_grasps(flat_pose(0.5, -0.3, 0.4))[0]
    turned = pick_grasps(flat_pose(0.51, -0.29, 1.3))[2]  # boxes of a second rotation
    paths = grasp.pad_paths(0.05, np.array([0.0, 0.0, 1.0])) + turned.pad_paths(0.03)
    rng = np.random.default_rng(1)
    for spread in (0.002, 0.01, 0.05):  # inside the pads' path, near it, around it
        points = grasp.pose.translation() + rng.normal(0.0, spread, (500, 3))
        brute = min(float(path.signed_distance(points).min()) for path in paths)
        assert nearest_distance(paths, points) == brute
        assert nearest_distance(BoxArray.of(paths), points, cap=0.004) == min(brute, 0.004)
    assert nearest_distance(paths, np.zeros((0, 3))) == math.inf
    assert nearest_distance(paths, np.ones((4, 3)), cap=0.01) == 0.01  # all far away


def test_upright_pose_is_the_bringup_layout_convention() -> None:
    placement = line((0.5, 0.1), 0.8, count=2)[1]
    w, x, y, z = placement.quaternion_wxyz()
    expected = RotationMatrix(Quaternion(w, x, y, z)).matrix()
    pose = upright_pose(placement.x, placement.y, placement.heading)
    assert pose.rotation().matrix() == pytest.approx(expected, abs=1e-12)
    assert pose.translation() == pytest.approx([placement.x, placement.y, placement.z])

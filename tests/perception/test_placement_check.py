"""Placement checks on a rendered run seen by the build-area cameras."""

from __future__ import annotations

from dataclasses import replace

import numpy as np
import pytest
from pydrake.common.eigen_geometry import AngleAxis
from pydrake.math import RigidTransform, RotationMatrix
from pydrake.multibody.inverse_kinematics import InverseKinematics
from pydrake.solvers import Solve

from dombot_description.cell import build_shadow_plant
from dombot_description.grasp import canonical_grasp, flat_pose, place_grasps, upright_pose
from dombot_description.scenario import load_scenario
from dombot_perception.pipeline import build_pipeline
from dombot_perception.placement_check import (
    FALLEN,
    MISSING,
    NOT_SEEN,
    STANDING,
    PlacementConfig,
    check_placements,
)

HEADING = 0.4
SPACING = 0.0288  # m between dominoes of the run
HALF_LENGTH, HALF_THICKNESS = 0.024, 0.00375


@pytest.fixture(scope="module")
def run_poses() -> list[np.ndarray]:
    step = SPACING * np.array([np.cos(HEADING), np.sin(HEADING)])
    start = np.array([0.50, 0.12])
    return [upright_pose(*(start + i * step), HEADING).GetAsMatrix4() for i in range(5)]


@pytest.fixture(scope="module")
def pipeline():
    return build_pipeline(load_scenario())


def test_standing_fallen_and_missing_dominoes_are_told_apart(
    run_poses, pipeline, render_build_area
) -> None:
    fallen = flat_pose(*(run_poses[3][:2, 3] + 0.01), HEADING + 0.5).GetAsMatrix4()
    views = render_build_area({0: run_poses[0], 1: run_poses[1], 2: run_poses[2], 3: fallen})
    results = check_placements(run_poses, views, pipeline, PlacementConfig())
    assert [r.status for r in results] == [STANDING, STANDING, STANDING, FALLEN, MISSING]
    for result in results[:3]:
        assert result.position_error < 0.003  # incl. the simulator's half-pixel K offset
        assert result.tilt < np.radians(1.0)
    assert np.linalg.norm(results[3].measured[:3, 3] - fallen[:3, 3]) < 0.003
    assert results[3].tilt > np.radians(80)


def test_a_leaning_domino_is_not_standing(run_poses, pipeline, render_build_area) -> None:
    leaning = run_poses[0].copy()
    turn = np.array([[np.cos(0.5), 0, np.sin(0.5)], [0, 1, 0], [-np.sin(0.5), 0, np.cos(0.5)]])
    leaning[:3, :3] = leaning[:3, :3] @ turn  # 29 degrees about its width axis
    leaning[2, 3] = 0.024 * np.cos(0.5) + 0.00375 * np.sin(0.5)
    views = render_build_area({0: leaning})
    [result] = check_placements(run_poses[:1], views, pipeline, PlacementConfig())
    assert result.status != STANDING


def test_a_place_outside_every_image_is_not_seen(run_poses, pipeline, render_build_area) -> None:
    views = render_build_area({0: run_poses[0]})
    far = run_poses[0].copy()
    far[:2, 3] = [3.0, 3.0]
    results = check_placements([run_poses[0], far], views, pipeline, PlacementConfig())
    assert [r.status for r in results] == [STANDING, NOT_SEEN]


def test_a_domino_that_tipped_forward_belongs_to_the_place_it_fell_from(
    run_poses, pipeline, render_build_area
) -> None:
    forward = run_poses[1][:2, 0:3][:, 2]  # the run's direction (body z, horizontal)
    # tipped over its front edge: lying flat, its centre almost on the next place
    centre = run_poses[1][:2, 3] + (HALF_LENGTH + HALF_THICKNESS) * forward
    fallen = flat_pose(*centre, HEADING).GetAsMatrix4()
    views = render_build_area({0: run_poses[0], 1: fallen})
    results = check_placements(run_poses[:3], views, pipeline, PlacementConfig())
    assert [r.status for r in results] == [STANDING, FALLEN, MISSING]
    assert np.linalg.norm(results[1].measured[:3, 3] - fallen[:3, 3]) < 0.003


@pytest.mark.parametrize("turn", [60.0, 90.0, 120.0])
def test_a_lying_domino_turned_since_it_was_seen_is_refitted(
    run_poses, pipeline, render_build_area, turn
) -> None:
    """Looked at again where it was seen lying (flat across the run), a domino a pick or
    push nearby turned about the vertical by ``turn`` degrees is found where it lies now:
    fitted from that pose alone, none of these was (down but not fitted: arc cycles seed
    2 had 34 such answers in its third cycle, each an obstacle never picked)."""
    centre = run_poses[2][:2, 3]
    seen = flat_pose(*centre, HEADING).GetAsMatrix4()
    lies = flat_pose(*(centre + 0.003), HEADING + np.radians(turn)).GetAsMatrix4()
    views = render_build_area({0: lies})
    alone = replace(PlacementConfig(), lying_turns=())
    [before] = check_placements([seen], views, pipeline, alone)
    assert before.status == FALLEN and before.measured is seen  # no pose
    [result] = check_placements([seen], views, pipeline, PlacementConfig())
    assert result.status == FALLEN and result.tilt > np.radians(80)
    assert np.linalg.norm(result.measured[:3, 3] - lies[:3, 3]) < 0.003


def side_by_side(centre: np.ndarray, yaw: float, gap: float = 0.0002) -> list[np.ndarray]:
    """Two flat dominoes turned ``yaw``, long side to long side ``gap`` apart about
    ``centre``."""
    across = np.array([-np.sin(yaw), np.cos(yaw)]) * (0.012 + gap / 2)
    return [flat_pose(*(centre + sign * across), yaw).GetAsMatrix4() for sign in (1.0, -1.0)]


def test_a_box_across_two_dominoes_side_by_side_is_not_taken_for_one(
    run_poses, pipeline, render_build_area
) -> None:
    """Two flat dominoes side by side show one 48 mm square face: looked at again where
    a box was fitted across a half of each (arc cycles seed 1: 12-14 mm and 72-88° off
    each, three picks closed on nothing), perception answers one of the two, or (no seam
    seen between them: which way they lie is unknown) down but not fitted, never the box
    across them."""
    centre = run_poses[2][:2, 3]
    pair = side_by_side(centre, HEADING)
    across = flat_pose(*centre, HEADING + np.pi / 2).GetAsMatrix4()
    views = render_build_area(dict(enumerate(pair)))
    [result] = check_placements([across], views, pipeline, PlacementConfig())
    assert result.status == FALLEN
    if result.measured is not across:
        axis = result.measured[:3, 0]
        turns = [np.degrees(np.arccos(min(1.0, abs(axis @ p[:3, 0])))) for p in pair]
        off = [np.linalg.norm(result.measured[:2, 3] - p[:2, 3]) for p in pair]
        assert min(off) < 0.003 and min(turns) < 5.0


def test_a_flat_domino_with_another_end_to_end_is_fitted(
    run_poses, pipeline, render_build_area
) -> None:
    """The face going on past a domino's end is not a pair side by side: fitted as ever
    (along the other it may slide: nothing pins that end)."""
    centre = run_poses[2][:2, 3]
    along = 0.0482 * np.array([np.cos(HEADING), np.sin(HEADING)])
    lies = flat_pose(*centre, HEADING).GetAsMatrix4()
    views = render_build_area({0: lies, 1: flat_pose(*(centre + along), HEADING).GetAsMatrix4()})
    [result] = check_placements([lies], views, pipeline, PlacementConfig())
    assert result.status == FALLEN and result.measured is not lies
    assert abs((result.measured[:3, 3] - lies[:3, 3]) @ lies[:3, 1]) < 0.002
    assert abs(result.measured[:3, 0] @ lies[:3, 0]) > np.cos(np.radians(5.0))


def facing(point: np.ndarray, towards: np.ndarray) -> np.ndarray:
    """A domino at ``point`` with its largest face turned to ``towards``, length upwards."""
    z = (towards - point) / np.linalg.norm(towards - point)
    x = np.array([0.0, 0.0, 1.0]) - z[2] * z
    x /= np.linalg.norm(x)
    pose = np.eye(4)
    pose[:3, :3] = np.column_stack([x, np.cross(z, x), z])
    pose[:3, 3] = point
    return pose


def occluder(place: np.ndarray, camera: str, views) -> np.ndarray:
    """A domino floating a third of the way from ``place`` to ``camera``, facing it."""
    eye = next(v for v in views if v.name == camera).X_WC[:3, 3]
    return facing(place + (eye - place) / 3.0, eye)


def test_a_place_hidden_behind_something_is_not_seen_rather_than_missing(
    run_poses, pipeline, render_camera_2
) -> None:
    """The arm above a domino just placed can hide its neighbours from the camera: no
    evidence that they fell (a run was rebuilt into a domino that still stood)."""
    hiding = occluder(run_poses[1][:3, 3], "camera_2", render_camera_2({}))
    empty = check_placements(
        run_poses[:2], render_camera_2({0: run_poses[0]}), pipeline, PlacementConfig()
    )
    hidden = check_placements(
        run_poses[:2], render_camera_2({0: run_poses[0], 1: hiding}), pipeline, PlacementConfig()
    )
    assert [r.status for r in empty] == [STANDING, MISSING]
    assert [r.status for r in hidden] == [STANDING, NOT_SEEN]


def test_a_domino_hidden_from_camera_2_is_read_standing_by_camera_3(
    run_poses, pipeline, render_build_area
) -> None:
    """camera_3, 49° round from camera_2, sees past what hides a place from camera_2; its
    own fit is taken, not one of both cameras' points together (their offsets twist the
    box)."""
    hiding = occluder(run_poses[1][:3, 3], "camera_2", render_build_area({}))
    views = render_build_area({0: run_poses[0], 1: run_poses[1], 2: hiding})
    camera_2 = [v for v in views if v.name == "camera_2"]
    alone = check_placements(run_poses[:2], camera_2, pipeline, PlacementConfig())
    results = check_placements(run_poses[:2], views, pipeline, PlacementConfig())
    assert [r.status for r in alone] == [STANDING, NOT_SEEN]
    assert [r.status for r in results] == [STANDING, STANDING]
    for result, truth in zip(results, run_poses, strict=False):
        foot, tilt = foot_and_tilt_errors(result.measured, truth)
        assert foot < FOOT_TOLERANCE and tilt < np.radians(0.5), (foot, np.degrees(tilt))


def test_a_place_hidden_from_both_placement_cameras_is_not_seen(
    run_poses, pipeline, render_build_area
) -> None:
    place = run_poses[1][:3, 3]
    nothing = render_build_area({})
    hiding = [occluder(place, camera, nothing) for camera in ("camera_2", "camera_3")]
    views = render_build_area({0: run_poses[0], 1: hiding[0], 2: hiding[1]})
    results = check_placements(run_poses[:2], views, pipeline, PlacementConfig())
    assert [r.status for r in results] == [STANDING, NOT_SEEN]


def towards_camera_3(views) -> tuple[np.ndarray, np.ndarray]:
    """A place and its neighbour in front as camera_3 sees a run heading towards it (as at
    circle30's place 12): both facing camera_3, the run's spacing apart."""
    place = np.array([0.45, 0.29])
    eye = next(v for v in views if v.name == "camera_3").X_WC[:2, 3]
    heading = np.arctan2(*(eye - place)[::-1])
    front = place + SPACING * np.array([np.cos(heading), np.sin(heading)])
    return upright_pose(*place, heading).GetAsMatrix4(), upright_pose(
        *front, heading
    ).GetAsMatrix4()


def test_a_domino_half_hidden_by_its_neighbour_from_camera_3_is_read_standing(
    pipeline, render_build_area
) -> None:
    """camera_3 looks along a run heading towards it from 45° above: the neighbour in
    front hides the lower ~26 mm of the place, more than half of it; the top it sees is
    fitted (``min_height_hidden``: the rest is hidden), not taken for a domino that fell
    (camera_3 alone called circle30's place 12 fallen in every release scene so)."""
    place, front = towards_camera_3(render_build_area({}))
    views = render_build_area({0: front, 1: place})
    camera_3 = [v for v in views if v.name == "camera_3"]
    results = check_placements([front, place], camera_3, pipeline, PlacementConfig())
    assert [r.status for r in results] == [STANDING, STANDING]
    foot, tilt = foot_and_tilt_errors(results[1].measured, place)
    assert foot < FOOT_TOLERANCE and tilt < np.radians(0.5), (foot, np.degrees(tilt))
    # the rule off (half the height needed, hidden or not): called fallen, as before
    half = replace(PlacementConfig(), min_height_hidden=0.5 * 2 * HALF_LENGTH)
    assert check_placements([front, place], camera_3, pipeline, half)[1].status == FALLEN


@pytest.mark.parametrize("lying", ["gone", "flat behind", "leaning back"])
def test_a_place_half_hidden_from_camera_3_is_not_read_standing_without_its_domino(
    pipeline, render_build_area, lying
) -> None:
    """The top a neighbour leaves in camera_3's view is read standing only where a
    domino stands: gone, lying flat behind its place, or leaning 30° back (away from
    camera_3, whose top still rises above the neighbour), it is not."""
    place, front = towards_camera_3(render_build_area({}))
    back = -place[:3, 2]  # away from camera_3, along the run
    poses = {0: front}
    if lying == "flat behind":
        centre = place[:2, 3] + (HALF_LENGTH + HALF_THICKNESS) * back[:2]
        poses[1] = flat_pose(*centre, np.arctan2(back[1], back[0])).GetAsMatrix4()
    elif lying == "leaning back":
        poses[1] = leaning(place, np.radians(30.0), back)
    camera_3 = [v for v in render_build_area(poses) if v.name == "camera_3"]
    results = check_placements([front, place], camera_3, pipeline, PlacementConfig())
    assert results[0].status == STANDING
    assert results[1].status != STANDING


def leaning(upright: np.ndarray, angle: float, towards: np.ndarray) -> np.ndarray:
    """``upright`` turned by ``angle`` about its bottom edge on the ``towards`` side."""
    axis = np.cross([0.0, 0.0, 1.0], towards)
    turn = RotationMatrix(AngleAxis(angle, axis / np.linalg.norm(axis))).matrix()
    pivot = upright[:3, 3] + HALF_THICKNESS * towards
    pivot[2] = 0.0
    pose = upright.copy()
    pose[:3, :3] = turn @ upright[:3, :3]
    pose[:3, 3] = pivot + turn @ (upright[:3, 3] - pivot)
    return pose


# ---------------------------------------------------------------- held by the gripper
# The domino stands in the gripper at its place just before the fingers open: the pads
# pinch its top, the gripper leans 27° over one side of the run. It may have turned about
# the pinch axis and slid in the hand during the carry.

CLOSED = 0.024  # m: the fingers closed on the domino's width


@pytest.fixture(scope="module")
def hold(world, render_camera_2, render_every_camera):
    """hold(target, turn, shift, lean, neighbours, every_camera) -> (views, truth): the
    views of camera_2 (``every_camera``: of all cameras) and the domino at
    ``target`` held at the canonical place grasp with the gripper leaning over the
    target's ``lean``·z side, turned by ``turn`` rad about the pinch axis and moved by
    ``shift`` (domino frame) in the hand, its lowest corner 0.2 mm above the table (and
    ``height`` more); the arm at an IK solution for it, the fingers closed (on nothing
    when not ``holding``: the domino is left out of the scene); ``neighbours`` standing
    too."""
    shadow = build_shadow_plant(world.scenario, CLOSED)
    plant = shadow.plant
    tcp_frame = plant.GetFrameByName(world.scenario.tcp_frame)
    home = np.asarray(world.scenario.home_position, dtype=float)

    def arm_at(tcp: RigidTransform) -> np.ndarray:
        ik = InverseKinematics(plant, plant.CreateDefaultContext())
        where = tcp.translation()
        ik.AddPositionConstraint(tcp_frame, np.zeros(3), plant.world_frame(), where, where)
        ik.AddOrientationConstraint(
            plant.world_frame(), tcp.rotation(), tcp_frame, RotationMatrix(), 0.0
        )
        ik.get_mutable_prog().AddQuadraticErrorCost(np.eye(7), home, ik.q())
        result = Solve(ik.prog(), home)
        assert result.is_success(), "no arm configuration holds the domino there"
        return result.GetSolution(ik.q())

    def held(
        target,
        turn=0.0,
        shift=(0.0, 0.0, 0.0),
        lean=1,
        neighbours=(),
        every_camera=False,
        height=0.0,
        holding=True,
    ):
        place = RigidTransform(target)
        tcp = place_grasps(place, canonical_grasp().inverse(), lean * target[:3, 2])[0]
        in_tcp = tcp.inverse() @ place
        pinch = in_tcp.inverse().translation() * [1.0, 1.0, 0.0]  # TCP on the mid plane
        turned = RigidTransform(pinch) @ RigidTransform(RotationMatrix.MakeYRotation(turn))
        domino = tcp @ in_tcp @ turned @ RigidTransform(-pinch) @ RigidTransform(shift)
        corners = CORNERS * [HALF_LENGTH, 0.012, HALF_THICKNESS] @ domino.rotation().matrix().T
        lowest = domino.translation()[2] + corners[:, 2].min()
        lift = RigidTransform([0.0, 0.0, 0.0002 + height - lowest])
        world.set_robot_positions(arm_at(lift @ tcp), CLOSED)
        truth = (lift @ domino).GetAsMatrix4()
        poses = {0: truth} if holding else {}
        poses |= {i + 1: pose for i, pose in enumerate(neighbours)}
        render = render_every_camera if every_camera else render_camera_2
        return render(poses), truth

    yield held
    world.set_robot_positions()  # home, open: the other tests see no arm


CORNERS = np.array([[sx, sy, sz] for sx in (-1, 1) for sy in (-1, 1) for sz in (-1, 1)])


def foot_and_tilt_errors(measured: np.ndarray, truth: np.ndarray) -> tuple[float, float]:
    """Horizontal distance of the feet (lower end centres) [m], angle between the length
    axes [rad]: what the caller corrects the place by."""

    def up_and_foot(pose):
        up = pose[:3, 0] * np.sign(pose[2, 0])
        return up, pose[:3, 3] - HALF_LENGTH * up

    (up_m, foot_m), (up_t, foot_t) = up_and_foot(measured), up_and_foot(truth)
    return float(np.hypot(*(foot_m - foot_t)[:2])), float(np.arccos(np.clip(up_m @ up_t, -1, 1)))


FOOT_TOLERANCE = 0.0015  # m, incl. the simulator's half-pixel K offset (~0.8 mm here)
TILT_TOLERANCE = np.radians(1.0)


@pytest.mark.parametrize("turn, shift", [(0.0, (0.0, 0.0, 0.0)), (6.0, (0.0, 0.0, 0.003))])
def test_a_domino_held_by_the_gripper_is_measured_below_the_pads(
    run_poses, pipeline, hold, turn, shift
) -> None:
    """The gripper leans away from camera_2, over the run's next place; the neighbours
    28.8 mm before and after stand (the pads clear them)."""
    views, truth = hold(run_poses[2], np.radians(turn), shift, -1, [run_poses[1], run_poses[3]])
    [held] = check_placements(run_poses[2:3], views, pipeline, PlacementConfig(in_hand=True))
    assert held.status == STANDING
    foot, tilt = foot_and_tilt_errors(held.measured, truth)
    assert foot < FOOT_TOLERANCE and tilt < TILT_TOLERANCE, (foot, np.degrees(tilt))
    assert abs(held.tilt - np.radians(turn)) < TILT_TOLERANCE
    # for comparison only: the normal fit takes in the pads (measured 0.6-0.7° off here)
    [normal] = check_placements(run_poses[2:3], views, pipeline, PlacementConfig())
    print("normal mode:", normal.status, foot_and_tilt_errors(normal.measured, truth))


@pytest.mark.parametrize("turn", [0.0, 6.0])
def test_a_domino_held_above_its_slot_is_measured_there(run_poses, pipeline, hold, turn) -> None:
    """Where the bring-up looks: 70 mm straight above the slot (the planner's
    place_approach_distance), over the standing neighbours, above the pile's 70 mm
    ceiling of the work region."""
    views, truth = hold(
        run_poses[2], np.radians(turn), (0.0, 0.0, 0.003), -1, [run_poses[1]], height=0.07
    )
    above = run_poses[2].copy()
    above[2, 3] += 0.07
    [held] = check_placements([above], views, pipeline, PlacementConfig(in_hand=True))
    assert held.status == STANDING
    foot, tilt = foot_and_tilt_errors(held.measured, truth)
    assert foot < FOOT_TOLERANCE and tilt < TILT_TOLERANCE, (foot, np.degrees(tilt))
    assert held.measured[2, 3] == pytest.approx(truth[2, 3], abs=0.002)


def test_a_domino_hidden_by_the_gripper_leaning_towards_the_camera_is_not_seen(
    run_poses, pipeline, hold
) -> None:
    """Leaning over +z here puts the wrist and gripper between camera_2 and the domino."""
    views, _ = hold(run_poses[2], np.radians(6.0), (0.0, 0.0, 0.003), 1, [run_poses[1]])
    [held] = check_placements(run_poses[2:3], views, pipeline, PlacementConfig(in_hand=True))
    assert held.status == NOT_SEEN


@pytest.mark.parametrize("every_camera", [False, True])
def test_held_dominoes_are_standing_where_they_are_or_not_seen(
    pipeline, hold, every_camera
) -> None:
    """Several run directions, lean directions and turns in the hand: a held domino is
    either measured within the tolerances or not called STANDING (e.g. a gripper leaning
    towards camera_2 hides it; an edge-on view pins the turn too weakly). With every
    camera (the node's in_hand_cameras), each camera's points are fitted alone: fused from
    two sides, their offsets twisted the box by up to 2°. camera_3 among them, all but one
    (camera_2 alone: 5 of 12; without camera_3: 10)."""
    statuses = []
    for heading in np.radians([45.0, -45.0, 135.0, -135.0, 90.0, 0.0]):
        step = SPACING * np.array([np.cos(heading), np.sin(heading)])
        centre = np.array([0.53, 0.14])
        run = [upright_pose(*(centre + i * step), heading).GetAsMatrix4() for i in (-1, 0, 1)]
        for lean, turn, shift in [(1, 5.0, (0.003, 0.0, 0.0)), (-1, -6.0, (-0.002, 0.0, 0.002))]:
            views, truth = hold(run[1], np.radians(turn), shift, lean, [run[0]], every_camera)
            [held] = check_placements(run[1:2], views, pipeline, PlacementConfig(in_hand=True))
            statuses.append(held.status)
            if held.status == STANDING:
                foot, tilt = foot_and_tilt_errors(held.measured, truth)
                assert foot < FOOT_TOLERANCE and tilt < TILT_TOLERANCE, (foot, np.degrees(tilt))
    print("in hand, every camera" if every_camera else "in hand, camera_2:", statuses)
    assert statuses.count(STANDING) >= (11 if every_camera else 2)
    assert set(statuses) <= {STANDING, NOT_SEEN}


# A real slot: domino 7 of the S-curve (--start 0.50 -0.07 --heading 90 --length 0.55
# --amplitude 0.05 --count 20) as PickPlacePlanner carries it from a flat pile domino: the
# arm at the end of its transfer segment, the domino at the plan's held_in_tcp. camera_2 sees
# the held domino almost edge-on there, which pins its turn in the hand by ~23 mm
# (_turn_support); the fit is within 0.1° all the same.
SLOT_7_ARM = np.array([1.154344, 1.354562, -1.076038, -1.752725, -2.266643, -0.957826, -0.047613])
SLOT_7_HELD_IN_TCP = np.array(
    [
        [-0.45399, 0.0, -0.891007, -0.000384],
        [0.0, 1.0, 0.0, 0.0],
        [0.891007, 0.0, -0.45399, 0.021129],
        [0.0, 0.0, 0.0, 1.0],
    ]
)


@pytest.mark.parametrize("turn", [0.0, 5.0])
def test_a_held_domino_at_a_planned_s_curve_slot_is_measured(
    world, pipeline, render_camera_2, turn
) -> None:
    heading = np.radians(80.99368)
    lead = 0.00075 * np.array([np.cos(heading), np.sin(heading)])  # released ahead
    release = upright_pose(*(np.array([0.451960, 0.092088]) + lead), heading).GetAsMatrix4()
    behind = upright_pose(0.450055, 0.063392, np.radians(91.48998)).GetAsMatrix4()
    world.set_robot_positions(SLOT_7_ARM, CLOSED)
    try:
        tcp = RigidTransform(world.tcp_pose())
        in_tcp = RigidTransform(SLOT_7_HELD_IN_TCP)
        pinch = in_tcp.inverse().translation() * [1.0, 1.0, 0.0]  # TCP on the mid plane
        turned = RigidTransform(pinch) @ RigidTransform(
            RotationMatrix.MakeYRotation(np.radians(turn))
        )
        domino = (tcp @ in_tcp @ turned @ RigidTransform(-pinch)).GetAsMatrix4()
        corners = CORNERS * [HALF_LENGTH, 0.012, HALF_THICKNESS] @ domino[:3, :3].T
        domino[2, 3] += 0.0002 - domino[2, 3] - corners[:, 2].min()
        views = render_camera_2({0: domino, 1: behind})
        [held] = check_placements([release], views, pipeline, PlacementConfig(in_hand=True))
    finally:
        world.set_robot_positions()
    assert held.status == STANDING
    foot, tilt = foot_and_tilt_errors(held.measured, domino)
    assert foot < FOOT_TOLERANCE and tilt < np.radians(0.5), (foot, np.degrees(tilt))


@pytest.mark.parametrize(("low", "seen"), [(0.0025, True), (0.001, True), (-0.002, False)])
def test_a_domino_held_lower_than_planned_is_read_that_low_but_not_higher(
    run_poses, pipeline, hold, low: float, seen: bool
) -> None:
    """Issue 23: the bring-up carries again a hold read more than 1 mm lower than planned
    above its slot (its descent would press it into the table). The fit sees how low it
    hangs, the points below the expected foot pulling the box down: here 0.4-0.5 mm short
    of it. It cannot see it hang higher: the top is cut off at the pads and the underside
    is not seen, so nothing pulls the box up and it reads as planned."""
    views, truth = hold(run_poses[2], 0.0, (0.0, 0.0, 0.0), -1, [run_poses[1]], height=0.07 - low)
    above = run_poses[2].copy()
    above[2, 3] += 0.07
    [held] = check_placements([above], views, pipeline, PlacementConfig(in_hand=True))
    assert held.status == STANDING
    hangs = above[2, 3] - truth[2, 3]  # lower than expected (both upright); let go 0.2 mm up
    assert hangs == pytest.approx(low - 0.0002, abs=1e-9)
    read = above[2, 3] - held.measured[2, 3]
    if seen:
        assert hangs - 0.0005 <= read <= hangs
    else:
        assert read == pytest.approx(0.0, abs=1e-4)


# Where the 30-domino ledger runs' in-hand checks saw nothing (issue 23: 48 of 118), as
# bench_in_hand renders them: 70 mm above the slot, the gripper over the slot's ±z side.
# spiral30 slot 21 and s_curve30 slot 21 head towards camera_2 (the gripper leaning over
# the free side ahead, +z, stands between camera_2 and the domino, and no pile camera sees
# the slot); circle30 slot 1 heads across camera_2's view (it sees the domino edge-on,
# which pins no turn about the pinch axis, whichever side the gripper leans to). camera_3,
# 49° round from camera_2, sees the domino past the gripper or face-on at all but one.
WITHOUT_CAMERA_3 = ("camera_0", "camera_1", "camera_2")  # the cell's cameras before it


@pytest.mark.parametrize(
    "x, y, heading, lean, seen_before, seen",
    [
        (0.625, 0.075, 36.0, 1, False, True),
        (0.625, 0.075, 36.0, -1, True, True),
        (0.611, 0.267, 44.0, 1, False, False),
        (0.611, 0.267, 44.0, -1, True, True),
        (0.68, 0.18, 90.0, 1, False, True),
        (0.68, 0.18, 90.0, -1, False, True),
    ],
)
def test_held_dominoes_where_the_ledger_saw_none_are_measured_with_camera_3(
    pipeline, hold, x, y, heading, lean, seen_before, seen
) -> None:
    """Every camera (the node's in_hand_cameras): a held domino is measured within the
    tolerances or NOT_SEEN, never a wrong pose (the job would carry a good hold again);
    with camera_3 it is measured where the cell's cameras before it (``seen_before``) saw
    it hidden by the gripper or edge-on; where the gripper hides it from camera_3 too,
    it is still NOT_SEEN."""
    slot = upright_pose(x, y, np.radians(heading)).GetAsMatrix4()
    views, truth = hold(slot, lean=lean, every_camera=True, height=0.07)
    above = slot.copy()
    above[2, 3] += 0.07
    config = PlacementConfig(in_hand=True)
    before = [v for v in views if v.name in WITHOUT_CAMERA_3]
    for cameras, expected_seen in ((before, seen_before), (views, seen)):
        [held] = check_placements([above], cameras, pipeline, config)
        assert held.status == (STANDING if expected_seen else NOT_SEEN), len(cameras)
        if expected_seen:
            foot, tilt = foot_and_tilt_errors(held.measured, truth)
            assert foot < FOOT_TOLERANCE and tilt < TILT_TOLERANCE, (foot, np.degrees(tilt))


def test_an_empty_hand_above_the_slot_is_not_seen(pipeline, hold) -> None:
    """The fingers closed on nothing above a slot that every camera sees: nothing below
    the pads to fit, so no evidence of a domino (never STANDING on the pads' points)."""
    slot = upright_pose(0.68, 0.18, np.radians(90.0)).GetAsMatrix4()
    above = slot.copy()
    above[2, 3] += 0.07
    for lean in (1, -1):
        views, _ = hold(slot, lean=lean, every_camera=True, height=0.07, holding=False)
        [held] = check_placements([above], views, pipeline, PlacementConfig(in_hand=True))
        assert held.status == NOT_SEEN


# s_curve30 slot 10 (bench_bringup's case; issue 23: blind in every 30-domino ledger run)
# as PickPlacePlanner carries it there (slots 1-9 standing): the arm where its transfer
# segment ends, the domino at SLOT_7_HELD_IN_TCP (the same canonical place grasp).
SLOT_10_ARM = np.array([1.18805, 1.293383, -1.208528, -1.740521, -2.305359, -1.229235, 0.197084])
S_CURVE30_SLOTS_8_9 = [(0.4181, 0.0663, 1.4785), (0.4222, 0.0879, 1.2866)]  # x, y, heading


@pytest.mark.parametrize("turn", [-6.0, 0.0, 6.0])
def test_a_hold_off_through_its_thickness_is_fitted_on_the_side_the_camera_sees(
    world, pipeline, render_every_camera, turn
) -> None:
    """The planned hold above s_curve30 slot 10, turned about the pinch axis: camera_2
    does not see it (the gripper), camera_3 alone does. Turned 6° one way the foot is
    ~4 mm off through the domino's thickness, and the fit from the expected pose put the
    box on the far side of the face camera_3 sees (its points fit a box on either side of
    it): camera_3 saw through that box and the hold was NOT_SEEN. Fitted from a thickness
    either side too, it is measured."""
    world.set_robot_positions(SLOT_10_ARM, CLOSED)
    try:
        tcp = RigidTransform(world.tcp_pose())
        in_tcp = RigidTransform(SLOT_7_HELD_IN_TCP)
        above = (tcp @ in_tcp).GetAsMatrix4()
        turned = RigidTransform(RotationMatrix.MakeYRotation(np.radians(turn)))
        truth = (tcp @ turned @ in_tcp).GetAsMatrix4()
        run = [upright_pose(*slot).GetAsMatrix4() for slot in S_CURVE30_SLOTS_8_9]
        views = render_every_camera({0: truth, 1: run[0], 2: run[1]})
        [held] = check_placements([above], views, pipeline, PlacementConfig(in_hand=True))
    finally:
        world.set_robot_positions()
    assert held.status == STANDING
    foot, tilt = foot_and_tilt_errors(held.measured, truth)
    assert foot < FOOT_TOLERANCE and tilt < TILT_TOLERANCE, (foot, np.degrees(tilt))

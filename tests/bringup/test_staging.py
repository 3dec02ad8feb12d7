"""Setting a standing neighbour aside (``task.staging``) without ROS: a scripted cell,
the real slot loop. A run domino lying across its slot between standing neighbours, no
grasp and no sweep of it planned: a neighbour is stood beside the pile, the lying one is
picked for the slot, and the neighbour's slot is to be built again."""

from __future__ import annotations

import math
from dataclasses import replace

import numpy as np
import pytest
from scipy.spatial.transform import Rotation

from dombot_bringup import layouts
from dombot_bringup.task.cell import Motion
from dombot_bringup.task.geometry import spot_of
from dombot_bringup.task.loop import Turn, place_slot
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.staging import aside_request, blocked_between, staging_spots
from dombot_bringup.task.state import Job
from dombot_planner.errors import ErrorCode
from support.scripted_cell import ScriptedCell, flat, lying, planned, refused
from support.sim_cells import blind_cell, run_segments

ARC = layouts.arc((0.0, 0.0), 0.6, math.radians(5.0), 10)  # the default run
PILE_CENTRE = (0.55, -0.30)
STANDING = (0, 1, 2, 3, 6, 7, 9)  # slot 9 (index 8) empty, 5 and 6 not built yet


def fallen_across(x: float, y: float, degrees: float) -> np.ndarray:
    """A domino lying flat at (x, y), its long side ``degrees`` from the world's x axis."""
    pose = lying(x, y)
    pose[:3, :3] = Rotation.from_euler("z", degrees, degrees=True).as_matrix()
    return pose


def enclosed_job(
    cell: ScriptedCell, settings: ArmJobSettings | None = None
) -> tuple[Job, np.ndarray]:
    """arc10_cycles5 seed 1, cycle 2: domino 9 knocked over as domino 10 was placed, lying
    19 mm outside its slot between the standing 8th and 10th."""
    job = Job.new(cell, ARC, "arc", settings or ArmJobSettings())
    job.state.standing = {k: job.targets[k] for k in STANDING}
    fallen = fallen_across(0.554, 0.27, 0.0)
    job.state.fallen = {8: fallen}
    return job, fallen


def test_staging_spots_keep_clear_of_the_pile_and_come_nearest_the_slot_first() -> None:
    pile = [lying(0.55 + 0.14 * math.cos(a), -0.30 + 0.14 * math.sin(a)) for a in (1.4, 1.6)]
    slot = (0.535, 0.272)
    spots = staging_spots(PILE_CENTRE, 0.14, slot, pile, np.zeros((0, 3)), 0.03)
    assert spots, "the ring has free spots"
    for spot in spots:
        assert math.dist((spot.x, spot.y), PILE_CENTRE) == pytest.approx(0.14)
        assert min(math.dist((spot.x, spot.y), spot_of(p)) for p in pile) > 0.04
    distances = [math.dist((s.x, s.y), slot) for s in spots]
    assert distances == sorted(distances)
    # the ring's point nearest the slot lies between the two pile dominoes: not offered
    assert distances[0] > math.dist(slot, (0.55, -0.16)) + 0.01
    # a seen point on the ring there rules out the spots around it too
    near_slot = np.array([[spots[0].x, spots[0].y, 0.0]])
    assert (spots[0].x, spots[0].y) not in [
        (s.x, s.y) for s in staging_spots(PILE_CENTRE, 0.14, slot, pile, near_slot, 0.03)
    ]


def test_a_domino_lying_between_standing_neighbours_is_reached_by_setting_one_aside() -> None:
    aside: list = []

    def place(request):
        if request.domino is job.state.standing.get(7) and not aside:
            aside.append(request)
            return planned("set aside")
        if aside and request.domino is fallen:
            return planned("place")
        return refused(ErrorCode.GRASP_UNREACHABLE)

    cell = ScriptedCell(pile=[flat(0.55)], place=place)
    job, fallen = enclosed_job(cell)
    assert place_slot(job, 8, may_defer=True) is Turn.PLACED
    # its sweeps were refused first (the scripted planner refuses every push)
    assert cell.strike_requests or job.state.unswept
    (request,) = aside
    assert math.dist(spot_of(request.place), PILE_CENTRE) == pytest.approx(0.14)
    assert math.dist(spot_of(request.place), (0.55, -0.30)) > 0.1  # not in the pile
    assert any(p is fallen for p in request.pile)  # beside the 8th: the pads may nudge it
    # the 8th is no longer standing: its slot is to be built again
    assert 7 not in job.state.standing and not job.report.dominoes[7].placed
    assert job.report.dominoes[8].set_aside[0].startswith("domino 8 set aside beside the pile")
    assert job.report.dominoes[8].placed
    assert job.report.summary()["set_aside"] == 1
    assert cell.place_requests[-1].domino is fallen  # picked for its slot after


def test_the_slot_of_a_neighbour_set_aside_is_built_again_with_attempts_of_its_own() -> None:
    """arc10_cycles5 seed 2, cycle 3: domino 2, placed at its 4th attempt, was set aside
    for slot 3 and its slot given up at once (max_attempts used before). The set aside is
    the task's own doing: the slot gets its attempts afresh."""
    aside: list = []

    def place(request):
        if request.domino is job.state.standing.get(7) and not aside:
            aside.append(request)
            return planned("set aside")
        return planned("place") if aside else refused(ErrorCode.GRASP_UNREACHABLE)

    cell = ScriptedCell(pile=[flat(0.55)], place=place)
    job, _ = enclosed_job(cell)
    job.report.dominoes[7].attempts = job.settings.max_attempts  # placed at its last
    assert place_slot(job, 8, may_defer=False) is Turn.PLACED
    assert aside and 7 not in job.state.standing
    assert place_slot(job, 7, may_defer=False) is Turn.PLACED
    assert job.report.dominoes[7].attempts == job.settings.max_attempts + 1


def test_nothing_is_set_aside_when_a_sweep_plans_or_none_is_allowed() -> None:
    cell = ScriptedCell(pile=[flat(0.55)], strike=lambda request: planned("sweep"))
    job, _ = enclosed_job(cell)
    assert blocked_between(job, 8) == []  # no sweep refused yet
    cell = ScriptedCell(pile=[flat(0.55)])
    job, _ = enclosed_job(cell, ArmJobSettings(max_set_asides=0))
    assert place_slot(job, 8, may_defer=False) is Turn.FAILED
    assert set(job.state.standing) == set(STANDING)
    assert not job.report.dominoes[8].set_aside


def test_a_set_aside_that_fails_counts_and_the_neighbour_is_looked_at_again() -> None:
    """Its carry stops short: the neighbour stands where the placement check sees it, the
    slot's set-asides run out and it is left empty, not tried for ever."""
    stops = lambda trajectory: Motion(trajectory.joint_names != ("carry",), "stopped short")  # noqa: E731
    cell = ScriptedCell(pile=[flat(0.55)], motion=stops)
    cell.place = lambda request: (
        planned("carry") if request.domino is job.state.standing.get(7) else refused()
    )
    job, _ = enclosed_job(cell)
    assert place_slot(job, 8, may_defer=False) is Turn.FAILED
    tries = job.report.dominoes[8].set_aside
    assert len(tries) == 2 and all("stopped short" in t for t in tries), tries
    assert 7 in job.state.standing  # seen standing by the placement check after each
    # and once what lies in the slot's way is looked at again (``look_at_the_way``): the
    # lying dominoes, then the unbuilt slots near them
    assert len(cell.checks) == 4


def test_a_domino_fallen_against_the_neighbour_is_a_pile_neighbour_of_its_pick() -> None:
    """arc10_cycles5 seed 2, cycle 4: domino 4 lay fallen against the standing 5th, 21 mm
    from its centre; sent as an obstacle, the planner refused every grasp of the 5th (the
    held domino "in collision at the pose") and slot 4 was left empty. As a pile
    neighbour (which the held domino may touch at its pick) the 5th is set aside and the
    fallen one picked for its slot; the run and the pile stay obstacles."""
    fallen = fallen_across(0.598, 0.162, 106.0)
    far = fallen_across(0.66, 0.10, 30.0)  # lying 9 cm from the 5th: still kept clear of
    pile = flat(0.55)
    aside: list = []

    def place(request):
        if request.domino is job.state.standing.get(4) and not aside:
            if any(p is fallen for p in request.standing):
                return refused(ErrorCode.GRASP_UNREACHABLE, "in collision at the pose (held)")
            aside.append(request)
            return planned("set aside")
        if aside and request.domino is fallen:
            return planned("place")
        return refused(ErrorCode.GRASP_UNREACHABLE)

    cell = ScriptedCell(pile=[pile], place=place)
    job = Job.new(cell, ARC, "arc", ArmJobSettings())
    job.state.standing = {k: job.targets[k] for k in (1, 2, 4, 5, 6, 7, 8, 9)}
    job.state.fallen = {3: fallen}
    job.state.toppled = [far]
    assert place_slot(job, 3, may_defer=False) is Turn.PLACED
    (request,) = aside
    assert len(request.pile) == 1 and request.pile[0] is fallen
    obstacles = [id(p) for p in request.standing]
    assert id(far) in obstacles and id(pile.pose) in obstacles
    assert {id(job.targets[k]) for k in (1, 2, 5, 6, 7, 8, 9)} <= set(obstacles)
    assert job.report.dominoes[3].set_aside[0].startswith("domino 5 set aside beside the pile")
    assert 4 not in job.state.standing and job.report.dominoes[3].placed


@pytest.mark.slow
def test_in_drake_the_neighbour_a_domino_fell_against_is_set_aside() -> None:
    """In Drake, the real planner and the world: domino 4 fallen flat against the standing
    5th (1 mm from its face, settled), the 6th standing beyond. With it an obstacle no
    grasp of the 5th plans (the evidence's refusal); as a pile neighbour the pick plans,
    and run in the world the 5th stands at the staging spot and the 6th still stands."""
    world, cell = blind_cell(domino_capacity=3)
    job = Job.new(cell, ARC, "arc", ArmJobSettings(plan_budget=0.0))
    fifth = ARC[4]
    outward = np.array(
        [math.cos(fifth.heading - math.pi / 2), math.sin(fifth.heading - math.pi / 2)]
    )
    x, y = np.array([fifth.x, fifth.y]) + outward * 0.025  # half widths 12 + 12 mm, 1 mm apart
    fallen = fallen_across(x, y, math.degrees(fifth.heading))
    world.set_domino_poses({0: job.targets[4], 1: job.targets[5], 2: fallen})
    world.settle(1.0)
    truth = [t.X_WD for t in world.domino_truth()]
    job.state.standing = {4: truth[0], 5: truth[1]}
    job.state.fallen = {3: truth[2]}
    spot = staging_spots(PILE_CENTRE, 0.14, (fifth.x, fifth.y), [], np.zeros((0, 3)), 0.03)[0]

    request = aside_request(job, 4, spot, [])
    assert len(request.pile) == 1 and request.pile[0] is truth[2]
    as_obstacle = replace(request, standing=(*request.standing, *request.pile), pile=())
    refusal = cell.plan_place(as_obstacle)
    assert refusal.error is ErrorCode.GRASP_UNREACHABLE, refusal.message
    assert "held–standing" in refusal.message  # the held domino against the fallen one
    plan = cell.plan_place(request)
    assert plan.success, plan.message
    run_segments(cell, plan.segments)
    cell.wait_for_sim_time(1.0)
    aside, sixth, _ = (t for t in world.domino_truth())
    assert aside.upright and math.dist(aside.X_WD[:2, 3], (spot.x, spot.y)) < 0.005
    assert sixth.upright and math.dist(sixth.X_WD[:2, 3], (ARC[5].x, ARC[5].y)) < 0.002

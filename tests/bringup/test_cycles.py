"""The perpetual cycle (``--cycles``) without ROS: a scripted cell, the real task core.

After each strike perception's look says where the run's dominoes lie; the next cycle
builds from them (nearest the slot first) before the pile, never pours again, and
reports each cycle; the job's exit status is the worst cycle's."""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path

import pytest
from scipy.spatial.transform import Rotation

from dombot_bringup import layouts
from dombot_bringup.bringup import cycle_layouts, parse_args
from dombot_bringup.layouts import LayoutError
from dombot_bringup.process_group import resident_mb
from dombot_bringup.sections import EXIT_FAILED, EXIT_PARTIAL, EXIT_SUCCESS, worst_status
from dombot_bringup.task.attempts import carried_away
from dombot_bringup.task.cell import PlacementCheck, Pose, Seen
from dombot_bringup.task.checks import look_again
from dombot_bringup.task.cycles import cycle_line, run_cycles
from dombot_bringup.task.geometry import distinct, in_the_way, near, placement_pose, spot_of
from dombot_bringup.task.loop import Turn, place_slot
from dombot_bringup.task.picking import Candidate, in_its_way, toppled_candidates
from dombot_bringup.task.records import at_slot
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_bringup.task.strike import strike
from dombot_description import tilt_from_vertical, tipped_pose
from dombot_description.scenario import load_scenario
from dombot_planner.errors import ErrorCode
from support.scripted_cell import ScriptedCell, flat, lying, planned, refused

LINE = layouts.line((0.45, 0.0), math.pi / 2, 3)  # slots at y = 0, 28.8 and 57.6 mm
# where the line's dominoes lie after a strike: each fell ahead onto the next
FALLEN_Y = [0.020, 0.0488, 0.0776]
PILE_Y = -0.3
# the scripted row lies flat, each domino over the next (a real one leans on the next),
# so the pads' and the pusher's pre-tests refuse it: the tests of the order and of the
# sweeps ask every offer (test_pads and test_strike_foresight cover the refusals foreseen)
ASK_EVERY_OFFER = ArmJobSettings(pile=8, foresee_refusals=False)


def toppling_cell(fallen_y: Sequence[float] = FALLEN_Y) -> ScriptedCell:
    """A cell where every placement stands and every strike topples the run: its
    dominoes are then seen lying at ``fallen_y`` along the line (perception answers them
    in slot order) until anything else moves (a sweep, a pick), then every upright place
    looked at stands again. A domino looked for lying (``checks.look_again``) lies where
    it was seen."""
    cell = ScriptedCell(pile=[flat(0.50), flat(0.60)], place=lambda request: planned("place"))
    cell.strike = lambda request: planned("strike")

    def placements(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        struck = (
            cell.executed
            and cell.executed[-1].joint_names == ("strike",)
            and cell.strike_requests[-1].sweep is None
        )
        upright = [pose for pose in expected if tilt_from_vertical(pose) < math.radians(15.0)]
        fell = iter(fallen_y)
        answers = [
            (Seen.FALLEN, pose, 0.0, tilt_from_vertical(pose))
            if not any(pose is u for u in upright)
            else (Seen.FALLEN, lying(0.45, next(fell)), 0.02, math.radians(85.0))
            if struck
            else (Seen.STANDING, pose, 0.001, 0.0)
            for pose in expected
        ]
        return PlacementCheck(True, "", *(tuple(column) for column in zip(*answers, strict=True)))

    cell.placements = placements
    return cell


def picked_from(cell: ScriptedCell) -> list[tuple[float, float]]:
    """Where each planned pick's domino lay (x, y), rounded to 0.1 mm."""
    return [(round(r.domino[0, 3], 4), round(r.domino[1, 3], 4)) for r in cell.place_requests]


def test_the_next_cycle_builds_from_the_toppled_dominoes_nearest_each_slot_first() -> None:
    cell = toppling_cell()
    jobs = run_cycles(cell, [("line", LINE)] * 2, ASK_EVERY_OFFER, lambda: {"sim": 512.0})
    assert len(jobs) == 2 and cell.resets == [(8, 0)]  # poured once
    first, second = picked_from(cell)[:3], picked_from(cell)[3:]
    assert first == [(0.5, PILE_Y), (0.5, PILE_Y), (0.5, PILE_Y)]  # the scripted pile
    # the toppled ones, each slot's nearest: the one lying over it becomes its domino
    assert second == [(0.45, 0.02), (0.45, 0.0488), (0.45, 0.0776)]
    report = jobs[-1].report
    assert [c.cycle for c in report.cycles] == [1, 2]
    one, two = report.cycles
    assert (one.toppled_found, one.toppled_picked) == (0, 0)
    assert (two.toppled_found, two.toppled_picked) == (3, 3)
    assert [(c.placed, c.dominoes, c.empty_slots) for c in report.cycles] == [(3, 3, [])] * 2
    assert [c.toppled_by_perception for c in report.cycles] == [3, 3]
    assert two.rss_mb == {"sim": 512.0} and report.exit_status == EXIT_SUCCESS
    # a cycle's own report lists the cycles up to it
    assert [c.cycle for c in jobs[0].report.cycles] == [1]
    line = cycle_line(two, 2)
    assert line.startswith("cycle 2/2 'line': SUCCESS, 3/3 placed") and "sim 512" in line


def test_every_cycles_picks_are_recorded_none_written_over(tmp_path: Path) -> None:
    """--record-picks with --cycles: one folder, numbered on across the cycles (each
    cycle's numbering from 0 wrote over the cycle before's records)."""
    settings = replace(ASK_EVERY_OFFER, record_picks=tmp_path)
    run_cycles(toppling_cell(), [("line", LINE)] * 2, settings)
    names = sorted(path.name for path in tmp_path.glob("*.json"))
    assert names == [f"pick{n:03d}_slot{n % 3 + 1}.json" for n in range(6)]


def test_the_next_layout_is_built_in_the_second_cycle_from_the_first_ones_toppled() -> None:
    cell = toppling_cell()
    beside = layouts.line((0.50, 0.0), math.pi / 2, 2)  # two, 5 cm further out
    jobs = run_cycles(cell, [("line", LINE), ("line of two", beside)], ASK_EVERY_OFFER)
    second = cell.place_requests[3:]
    assert [round(r.place[0, 3], 4) for r in second] == [0.5, 0.5]  # the new slots
    assert [(round(r.domino[0, 3], 4), round(r.domino[1, 3], 4)) for r in second] == [
        (0.45, 0.02),  # nearest the first new slot
        (0.45, 0.0488),
    ]
    report = jobs[-1].report
    assert report.layout == "line of two" and len(report.dominoes) == 2
    assert [(c.layout, c.dominoes, c.placed) for c in report.cycles] == [
        ("line", 3, 3),
        ("line of two", 2, 2),
    ]
    assert (report.cycles[1].toppled_found, report.cycles[1].toppled_picked) == (3, 2)


def test_a_toppled_domino_no_grasp_reaches_stays_an_obstacle_and_the_pile_fills_in() -> None:
    cell = toppling_cell()
    built = 0

    def place(request):  # the pile's dominoes plan; in the second cycle the toppled do not
        nonlocal built
        if request.domino[1, 3] > PILE_Y + 0.1 and built >= 3:
            return refused(ErrorCode.GRASP_UNREACHABLE)
        built += 1
        return planned("place")

    cell.place = place
    jobs = run_cycles(cell, [("line", LINE)] * 2, ArmJobSettings(pile=8))
    second = [r for r in cell.place_requests[3:] if r.domino[1, 3] == PILE_Y]
    assert len(second) == 3  # every slot from the pile
    lying_y = sorted(round(p[1, 3], 4) for p in second[0].standing)
    assert lying_y == FALLEN_Y  # the toppled dominoes kept clear of
    assert jobs[-1].report.cycles[1].toppled_picked == 0


def test_a_toppled_domino_no_grasp_reaches_over_a_slot_is_swept_aside_and_kept_in_mind() -> None:
    """Its pick refused, it would block the slot for good: pushed across the run (no slot
    of this layout to check it by), it is taken to lie where the push left it."""
    cell = ScriptedCell(pile=[flat(0.55)], strike=lambda request: planned())
    from_pile = lambda request: request.domino[1, 3] < PILE_Y + 0.1  # noqa: E731
    cell.place = lambda r: planned("place") if cell.strike_requests and from_pile(r) else refused()
    layout = layouts.line((0.45, 0.0), math.pi / 2, 3)
    job = Job.new(cell, layout, "line", ArmJobSettings())
    over_slot = lying(0.463, 0.0)  # 13 mm beside slot 1's centre, across the run
    job.state.toppled = [over_slot]
    job.state.unpickable.append(spot_of(over_slot))
    assert place_slot(job, 0, may_defer=True) is Turn.PLACED
    (sweep,) = cell.strike_requests
    assert sweep.domino is over_slot and sweep.sweep.tolist() == pytest.approx([1.0, 0.0])
    (moved,) = job.state.toppled
    assert moved[0, 3] == pytest.approx(0.463 + sweep.push_distance)
    assert len(job.report.dominoes[0].sweeps) == 1


def test_a_failed_cycle_ends_the_cycles_and_the_exit_status_is_the_worst() -> None:
    cell = toppling_cell()
    strikes = 0

    def strike(request):  # the second cycle's strike is refused: the run stays standing
        nonlocal strikes
        strikes += 1
        return planned("strike") if strikes == 1 else refused()

    cell.strike = strike
    jobs = run_cycles(cell, [("line", LINE)] * 3, ArmJobSettings(pile=8))
    assert len(jobs) == 2  # no third cycle on a run left standing
    report = jobs[-1].report
    assert [c.exit_status for c in report.cycles] == [EXIT_SUCCESS, EXIT_FAILED]
    assert report.exit_status == EXIT_FAILED and jobs[0].report.exit_status == EXIT_SUCCESS


def test_each_cycle_reports_its_own_verdict_after_a_partial_one() -> None:
    """A cycle built whole after a partial one is a success; only the job's exit status
    is the worst (arc10_cycles5 seed 2 called cycles 4 and 5 partial, 10/10 toppled)."""
    cell = toppling_cell()
    second_slot = LINE[1].y

    def place(request):  # the first cycle's second slot is refused: built around it
        first_cycle = not cell.strike_requests
        return (
            refused()
            if first_cycle and abs(request.place[1, 3] - second_slot) < 1e-3
            else planned("place")
        )

    cell.place = place
    jobs = run_cycles(cell, [("line", LINE)] * 2, ArmJobSettings(pile=8))
    report = jobs[-1].report
    assert [c.exit_status for c in report.cycles] == [EXIT_PARTIAL, EXIT_SUCCESS]
    assert [c.empty_slots for c in report.cycles] == [[2], []]
    assert report.exit_status == EXIT_PARTIAL


def test_the_worst_cycle_decides_failed_over_partial_over_success() -> None:
    assert worst_status([EXIT_SUCCESS, EXIT_PARTIAL, EXIT_SUCCESS]) == EXIT_PARTIAL
    assert worst_status([EXIT_PARTIAL, EXIT_FAILED, EXIT_SUCCESS]) == EXIT_FAILED
    assert worst_status([EXIT_SUCCESS]) == EXIT_SUCCESS


def area() -> layouts.BuildArea:
    scenario = load_scenario()
    return layouts.BuildArea(*scenario.build_x, *scenario.build_y, *scenario.build_reach)


def test_the_next_layout_is_given_like_the_first_and_keeps_what_it_does_not_say() -> None:
    args = parse_args(
        [
            *("--layout", "line", "--start", "0.5", "0.1", "--count", "3", "--pile", "8"),
            *("--cycles", "3", "--next-layout", "line --heading 60"),
        ]
    )
    chosen = cycle_layouts(args, area())
    assert [(name, len(p)) for name, p in chosen] == [("line", 3)] * 3
    first, following = chosen[0][1], chosen[1][1]
    assert (following[0].x, following[0].y) == (first[0].x, first[0].y)  # --start kept
    assert math.degrees(following[0].heading) == pytest.approx(60.0)
    assert math.degrees(first[0].heading) == pytest.approx(90.0)
    again = cycle_layouts(parse_args(["--count", "4", "--cycles", "2"]), area())
    assert again[0] is again[1] and again[0][0] == "arc"


def test_a_next_layout_from_a_csv(tmp_path) -> None:
    csv = tmp_path / "next.csv"
    csv.write_text("0.5,0.1\n0.5,0.2\n")
    args = parse_args(["--count", "4", "--cycles", "2", "--next-layout", f"csv --csv '{csv}'"])
    chosen = cycle_layouts(args, area())
    assert [(name, len(p)) for name, p in chosen] == [("arc", 4), ("csv", 4)]


@pytest.mark.parametrize(
    ("options", "message"),
    [
        (["--cycles", "0"], r"--cycles must be 1\.\.50"),
        (["--next-layout", "line"], r"--next-layout is built from the second cycle on"),
        (["--cycles", "2", "--next-layout", "hexagon"], r"--next-layout: argument layout"),
        (["--cycles", "2", "--next-layout", "line --pile 3"], r"--next-layout: unrecognized"),
        (["--cycles", "2", "--next-layout", ""], r"--next-layout needs a layout name"),
        (
            ["--cycles", "2", "--next-layout", "line --start 0.2 0.0"],
            r"cycle 2 \('line'\): .*outside the build area",
        ),
        (
            ["--pile", "10", "--cycles", "2", "--next-layout", "line --count 12"],
            r"cycle 2 \('line'\): a run of 12 needs at least as many dominoes",
        ),
    ],
)
def test_a_bad_cycle_option_is_refused_before_anything_starts(
    options: list[str], message: str
) -> None:
    with pytest.raises(LayoutError, match=message):
        cycle_layouts(parse_args(options), area())


def test_resident_memory_is_read_for_a_running_process_and_none_for_a_gone_one() -> None:
    assert resident_mb() > 10.0  # this test's python
    assert resident_mb(2**22 + 1) is None  # above the kernel's pid_max default


def test_a_lying_domino_is_in_a_slots_way_within_the_margin_and_where_the_pads_go() -> None:
    """The slot's domino stands across the line (thickness along y, width along x); a
    flat domino lies with its length along x, its width (24 mm) along y."""
    target, along, across = placement_pose(LINE[0]), 0.008, 0.021
    # its near side 8 mm ahead of the slot's centre: 4.25 mm from the slot's front face
    assert in_the_way(lying(0.45, 0.020), target, along, across)
    # its near side 14 mm ahead (over 8 mm clear of the front face): not in the way
    assert not in_the_way(lying(0.45, 0.026), target, along, across)
    # beside the slot across the run, its end 19 mm from the slot's side: where the pads go
    assert in_the_way(lying(0.505, 0.0), target, along, across)
    assert not in_the_way(lying(0.530, 0.0), target, along, across)
    # a struck domino leaning 75° on the next, its foot 5 mm ahead of the front face
    leaning = placement_pose(LINE[0])
    leaning[:3, :3] = Rotation.from_euler("x", -75.0, degrees=True).as_matrix() @ leaning[:3, :3]
    leaning[:3, 3] = [0.45, 0.00875 + 0.024 * math.sin(math.radians(75.0)), 0.01]
    assert in_the_way(leaning, target, along, across)


def test_a_domino_remembered_twice_is_one() -> None:
    """A struck run's check gave two slots the same lying domino, 4 mm apart: it is one
    obstacle, one toppled domino for the next cycle, and gone once it is picked up."""
    one, twin, other = lying(0.45, 0.020), lying(0.45, 0.024), lying(0.45, 0.0488)
    assert distinct([one, twin, other]) == [one, other]
    job = Job.new(ScriptedCell(), LINE, "line", ArmJobSettings())
    job.state.fallen = {1: one, 2: twin}
    job.state.toppled = [other]
    assert job.state.lying() == [one, other]
    carried_away(job, Candidate(one, 1))
    assert job.state.fallen == {} and job.state.lying() == [other]


def test_the_toppled_domino_in_a_slots_way_is_offered_first() -> None:
    job = Job.new(ScriptedCell(), LINE, "line", ArmJobSettings())
    # ahead: along the run, its end 10 mm ahead of the slot's centre (6 mm from its front
    # face); beside: across it, nearer the slot's centre, its side 13.5 mm ahead (clear)
    ahead, beside = lying(0.47, 0.034), lying(0.43, 0.0255)
    ahead[:3, :3] = Rotation.from_euler("z", 90.0, degrees=True).as_matrix()
    job.state.toppled = [beside, ahead]
    assert in_its_way(job, 0) == [ahead]
    assert [c.pose for c in toppled_candidates(job, 0, [])] == [ahead, beside]


def in_the_way_cell(refuse_toppled: bool) -> tuple[ScriptedCell, list[int]]:
    """A cell whose sweeps plan, whose pile domino plans, and whose toppled dominoes plan
    unless ``refuse_toppled``; with the sweeps done when each pick was asked for."""
    sweeps_before: list[int] = []
    cell = ScriptedCell(pile=[flat(0.55)], strike=lambda request: planned("sweep"))

    def place(request):
        sweeps_before.append(len(cell.strike_requests))
        if refuse_toppled and request.domino[1, 3] > PILE_Y + 0.1:
            return refused(ErrorCode.GRASP_UNREACHABLE)
        return planned("place")

    cell.place = place
    return cell, sweeps_before


def test_no_pile_domino_is_placed_while_a_toppled_one_no_grasp_takes_lies_in_the_way() -> None:
    """Cycle 3 of the arc: a pile domino placed beside a toppled one fell onto the run.
    Refused, the toppled domino is swept out of the slot's way before the pile's plans."""
    cell, sweeps_before = in_the_way_cell(refuse_toppled=True)
    job = Job.new(cell, LINE, "line", ArmJobSettings())
    job.state.toppled = [lying(0.45, 0.020)]
    assert place_slot(job, 0, may_defer=True) is Turn.PLACED
    froms = [round(r.domino[1, 3], 4) for r in cell.place_requests]
    assert froms[0] == 0.02 and froms[-1] == PILE_Y  # the toppled one first, refused
    assert len(cell.strike_requests) == 1 and sweeps_before[-1] == 1  # swept, then the pile
    assert in_its_way(job, 0) == [] and len(job.state.toppled) == 1  # out of the way, known


def test_the_truth_names_what_lay_against_a_slot_but_the_held_domino() -> None:
    """For the log after a placement fell or stalled: the simulator's dominoes whose
    footprint comes within 5 mm of the slot's (slot 1: x 0.438-0.462 across the run)."""
    near_end = {"4 mm off": 0.466, "6 mm off": 0.468}  # their ends towards the slot
    dominoes = [
        ("held", lying(0.45, 0.0)),
        ("under", lying(0.46, 0.01)),
        *((name, lying(x + 0.024, 0.0)) for name, x in near_end.items()),
    ]
    found = at_slot(dominoes, placement_pose(LINE[0]), "held")
    assert found == "under at [0.46, 0.01] tilted 90°, 4 mm off at [0.49, 0.0] tilted 90°"
    assert at_slot(dominoes[:1], placement_pose(LINE[0]), "held") == "nothing"


def test_a_domino_a_sweep_pushes_into_the_slot_is_swept_before_anything_is_placed() -> None:
    """Arc cycle 2, slot 6: the toppled domino pushed along with the one swept out of the
    slot's way was looked for where it had lain, and every placement there fell
    (presumably it lay in the slot). Pushed the whole way, it is taken to lie where the
    push left it: in the slot's way, swept in turn (pushing the first back: in line, they
    are scripted not to move but for the pushes), and no pile domino is placed there
    meanwhile."""
    cell, _ = in_the_way_cell(refuse_toppled=True)
    # two sweeps: pushed back into each other's way, the scripted pair would go on
    job = Job.new(cell, LINE, "line", ArmJobSettings(max_sweeps=2))
    # over slot 1, across the run (swept +x); behind it under the pads, clear of the slot
    over, behind = lying(0.455, 0.0), lying(0.3915, 0.0)
    job.state.toppled = [over, behind]
    assert in_its_way(job, 0) == [over]
    assert place_slot(job, 0, may_defer=True) is Turn.DEFERRED
    first, second = cell.strike_requests
    assert first.domino is over and "1 lying on its way with it" in job.report.dominoes[0].sweeps[0]
    assert spot_of(second.domino) == pytest.approx([0.3915 + first.push_distance, 0.0])
    assert all(r.domino[1, 3] != PILE_Y for r in cell.place_requests)


def test_of_two_toppled_dominoes_in_a_slots_way_one_is_swept_and_one_becomes_its_domino() -> None:
    cell, sweeps_before = in_the_way_cell(refuse_toppled=False)
    job = Job.new(cell, LINE, "line", ArmJobSettings())
    over, ahead = lying(0.45, -0.004), lying(0.45, 0.020)
    job.state.toppled = [over, ahead]
    assert place_slot(job, 0, may_defer=True) is Turn.PLACED
    (sweep,) = cell.strike_requests
    assert sweeps_before == [1]  # nothing planned while two lay there
    (left,) = job.state.toppled  # the swept one, out of the way; the other placed
    assert cell.place_requests[0].domino is not sweep.domino
    assert left[0, 3] != pytest.approx(0.45) and in_its_way(job, 0) == []


def test_a_struck_domino_seen_down_but_not_fitted_is_an_obstacle_swept_never_picked() -> None:
    """After the strike perception sees slot 2's domino down but fits no box to it (its
    own target answered, tilt 0), and looked at again it stays unfitted: the next cycle
    takes it to lie flat over slot 2's front edge, i.e. in slot 3's way: kept clear of,
    swept out of the way (across the run), never picked."""
    cell = toppling_cell()
    toppled, presumed = cell.placements, tipped_pose(placement_pose(LINE[1]), math.pi / 2)

    def placements(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        answer = toppled(expected, in_hand)
        unfitted = [
            (k, pose)
            for k, pose in enumerate(expected)
            if (k == 1 and len(expected) == 3 and answer.status == (Seen.FALLEN,) * 3)
            or pose[1, 3] == pytest.approx(presumed[1, 3])  # the strike's look, or again
        ]
        columns = [list(answer.measured), list(answer.position_error), list(answer.tilt)]
        for k, pose in unfitted:
            columns[0][k], columns[1][k], columns[2][k] = pose, 0.0, 0.0
        return PlacementCheck(True, "", answer.status, *(tuple(c) for c in columns))

    cell.placements = placements
    jobs = run_cycles(cell, [("line", LINE)] * 2, ASK_EVERY_OFFER)
    (unfitted,) = jobs[0].state.unfitted
    assert spot_of(unfitted) == pytest.approx(spot_of(presumed))
    second = cell.place_requests[3:]
    assert all(r.domino[1, 3] != pytest.approx(presumed[1, 3]) for r in second)
    kept_clear = [*second[0].standing, *second[0].pile]  # the pick beside it: its pile
    assert any(near(spot_of(p), spot_of(presumed), 1e-6) for p in kept_clear)
    swept = cell.strike_requests[1]  # after the first cycle's strike
    assert spot_of(swept.domino) == pytest.approx(spot_of(presumed))
    second_cycle = jobs[1].report.cycles[1]  # the unfitted one found, never picked
    assert (second_cycle.toppled_found, second_cycle.toppled_picked) == (3, 2)


def test_an_unfitted_struck_domino_is_looked_at_again_as_the_next_cycle_starts() -> None:
    """Slot 2's domino, seen down after the strike but not fitted, is asked about again
    as the next cycle starts, before anything is picked (perception refits a lying
    domino turned about the vertical too: ``placement_check._refit``); found, it is a
    toppled domino like the others, and picked. Before, it was looked at again only once
    something moved within 5 cm of it (arc10_cycles5 seed 2 carried 1, 3 and 7 unfitted
    into its cycles 3-5, never picked)."""
    cell = toppling_cell()
    toppled, presumed = cell.placements, tipped_pose(placement_pose(LINE[1]), math.pi / 2)
    found = lying(0.452, 0.052)
    asked_after: list[int] = []  # place requests made when the presumed pose was asked

    def placements(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        answer = toppled(expected, in_hand)
        columns = [list(answer.measured), list(answer.position_error), list(answer.tilt)]
        for k, pose in enumerate(expected):
            if k == 1 and len(expected) == 3 and answer.status == (Seen.FALLEN,) * 3:
                columns[0][k], columns[1][k], columns[2][k] = pose, 0.0, 0.0  # not fitted
            elif pose[1, 3] == pytest.approx(presumed[1, 3]):
                asked_after.append(len(cell.place_requests))
                columns[0][k], columns[2][k] = found, tilt_from_vertical(found)
        return PlacementCheck(True, "", answer.status, *(tuple(c) for c in columns))

    cell.placements = placements
    jobs = run_cycles(cell, [("line", LINE)] * 2, ASK_EVERY_OFFER)
    assert asked_after[0] == 3  # the first cycle's three picks, none of the second's
    assert any(r.domino is found for r in cell.place_requests[3:])
    second_cycle = jobs[1].report.cycles[1]
    assert (second_cycle.toppled_found, second_cycle.toppled_picked) == (3, 3)


def test_a_run_domino_left_lying_is_not_forgotten_when_its_slots_new_domino_falls() -> None:
    """Slot 2's fallen domino, which no grasp took, still lies beside the slot, built
    from the pile; struck, slot 2's new domino falls: both lie in the build area for the
    next cycle (the first was overwritten by the second's pose, unknown debris)."""
    old = lying(0.47, 0.030)
    cell = toppling_cell()
    job = Job.new(cell, LINE, "line", ASK_EVERY_OFFER)
    job.state.standing = {k: job.targets[k] for k in range(3)}
    job.state.fallen = {1: old}
    strike(job, [0, 1, 2])
    lying_now = job.state.lying()
    assert len(lying_now) == 4
    assert any(pose is old for pose in lying_now)


def looking_again(moved: Pose, seen_now: tuple, gone: Pose, unfit: Pose) -> ScriptedCell:
    """A cell whose look again finds ``moved`` lying as ``seen_now`` (pose, position
    error, tilt), ``gone`` missing and ``unfit`` down but not fitted; any other place
    (a slot's) empty."""
    answers = {
        id(moved): (Seen.FALLEN, *seen_now),
        id(gone): (Seen.MISSING, gone, 0.0, 0.0),
        id(unfit): (Seen.FALLEN, unfit, 0.0, 0.0),
    }
    return answering(answers)


def answering(answers: dict[int, tuple]) -> ScriptedCell:
    """A cell whose placement checks answer each pose by its id in ``answers`` (status,
    measured, position error, tilt), any other MISSING."""

    def placements(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        empty = [(Seen.MISSING, pose, 0.0, 0.0) for pose in expected]
        rows = (answers.get(id(pose), row) for pose, row in zip(expected, empty, strict=True))
        columns = zip(*rows, strict=True)
        return PlacementCheck(True, "", *(tuple(column) for column in columns))

    return ScriptedCell(placements=placements)


def test_toppled_dominoes_near_where_something_moved_are_looked_at_again() -> None:
    """Where they were seen: one found moved lies where perception measured it now, one
    down but not fitted is an obstacle only, one gone is forgotten; one far from what
    moved is not asked about."""
    moved, gone, unfit = lying(0.45, 0.020), lying(0.45, 0.049), lying(0.47, 0.035)
    far = lying(0.45, 0.20)
    now = lying(0.45, 0.035)

    cell = looking_again(moved, (now, 0.015, math.radians(85.0)), gone, unfit)
    job = Job.new(cell, LINE, "line", ArmJobSettings())
    job.state.toppled = [moved, gone, far]
    job.state.unfitted = [unfit]
    look_again(job)
    assert cell.checks == []  # nothing moved
    job.state.forget_refusals_near(spot_of(lying(0.45, 0.03)))  # a pick there
    look_again(job)
    (asked, _, _), (slots, _, _) = cell.checks  # the lying ones, then the slots
    assert [id(p) for p in asked] == [id(moved), id(gone), id(unfit)]
    assert [id(p) for p in slots] == [id(t) for t in job.targets]  # none stands, all near
    assert job.state.toppled == [far, now] and job.state.unfitted == [unfit]
    assert job.state.disturbed == []


def test_fallen_run_dominoes_near_where_something_moved_are_looked_at_again() -> None:
    """A run that fell lies shingled: picking one moves the ones leaning on it (circle30
    seed 1's rebuild closed many picks on nothing). Those near a pick are refitted as the
    toppled are: moved, gone (the slot built from elsewhere), unfitted (an obstacle)."""
    moved, gone, unfit, far = (lying(0.45, y) for y in (0.020, 0.049, 0.035, 0.20))
    now = lying(0.45, 0.028)

    cell = looking_again(moved, (now, 0.008, math.radians(74.0)), gone, unfit)
    job = Job.new(cell, LINE, "line", ArmJobSettings())
    job.state.fallen = {0: moved, 1: gone, 2: unfit, 5: far}
    job.state.forget_refusals_near(spot_of(lying(0.45, 0.03)))  # a pick there
    look_again(job)
    (asked, _, _), _ = cell.checks
    assert [id(p) for p in asked] == [id(moved), id(gone), id(unfit)]
    assert job.state.fallen == {0: now, 5: far}
    assert job.state.unfitted == [unfit] and job.state.toppled == []


def test_a_domino_unknown_so_far_found_lying_at_an_unbuilt_slot_is_taken_as_toppled() -> None:
    """Arc cycles seed 3: a pick knocked a domino onto slot 6, unseen, and four
    placements there fell off it. The unbuilt slots near what moved are looked at, after
    the lying dominoes and apart from them (an upright place took a lying one's points):
    one fitted lying there whose footprint meets no known lying domino is toppled (then
    in the slot's way); one that meets a known one in the slot's way is that one fitted
    again; one in the slot's way that meets only one known out of it (cycle 4: slot 5's,
    known 20 mm off and unfitted there) is toppled too; one down but not fitted gives
    nothing to act on; a standing slot and one far off are not asked."""
    line = layouts.line((0.45, 0.0), math.pi / 2, 7)  # slots 28.8 mm apart along y
    known = lying(0.45, 0.0576)  # over slot 3
    unknown = lying(0.46, 0.0288)  # over slot 2, 10 mm across the run
    stale, beside = lying(0.53, 0.125), lying(0.49, 0.1152)  # beside slot 5, overlapping
    answers: dict[int, tuple] = {}
    cell = answering(answers)
    job = Job.new(cell, line, "line", ArmJobSettings())
    targets = job.targets
    answers[id(known)] = (Seen.FALLEN, known, 0.0, math.radians(88.0))
    answers[id(targets[1])] = (Seen.FALLEN, unknown, 0.01, math.radians(88.0))
    answers[id(targets[2])] = (Seen.FALLEN, lying(0.451, 0.058), 0.0, math.radians(87.0))
    answers[id(targets[3])] = (Seen.FALLEN, targets[3], 0.0, 0.0)  # down, not fitted
    answers[id(targets[4])] = (Seen.FALLEN, beside, 0.04, math.radians(88.0))
    job.state.toppled = [known]
    job.state.unfitted = [stale]  # farther than DISTURBED_RADIUS from the pick: not asked
    assert in_its_way(job, 4) == [] and job.in_the_way(4, beside)
    job.state.standing = {0: job.targets[0]}
    job.state.disturbed = [spot_of(job.targets[2])]  # a pick over slot 3
    look_again(job)
    (lying_asked, _, _), (slots_asked, _, _) = cell.checks
    assert [id(p) for p in lying_asked] == [id(targets[0]), id(known)]
    assert [id(p) for p in slots_asked] == [id(targets[0]), *map(id, targets[1:6])]
    assert [id(p) for p in job.state.toppled] == [id(known), id(unknown), id(beside)]
    assert [id(p) for p in job.state.unfitted] == [id(stale)]
    assert [id(p) for p in in_its_way(job, 1)] == [id(unknown)]
    assert [id(p) for p in in_its_way(job, 4)] == [id(beside)]


def test_what_lies_in_a_slots_way_is_looked_at_again_before_the_slot_is_given_up() -> None:
    """Arc cycles seed 3 (at 2c413eb): slot 1 was left empty in cycles 1-4 for a domino
    remembered 19 mm from where it lay, every grasp and sweep of the remembered pose
    refused. Before an attempt is spent on what lies in a slot's way (or the slot put
    off), it is looked at again: found out of the way, the slot is built from the pile."""
    remembered, lies = lying(0.45, 0.020), lying(0.53, 0.0)  # in slot 1's way; beside it

    def placements(expected: Sequence[Pose], in_hand: bool) -> PlacementCheck:
        rows = [
            (Seen.FALLEN, lies, 0.08, math.radians(89.0))
            if pose is remembered
            else (Seen.STANDING, pose, 0.001, 0.0)
            if tilt_from_vertical(pose) < math.radians(15.0)
            else (Seen.MISSING, pose, 0.0, 0.0)
            for pose in expected
        ]
        return PlacementCheck(True, "", *(tuple(c) for c in zip(*rows, strict=True)))

    cell = ScriptedCell(pile=[flat(0.50, PILE_Y)], placements=placements)
    cell.place = lambda request: (
        planned("place") if request.domino[1, 3] == PILE_Y else refused(ErrorCode.GRASP_UNREACHABLE)
    )
    job = Job.new(cell, LINE, "line", ArmJobSettings())
    job.state.toppled = [remembered]
    assert in_its_way(job, 0) == [remembered]
    assert place_slot(job, 0, may_defer=False) is Turn.PLACED
    asked = [pose for expected, _, _ in cell.checks for pose in expected]
    assert any(pose is remembered for pose in asked)
    assert [id(p) for p in job.state.toppled] == [id(lies)] and in_its_way(job, 0) == []
    assert job.report.dominoes[0].attempts == 1

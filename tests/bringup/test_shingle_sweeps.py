"""A shingled row of fallen dominoes swept out of a slot's way with the real planner (no
ROS): the lying dominoes on the sweep's way are pushed along as one blob, the standing
run kept clear of (issue 23: s_curve30 seed 2, arc cycles 4 and 5)."""

from __future__ import annotations

import math

import pytest
from pydrake.math import RigidTransform

from dombot_bringup import layouts
from dombot_bringup.debris import carried_along, sweep_pushes
from dombot_bringup.task.cell import Plan, StrikeRequest, planner_strike_request
from dombot_bringup.task.clearing import sweep_debris
from dombot_bringup.task.geometry import near_any, placement_pose, spot_of
from dombot_bringup.task.picking import PLANNER_SETTINGS
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from dombot_description import tipped_pose
from dombot_description.scenario import load_scenario
from dombot_planner.errors import PlanningError
from dombot_planner.settings import PlannerSettings
from dombot_planner.strike import StrikePlan, StrikePlanner
from dombot_planner.verify import StrikeChecker
from support.planning_clock import UNHURRIED
from support.scripted_cell import ScriptedCell, planned

SCENARIO = load_scenario()
SETTINGS = PlannerSettings(default_time_budget=UNHURRIED)
CLEARANCE = PLANNER_SETTINGS.coarse_clearance
KEEP = ArmJobSettings().carry_clearance


def s_curve30() -> list[layouts.DominoPlacement]:
    """bench_bringup's s_curve30: its slots 1-12 run 0.40-0.47 m from the arm's base."""
    return layouts.s_curve((0.46, -0.08), math.radians(75), 0.6, 0.08, 30, 0.022)


def arc10() -> list[layouts.DominoPlacement]:
    """bench_bringup's arc10 (the arc's defaults: 0.6 m about the base, from 5°)."""
    return layouts.arc((0.0, 0.0), 0.6, math.radians(5.0), 10)


class RealStrikes:
    """/plan_strike answered by the real planner from the arm's home, as planner_node
    would; what it planned, with the request, for the checker."""

    def __init__(self, planner: StrikePlanner) -> None:
        self.planner = planner
        self.plans: list[tuple[StrikeRequest, StrikePlan]] = []

    def __call__(self, request: StrikeRequest) -> Plan:
        try:
            plan = self.planner.plan(planner_strike_request(request, SCENARIO.home_position, 0.0))
        except PlanningError as error:
            return Plan(False, error.code, f"{error.code.name} at {error.stage}: {error.message}")
        self.plans.append((request, plan))
        return planned("approach", "push", "retreat")


@pytest.fixture(scope="module")
def planner() -> StrikePlanner:
    return StrikePlanner(SCENARIO, SETTINGS)


def shingled(
    layout: list[layouts.DominoPlacement],
    standing: range,
    fallen: range,
    lean: float,
    cell: ScriptedCell,
) -> Job:
    """The layout's slots ``standing`` built; the dominoes of slots ``fallen`` fallen
    forward ``lean`` rad onto the next (a shingled row), seen down but not fitted (never
    picked)."""
    job = Job.new(cell, layout, "shingled", ArmJobSettings())
    job.state.standing = {i: job.targets[i] for i in standing}
    job.state.unfitted = [tipped_pose(job.targets[i], lean) for i in fallen]
    return job


@pytest.mark.parametrize(
    ("layout", "standing", "fallen", "lean"),
    [
        # domino 13 fell and felled 1-12 (67-90° from their targets, most ~70°)
        (s_curve30(), range(12, 13), range(12), math.radians(70.0)),
        # cycle 4 built slots 1-4 from the toppled row, which lay over 5-10 (~75°)
        (arc10(), range(4), range(4, 10), math.radians(75.0)),
    ],
    ids=["s_curve30_seed2", "arc10_cycle4"],
)
def test_a_shingled_row_is_swept_as_one_blob_clear_of_the_standing_run(
    planner, layout, standing, fallen, lean
) -> None:
    """The row lying over slot 5, seen down but not fitted: its domino there is swept
    across the run, those lying on the sweep's way with it; before, each was an obstacle
    of the sweep and every sweep of the row was refused. The plan keeps the arm
    coarse_clearance and the pads fine_obstacle_clearance from the standing run."""
    strikes = RealStrikes(planner)
    cell = ScriptedCell(strike=strikes)
    job = shingled(layout, standing, fallen, lean, cell)
    assert sweep_debris(job, 4, failed=[])
    ((request, plan),) = strikes.plans
    assert len(request.standing) < len(standing) + len(fallen) - 1  # some pushed along
    assert len(request.standing) >= len(standing)  # the standing run kept
    assert "lying on its way with it" in job.report.dominoes[4].sweeps[0]
    kept = [spot_of(p) for p in request.standing]
    carried = [spot_of(p) for p in job.state.unfitted if not near_any(spot_of(p), kept)]
    assert all(near_any(spot, job.state.disturbed) for spot in carried)  # looked at again
    run = tuple(RigidTransform(job.targets[i]) for i in standing)
    checker = StrikeChecker(
        SCENARIO, RigidTransform(request.domino), run, SETTINGS.acceleration_limit
    )
    result = checker.check(plan.sampled(SETTINGS.sample_period), SCENARIO.home_position, 0.0)
    for phase in ("approach", "push", "retreat"):
        assert result.min_clearance(phase, "arm", "standing") >= CLEARANCE
        pads = result.min_clearance(phase, "pads", "standing")
        assert pads >= SETTINGS.fine_obstacle_clearance


def test_the_dominoes_a_sweep_pushes_along() -> None:
    """Along a shingled row, the sweep of one domino across it pushes its neighbours on
    the row along (they lie where the pusher goes), not a domino farther along the row;
    none when one of them lies within carry_clearance of a standing domino, before or
    after the push (arc cycle 5: such a sweep left a standing domino leaning 9°)."""
    layout = arc10()
    targets = [placement_pose(p) for p in layout]
    row = [tipped_pose(t, math.radians(75.0)) for t in targets]
    debris, others = row[5], [row[4], row[6], row[9]]
    ((direction, distance), _) = sweep_pushes(debris, layout[5], 0.022)  # 46 mm inwards

    def carried(standing: list) -> list[int] | None:
        return carried_along(debris, others, standing, direction, distance, CLEARANCE, KEEP)

    assert carried([]) == [0, 1]
    # slot 5 (index 4) standing where its domino fell from: 4's domino touches it
    assert carried([targets[4]]) is None
    # a domino standing 10 mm beyond where the row's next domino would be pushed to
    beyond = targets[6].copy()
    beyond[:2, 3] = spot_of(row[6]) + (distance + 0.01) * direction[:2]
    assert carried([beyond]) is None
    # ... or standing far from the row (slot 1): nothing changes
    assert carried([targets[0]]) == [0, 1]

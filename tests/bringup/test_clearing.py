"""Sweeping debris out of a slot's way (``dombot_bringup.task.clearing``) against a
scripted cell: a sweep the planner refused is not asked again while nothing changed."""

from __future__ import annotations

import math

from dombot_bringup import layouts
from dombot_bringup.task.clearing import sweep_debris
from dombot_bringup.task.geometry import spot_of
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job
from support.scripted_cell import ScriptedCell, lying, refused


def blocked_slot() -> tuple[Job, ScriptedCell]:
    """A line of 4 with 1 and 4 standing; domino 3 fell flat 13 mm off its slot, where no
    grasp reaches it; every sweep of it is refused."""
    cell = ScriptedCell(strike=lambda request: refused())
    layout = layouts.line((0.45, 0.0), math.pi / 2, 4)
    run_job = Job.new(cell, layout, "line", ArmJobSettings())
    state, targets = run_job.state, run_job.targets
    state.standing = {0: targets[0], 3: targets[3]}
    state.fallen[2] = lying(targets[2][0, 3] + 0.013, targets[2][1, 3])
    state.unpickable.append(spot_of(state.fallen[2]))
    return run_job, cell


def test_a_refused_sweep_is_not_asked_again_until_something_changes() -> None:
    run_job, cell = blocked_slot()
    state = run_job.state
    assert not sweep_debris(run_job, 2, failed=[])
    assert len(cell.strike_requests) == 2  # both sides across the run, refused
    assert not sweep_debris(run_job, 2, failed=[])
    assert len(cell.strike_requests) == 2  # the same sweeps, the same obstacles: not asked
    state.standing[1] = run_job.targets[1]  # one more obstacle: still refused, not asked
    assert not sweep_debris(run_job, 2, failed=[])
    assert len(cell.strike_requests) == 2
    del state.standing[0], state.standing[1]  # a standing domino gone: asked again
    assert not sweep_debris(run_job, 2, failed=[])
    assert len(cell.strike_requests) == 4
    state.forget_refusals_near(spot_of(state.fallen[2]))  # something near it moved,
    state.unpickable.append(spot_of(state.fallen[2]))  # its pick refused again: swept again
    assert not sweep_debris(run_job, 2, failed=[])
    assert len(cell.strike_requests) == 6

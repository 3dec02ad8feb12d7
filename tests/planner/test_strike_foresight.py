"""Strikes and sweeps refused before any IK (dombot_planner.strike_foresight) agree with
the planner's answers."""

from __future__ import annotations

import dataclasses
import math

import numpy as np
import pytest
from pydrake.math import RigidTransform

from dombot_description import DOMINO_SIZE
from dombot_description.grasp import flat_pose, gripper_geometry, release_opening
from dombot_description.scenario import load_scenario
from dombot_planner.errors import ErrorCode, PlanningError
from dombot_planner.pads import pads_near
from dombot_planner.request import StrikeRequest
from dombot_planner.settings import PlannerSettings
from dombot_planner.strike import StrikePlanner
from dombot_planner.strike_foresight import foreseen_strike_refusal
from support.planning_clock import UNHURRIED

SCENARIO = load_scenario()
SETTINGS = PlannerSettings(default_time_budget=UNHURRIED)
ALONG = np.array([0.0, 1.0, 0.0])  # the sweep
DOMINO = flat_pose(0.58, -0.30, math.pi / 2)  # flat, its length along the sweep


@pytest.fixture(scope="module")
def planner() -> StrikePlanner:
    return StrikePlanner(SCENARIO, SETTINGS)


def behind(gap: float) -> RigidTransform:
    """A flat domino across the sweep behind DOMINO, its near face ``gap`` from DOMINO's
    back end."""
    offset = DOMINO_SIZE[0] / 2 + gap + DOMINO_SIZE[1] / 2
    return flat_pose(*(DOMINO.translation() - offset * ALONG)[:2], 0.0)


def sweep(standing: tuple[RigidTransform, ...]) -> StrikeRequest:
    return StrikeRequest(
        DOMINO,
        SCENARIO.home_position,
        release_opening(DOMINO_SIZE[1]),
        standing,
        push_distance=0.02,
        sweep=ALONG,
    )


def test_pusher_near_a_domino_beside_a_pad() -> None:
    """A domino beside the closed pads' end face, 3 mm from it (or 1 mm into it), is within
    coarse_clearance (5 mm) of the pusher; 7 mm from it, it is not."""
    pad = gripper_geometry().pad_boxes_in_tcp(0.0)[0]
    clearance = SETTINGS.coarse_clearance

    def beside(gap: float) -> RigidTransform:
        return pad.pose @ RigidTransform([pad.size[0] / 2 + DOMINO_SIZE[0] / 2 + gap, 0.0, 0.0])

    tcp = RigidTransform()
    assert pads_near(tcp, 0.0, [beside(-0.001)], clearance)
    assert pads_near(tcp, 0.0, [beside(0.003)], clearance)
    assert not pads_near(tcp, 0.0, [beside(0.007)], clearance)
    assert not pads_near(tcp, 0.0, [], clearance)


@pytest.mark.parametrize(
    ("standing", "foreseen"),
    [
        ((behind(0.002),), True),  # the pusher's place taken at every orientation
        ((behind(0.03),), True),  # the pads within 5 mm of it at every orientation
        ((behind(0.06),), False),  # room behind it: it plans
        ((), False),
    ],
    ids=["boxed_in", "close", "room", "alone"],
)
def test_a_foreseen_strike_refusal_is_the_planners(planner, standing, foreseen: bool) -> None:
    """``foreseen_strike_refusal`` says why only where the planner refuses the sweep."""
    request = sweep(standing)
    foreseen_error = foreseen_strike_refusal(request, SETTINGS)
    assert (foreseen_error is not None) == foreseen
    if foreseen:
        with pytest.raises(PlanningError) as refused:
            planner.plan(request)
        assert refused.value.code == foreseen_error.code == ErrorCode.PLACE_IN_COLLISION
    else:
        assert planner.plan(request).segments


def test_a_sweep_into_a_standing_domino_is_foreseen() -> None:
    """The request's own checks (a sweep that pushes the domino into another) are told."""
    ahead = dataclasses.replace(sweep(()), sweep=-ALONG, standing=(behind(0.005),))
    refusal = foreseen_strike_refusal(ahead, SETTINGS)
    assert refusal is not None and refusal.stage == "validation"

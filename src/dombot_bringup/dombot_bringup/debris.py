"""Pushes that clear a slot of the run of a fallen domino no grasp reaches (no ROS).

A domino that fell between standing neighbours often leaves the fingers no room on
either side of it; left there it blocks its slot for good (two S-curve runs ended so).
The planner's sweep (/plan_strike with a sweep direction) pushes it low across the run
instead; here is which way, and how far.
"""

from __future__ import annotations

import math

import numpy as np

from dombot_bringup.layouts import DOMINO_WIDTH, DominoPlacement
from dombot_description import domino_corners
from dombot_description.pusher import MAX_SWEEP_DISTANCE as MAX_SWEEP


def sweep_pushes(
    debris: np.ndarray, placement: DominoPlacement, margin: float
) -> list[tuple[np.ndarray, float]]:
    """(direction, distance) pushes across the run at ``placement`` after which the fallen
    domino at ``debris`` (4×4 pose) lies ``margin`` beyond the run's side: towards the side
    its centre is on first (the shorter push), then the other; none longer than MAX_SWEEP."""
    across = np.array([-math.sin(placement.heading), math.cos(placement.heading), 0.0])
    offset = domino_corners(debris) - [placement.x, placement.y, 0.0]
    side = 1.0 if np.mean(offset @ across) >= 0.0 else -1.0
    pushes = []
    for direction in (side * across, -side * across):
        hindmost = (offset @ direction).min()
        distance = DOMINO_WIDTH / 2 + margin - hindmost
        if distance <= MAX_SWEEP:
            pushes.append((direction, distance))
    return pushes

"""Whether the run still topples through a domino standing off its target: the geometry
of it and its neighbours (``chain_breaks``), and what lifting it out of the run would put
at risk (``at_risk``)."""

from __future__ import annotations

import math
from collections.abc import Collection, Mapping

import numpy as np

from dombot_bringup.task.cell import Pose
from dombot_bringup.task.settings import ArmJobSettings
from dombot_description import DOMINO_SIZE

HEIGHT, WIDTH = DOMINO_SIZE[0], DOMINO_SIZE[1]


def topple_miss(falling: Pose, struck: Pose, settings: ArmJobSettings) -> str:
    """Why ``falling``, toppling towards ``struck`` (across its faces, the side ``struck``
    is on), would not topple it; "" when it would: the centres' spacing along the fall
    within the toppling range (``chain_spacing`` of the height: the layouts' range, which
    every simulated wave carried), ``struck``'s centre off the line of the fall by at most
    (1 - chain_min_overlap) of the width, the faces turned at most chain_max_yaw."""
    along = np.asarray(falling[:2, 2], dtype=float)
    along /= np.linalg.norm(along)
    offset = np.asarray(struck[:2, 3] - falling[:2, 3], dtype=float)
    if float(offset @ along) < 0.0:
        along = -along
    spacing = float(offset @ along)
    across = abs(float(offset @ np.array([-along[1], along[0]])))
    other = np.asarray(struck[:2, 2], dtype=float)
    turn = math.acos(min(1.0, abs(float(other @ along)) / max(float(np.linalg.norm(other)), 1e-9)))
    low, high = (ratio * HEIGHT for ratio in settings.chain_spacing)
    if not low <= spacing <= high:
        return (
            f"{spacing * 1e3:.1f} mm apart along the fall, outside the "
            f"{low * 1e3:.1f}-{high * 1e3:.1f} mm that topples"
        )
    overlap = 1.0 - across / WIDTH
    if overlap < settings.chain_min_overlap:
        return (
            f"{across * 1e3:.1f} mm to the side: it would meet {max(overlap, 0.0):.0%} of "
            f"the face, less than {settings.chain_min_overlap:.0%}"
        )
    if turn > settings.chain_max_yaw:
        return f"faces turned {math.degrees(turn):.0f}° to each other, more than " + (
            f"{math.degrees(settings.chain_max_yaw):.0f}°"
        )
    return ""


def chain_breaks(
    index: int,
    pose: Pose,
    tilt: float,
    neighbours: Mapping[int, Pose],
    settings: ArmJobSettings,
) -> str:
    """Why the run would stop at domino ``index`` standing at ``pose``, leaning ``tilt``
    from vertical; "" when it still topples through it: toppled by the one before it and
    toppling the next (``neighbours``: layout index → where each stands or will stand;
    the run's ends have one). Leaning more than chain_max_tilt it is not standing on its
    own foot (something holds it): no word on where it would fall."""
    if tilt > settings.chain_max_tilt:
        return f"leaning {math.degrees(tilt):.1f}°: it rests on something"
    pairs = (
        (index - 1, neighbours.get(index - 1), index, pose),
        (index, pose, index + 1, neighbours.get(index + 1)),
    )
    for first, falling, second, struck in pairs:
        if falling is None or struck is None:
            continue
        if why := topple_miss(falling, struck, settings):
            return f"domino {first + 1} would not topple domino {second + 1}: {why}"
    return ""


def at_risk(index: int, standing: Collection[int]) -> list[int]:
    """The ``standing`` dominoes a fall of domino ``index`` could take down: those with
    no empty slot between them and it, either way (a closed section once its safety gaps
    are filled)."""
    reached = []
    for step in (-1, 1):
        k = index + step
        while k in standing:
            reached.append(k)
            k += step
    return sorted(reached)

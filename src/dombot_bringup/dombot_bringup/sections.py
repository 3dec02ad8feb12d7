"""A run built around empty slots: its standing sections, their strike order, the verdict.

A slot that cannot be filled stays empty and the run is built around it. What stands
falls apart into sections (maximal groups of consecutive standing slots); each is struck
from its own first domino, because the wave stops at an empty slot: the spacing is ~60 %
of a domino's height, so across one empty slot the next domino stands 1.2 heights away.

Strike order: a domino topples forward along the run (body z, the layout's heading), so a
struck section's dominoes land on the slots after it, never before it. Struck from the
end of the run backwards, every section still standing lies behind the one struck: its
fall cannot reach them, and the arm, coming down behind a section's first domino, never
meets the dominoes an earlier strike left lying in the gap before it (the planner knows
only upright obstacles). A run that curls back (a spiral's turns, a closed circle) can
put an earlier section within a toppling domino's reach; ``strike_order`` therefore
checks each section's fall against the unstruck ones and puts off a section that would
hit one. No ROS here: the arm job asks, these functions decide.
"""

from __future__ import annotations

import math
from collections import Counter
from collections.abc import Iterable, Mapping, Sequence
from dataclasses import dataclass

import numpy as np

from dombot_bringup.layouts import DOMINO_LENGTH, DOMINO_THICKNESS, DOMINO_WIDTH, DominoPlacement
from dombot_planner.errors import ErrorCode

# How far ahead of its centre a toppling domino's top lands (as for the safety gaps), and
# how far to either side of its line another domino's centre must be to be missed.
TOPPLE_REACH = DOMINO_LENGTH + DOMINO_THICKNESS  # m
TOPPLE_HALF_WIDTH = DOMINO_WIDTH  # m: both dominoes' half widths

# Exit statuses of the arm job (bringup's 130 is Ctrl-C); EXIT_REFUSED: bad options, layout
# or environment, refused before any node starts
EXIT_SUCCESS, EXIT_FAILED, EXIT_REFUSED, EXIT_PARTIAL = 0, 1, 2, 3
VERDICTS = {EXIT_SUCCESS: "SUCCESS", EXIT_PARTIAL: "PARTIAL", EXIT_FAILED: "FAILED"}


@dataclass(frozen=True)
class Section:
    """Consecutive standing slots ``first``..``last`` (layout indices, both included)."""

    first: int
    last: int

    @property
    def slots(self) -> range:
        return range(self.first, self.last + 1)

    def __str__(self) -> str:  # counted from 1, as in the log
        if self.first == self.last:
            return f"domino {self.first + 1}"
        return f"dominoes {self.first + 1}-{self.last + 1}"


def sections_of(standing: Iterable[int]) -> list[Section]:
    """The maximal groups of consecutive slots in ``standing``, in run order."""
    slots = sorted(set(standing))
    sections: list[Section] = []
    for slot in slots:
        if sections and sections[-1].last == slot - 1:
            sections[-1] = Section(sections[-1].first, slot)
        else:
            sections.append(Section(slot, slot))
    return sections


def topples_onto(placement: DominoPlacement, other: DominoPlacement) -> bool:
    """Whether ``placement``, toppling forward, lands on ``other``: its centre lies ahead of
    ``placement``'s within TOPPLE_REACH, and within TOPPLE_HALF_WIDTH of its line."""
    offset = np.array([other.x - placement.x, other.y - placement.y])
    along = np.array([math.cos(placement.heading), math.sin(placement.heading)])
    ahead = float(offset @ along)
    aside = abs(float(offset @ np.array([-along[1], along[0]])))
    return 0.0 < ahead <= TOPPLE_REACH and aside <= TOPPLE_HALF_WIDTH


def hits(section: Section, others: Iterable[Section], layout: Sequence[DominoPlacement]) -> bool:
    """Whether striking ``section`` would topple a domino of one of ``others``."""
    targets = [layout[i] for other in others for i in other.slots]
    return any(topples_onto(layout[i], target) for i in section.slots for target in targets)


def strike_order(sections: Sequence[Section], layout: Sequence[DominoPlacement]) -> list[Section]:
    """``sections`` in the order to strike them: from the end of the run backwards, each
    time the last unstruck section whose fall reaches no other unstruck one (see the module
    docstring). When every one would (a ring closed on itself), the last: what it knocks
    over early is seen by perception and reported."""
    unstruck = sorted(sections, key=lambda s: s.first)
    order: list[Section] = []
    while unstruck:
        safe = [s for s in unstruck if not hits(s, [o for o in unstruck if o != s], layout)]
        chosen = (safe or unstruck)[-1]
        order.append(chosen)
        unstruck.remove(chosen)
    return order


def count_refusal(refusals: dict[str, int], code: int, foreseen: bool = False) -> None:
    """Count a /plan_place refusal under its error code's name (``foreseen``: told without
    asking the planner, under the name and " (foreseen)")."""
    try:
        name = ErrorCode(code).name
    except ValueError:  # a newer planner's
        name = str(code)
    name += " (foreseen)" if foreseen else ""
    refusals[name] = refusals.get(name, 0) + 1


def empty_reason(
    failures: Sequence[str], deferrals: Sequence[str], refusals: Mapping[str, int]
) -> str:
    """Why a slot was given up, in one line: its attempts' failures, each once with how
    often (or what put it off when no attempt was made), then the planner's refusals for
    it by code, most first (PLACE_*: about the slot; GRASP_*: about the dominoes)."""
    told = Counter(failures) or Counter(deferrals[-1:]) or Counter(["not attempted"])
    reason = ", ".join(why if n == 1 else f"{why} x{n}" for why, n in told.items())
    ranked = sorted(refusals.items(), key=lambda item: -item[1])
    if ranked:
        reason += "; the planner refused: " + ", ".join(f"{name} x{n}" for name, n in ranked)
    return reason


def empty_message(slot: int, reason: str) -> str:
    """The log's and report's line for slot ``slot`` (layout index) given up."""
    return f"domino {slot + 1} could not be placed ({reason}): left empty, building around it"


def exit_status(
    empty: int,
    sections: int,
    struck: int,
    toppled_by_perception: bool,
    toppled_by_truth: bool | None,
) -> int:
    """EXIT_SUCCESS: no slot empty, the run struck and seen down; EXIT_PARTIAL: some slots
    empty, every section struck and every standing domino seen down (and not contradicted
    by the simulator's truth, where it is known); EXIT_FAILED otherwise (nothing stood, a
    strike failed or left dominoes standing)."""
    down = sections > 0 and struck == sections and toppled_by_perception
    if not down or toppled_by_truth is False:
        return EXIT_FAILED
    return EXIT_PARTIAL if empty else EXIT_SUCCESS


def worst_status(statuses: Iterable[int]) -> int:
    """The exit status of several runs (``--cycles``): EXIT_FAILED if one failed, else
    EXIT_PARTIAL if one was partial, else EXIT_SUCCESS."""
    ranked = (EXIT_SUCCESS, EXIT_PARTIAL, EXIT_FAILED)
    return max(statuses, key=ranked.index, default=EXIT_SUCCESS)

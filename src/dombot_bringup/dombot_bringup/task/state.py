"""One run's state: what the task learnt of the build and the pile so far."""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field
from typing import TYPE_CHECKING

import numpy as np

from dombot_bringup.layouts import DominoPlacement
from dombot_bringup.process_group import say
from dombot_bringup.run_report import DominoOutcome, RunReport, target_of
from dombot_bringup.task.cell import Cell, Detections, Later, Pose
from dombot_bringup.task.geometry import (
    SAME_SPOT,
    distinct,
    in_the_way,
    near,
    placement_pose,
    spot_of,
)
from dombot_bringup.task.settings import ArmJobSettings

if TYPE_CHECKING:
    from dombot_bringup.task.ahead import PlanAhead

DISTURBED_RADIUS = 0.05  # m: a pick moves the dominoes whose centres are this close to it


def log(message: str) -> None:
    """A ``[bringup]`` line, written whole among the nodes' forwarded output."""
    say(message)


@dataclass
class BuildState:
    standing: dict[int, Pose] = field(default_factory=dict)  # layout index → target pose
    fallen: dict[int, Pose] = field(default_factory=dict)  # layout index → measured pose
    # dominoes an earlier cycle knocked down (``task.cycles``), where perception saw them
    # lie: picked for this run's slots before the pile's, obstacles until then
    toppled: list[Pose] = field(default_factory=list)
    # struck dominoes perception saw down but could not fit, where they presumably lie
    # (``strike``; settings.unfitted_lean): obstacles, swept out of a slot's way, not picked
    unfitted: list[Pose] = field(default_factory=list)
    # (x, y) where something moved (a pick, a push, a fall) since the toppled dominoes
    # were last seen: those near it are looked at again before one is picked
    disturbed: list[np.ndarray] = field(default_factory=list)
    toppled_picked: int = 0  # toppled dominoes picked up (the report's count)
    # (x, y) of dominoes no grasp reaches or whose pick failed: not offered again
    unpickable: list[np.ndarray] = field(default_factory=list)
    stuck: set[int] = field(default_factory=set)  # run dominoes whose pick-up again failed
    # run dominoes seen standing off target and left there (``checks.second_look``): kept
    # while they stay where they were left, without another look
    left_off: set[int] = field(default_factory=set)
    crowded: list[np.ndarray] = field(default_factory=list)  # (x, y) refused with its pile
    cored: list[np.ndarray] = field(default_factory=list)  # ... and with its pile's cores
    # (x, y) of pile dominoes pushed to lay them flat, or whose pushes were all refused:
    # not pushed again there (one that did not move would be pushed for ever)
    pushed: list[np.ndarray] = field(default_factory=list)
    # why the pile domino at (x, y) is out of reach: the last refusal of it or its push
    reasons: list[tuple[np.ndarray, str]] = field(default_factory=list)
    # debris sweeps the planner refused: the domino's (x, y), the push (x, y direction
    # times distance) and the slots standing then; not asked again while those still stand
    # and nothing near it moved (arc cycle 5: one toppled domino's two sweeps refused 26
    # times over the turns of the three slots it blocked)
    unswept: list[tuple[np.ndarray, np.ndarray, frozenset[int]]] = field(default_factory=list)
    # layout index → its attempts when its domino, standing, was set aside beside the pile
    # (``staging``): the slot is built again with max_attempts of its own (arc10_cycles5
    # seed 2, cycle 3: slot 2, placed at its 4th attempt and then set aside, was given up
    # at once)
    set_aside_after: dict[int, int] = field(default_factory=dict)
    # layout index → the slots standing when a flat domino's place there planned with its
    # pile ignored (``attempts.places_ignoring_pile``): not asked again while they stand
    place_planned: dict[int, frozenset[int]] = field(default_factory=dict)

    def lying(self) -> list[Pose]:
        """Every domino known to lie in the build area: the run's fallen, the toppled, the
        unfitted; one remembered twice (within SAME_SPOT) once."""
        return distinct([*self.fallen.values(), *self.toppled, *self.unfitted])

    def knocked_down(self, index: int) -> None:
        """Slot ``index``'s domino no longer stands. A run domino still remembered fallen
        from that slot (no grasp took it, and the slot was built from elsewhere) is
        another domino: kept as a toppled one, not overwritten by this one's pose and
        forgotten (arc cycles seed 2, cycle 3: run domino 2, refused at [0.598, 0.053],
        still lay there when slot 2, built from the pile, was struck)."""
        if self.standing.pop(index, None) is not None and index in self.fallen:
            self.toppled.append(self.fallen.pop(index))

    def forget_refusals_near(self, spot: np.ndarray) -> None:
        """A pick or push at ``spot`` moved the dominoes around it: offer them again, and
        look at the toppled ones there again before picking one."""
        self.disturbed.append(spot)
        self.unpickable = [u for u in self.unpickable if not near(u, spot, DISTURBED_RADIUS)]
        self.crowded = [u for u in self.crowded if not near(u, spot, DISTURBED_RADIUS)]
        self.cored = [u for u in self.cored if not near(u, spot, DISTURBED_RADIUS)]
        self.pushed = [u for u in self.pushed if not near(u, spot, DISTURBED_RADIUS)]
        self.reasons = [r for r in self.reasons if not near(r[0], spot, DISTURBED_RADIUS)]
        self.unswept = [u for u in self.unswept if not near(u[0], spot, DISTURBED_RADIUS)]

    def pushed_along(self, pose: Pose, push: np.ndarray) -> None:
        """The lying domino remembered at ``pose`` (and any remembered within SAME_SPOT of
        it: the same domino) was pushed ``push`` (x, y): taken to lie there now, and looked
        at again there before the next pick (``checks.look_again``)."""
        spot = spot_of(pose)
        moved = pose.copy()
        moved[:2, 3] += push

        def there(other: Pose) -> bool:
            return other is pose or near(spot_of(other), spot, SAME_SPOT)

        self.toppled = [moved if there(p) else p for p in self.toppled]
        self.unfitted = [moved if there(p) else p for p in self.unfitted]
        self.fallen = {k: moved if there(p) else p for k, p in self.fallen.items()}
        self.forget_refusals_near(spot)
        self.forget_refusals_near(spot_of(moved))

    def sweep_refused(self, spot: np.ndarray, push: np.ndarray) -> bool:
        """Whether the same sweep (``push``: direction times distance) of the domino at
        ``spot`` was refused with no fewer obstacles than now: nothing near it moved since
        and every domino then standing still stands."""
        standing = set(self.standing)
        return any(
            near(spot, at, SAME_SPOT) and np.allclose(push, then, atol=1e-6) and was <= standing
            for at, then, was in self.unswept
        )

    def remember_why(self, spot: np.ndarray, why: str) -> None:
        """The pile domino at ``spot`` is out of reach for now, because ``why``."""
        self.reasons = [r for r in self.reasons if not near(r[0], spot, SAME_SPOT)]
        self.reasons.append((spot, why))

    def why(self, spot: np.ndarray) -> str:
        """Why the pile domino at ``spot`` is out of reach, as last remembered."""
        return next((w for s, w in reversed(self.reasons) if near(s, spot, SAME_SPOT)), "")


@dataclass
class Job:
    """One run: the cell it runs in, the layout to build, and what is known so far."""

    cell: Cell
    layout: list[DominoPlacement]
    settings: ArmJobSettings
    report: RunReport
    targets: list[Pose]  # each slot's target pose
    releases: list[Pose]  # where each is let go (place_lead ahead)
    state: BuildState = field(default_factory=BuildState)
    # Simulated time since which nothing has moved (the arm at rest after a placement
    # check): the pile cameras' frames from then on are fresh for the next look too.
    still_since: float | None = None
    # Simulated time the fingers let go of the domino just placed (None: not since the
    # arm last started moving): its settling runs on while the arm retreats.
    let_go_at: float | None = None
    # A look at the pile asked for while the arm placed (its answer when called), for the
    # next pick: nothing touches the pile between (any other motion drops it).
    pile_look: Later[Detections] | None = None
    pile_seen_at: float = 0.0  # simulated time of the last look's frames (not_before)
    # The finger opening [m] where the job's last gripper command stopped (None: not
    # commanded yet, e.g. as poured at the start).
    fingers: float | None = None
    # The slot whose turn comes next if the one being built stands (``loop.build``), and
    # its first request sent while the arm placed or after the retreat (``ahead``).
    upcoming: int | None = None
    ahead: PlanAhead | None = None
    pictures: dict[str, np.ndarray] = field(default_factory=dict)  # for the report
    # the simulator's domino standing at each slot before the strike (report only): after
    # it each slot's own, not the nearest, which may be the one before it that fell there
    built_bodies: dict[int, str] = field(default_factory=dict)
    picks_recorded: int = 0  # files in settings.record_picks

    @classmethod
    def new(
        cls, cell: Cell, layout: Sequence[DominoPlacement], name: str, settings: ArmJobSettings
    ) -> Job:
        report = RunReport(
            layout=name,
            dominoes=[DominoOutcome(p.index, target_of(p)) for p in layout],
            pile=settings.pile,
            seed=settings.seed,
        )
        return cls(
            cell,
            list(layout),
            settings,
            report,
            [placement_pose(p) for p in layout],
            [placement_pose(p, settings.place_lead) for p in layout],
        )

    def domino(self, index: int) -> str:
        """How the log names slot ``index``: "domino 3/10"."""
        return f"domino {index + 1}/{len(self.layout)}"

    def in_the_way(self, index: int, lying: Pose) -> bool:
        """A domino lying at ``lying`` is in the way of slot ``index``'s domino and the
        pads beside it (``geometry.in_the_way``, settings clear_margin and clear_pads)."""
        settings = self.settings
        along = settings.clear_margin + abs(settings.place_lead)  # let go that far ahead
        across = settings.clear_margin + settings.clear_pads
        return in_the_way(lying, self.targets[index], along, across)

"""What happened in an arm run, as JSON and a top-down picture (no ROS).

The report separates what the robot *believed* (perception's placement checks, which
drove its decisions) from the simulator's ground truth (recorded for the report only).
"""

from __future__ import annotations

import json
import math
from dataclasses import asdict, dataclass, field
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.patches import Polygon

from dombot_bringup.layouts import DOMINO_THICKNESS, DOMINO_WIDTH, DominoPlacement
from dombot_bringup.sections import VERDICTS, exit_status, worst_status

LABEL_GAP = 0.008  # m between a domino's end and its number in the picture
# the report's planned_ahead counts (``task.ahead``): requests sent, by when; answers
PLANNED_AHEAD = ("descent", "look_answered", "after_retreat", "used", "dropped")
TRUTH_TOLERANCE = (3.0, 3.0)  # mm, deg: "standing where intended" in the simulator's truth


@dataclass
class TruthPose:
    """A domino as the simulator saw it: centre, heading of its body z in the plane, tilt."""

    x: float
    y: float
    heading: float  # rad
    tilt_deg: float  # length axis from vertical
    error_mm: float  # horizontal distance from its target


@dataclass
class DominoOutcome:
    index: int
    target: tuple[float, float, float]  # x, y, heading
    placed: bool = False
    attempts: int = 0
    failures: list[str] = field(default_factory=list)
    deferrals: list[str] = field(default_factory=list)  # turns put off: nothing planned
    # the planner's, by error code; those told without asking it: "CODE (foreseen)"
    refusals: dict[str, int] = field(default_factory=dict)
    check: str = ""  # perception's verdict after placing
    measured_error_mm: float | None = None
    measured_tilt_deg: float | None = None
    off_target: bool = False  # upright but beyond the tolerance: left standing, not re-placed
    # Held dominoes found off before the fingers let go, and placed again from where they
    # were held: what perception measured each time.
    corrected_in_hand: list[str] = field(default_factory=list)
    # Held dominoes dropped back on the pile: they could neither stand nor be carried
    # again, or their descent to the place stalled.
    put_back: list[str] = field(default_factory=list)
    # Fallen dominoes no grasp reached, pushed out of this slot's way.
    sweeps: list[str] = field(default_factory=list)
    # Standing neighbours picked up and stood beside the pile to reach what lay in its way.
    set_aside: list[str] = field(default_factory=list)
    # Crowded pile dominoes pushed apart when no pick planned (before ignoring the pile).
    spreads: list[str] = field(default_factory=list)
    # Pile dominoes that planned only ignoring their pile, pushed out of their crowd first.
    isolations: list[str] = field(default_factory=list)
    # Pile dominoes no grasp took as they lay (on edge, upright, out of reach) pushed over
    # or slid so that they lie flat within reach.
    laid_flat: list[str] = field(default_factory=list)
    simulated_s: float = 0.0
    wall_s: float = 0.0
    # ... of it waiting for each kind of answer (motion, planning, perception, gripper,
    # waiting for a domino to settle or a camera period): where the time goes
    simulated_by_activity: dict[str, float] = field(default_factory=dict)
    # Per pick executed: how far the simulator had the nearest domino from the pose
    # perception gave the planner (to tell a misperceived domino from a missed grasp).
    pick_seen_off_mm: list[float | None] = field(default_factory=list)
    truth_built: TruthPose | None = None  # before the strike
    truth_after_strike: TruthPose | None = None


@dataclass
class EmptySlot:
    """A slot given up: the run was built around it."""

    slot: int  # counted from 1, as in the log
    reason: str


@dataclass
class GapDecision:
    """A safety gap as laid out, and where the build left it (``task.gaps``)."""

    slots: list[int]  # counted from 1, as laid out
    verdict: str  # "kept", "moved" or "dropped" (its stretch built in run order)
    now: list[int]  # where it is built last; empty: dropped
    why: str  # the planner's refusal of its last slot between its neighbours, or ""
    plans: int  # planning calls asked to decide


@dataclass
class StretchStart:
    """Where a stretch of consecutive slots (no safety gap) was started (``task.order``):
    built from ``start`` backwards to ``first``, then onwards to ``last``."""

    first: int  # counted from 1, as laid out
    last: int
    start: int  # ``first``: built in run order
    behind: str  # "slot: refusal" of the last slot refused with the one behind standing
    ahead: str  # "slot: refusal" of a slot before it refused with the one ahead standing
    plans: int  # planning calls asked to decide

    def words(self) -> str:
        """The log's words after the start: why there."""
        if not self.behind:
            return " (each slot plans with the one behind standing)"
        if self.ahead:
            return (
                f" (refused with the one behind: {self.behind}; with the one ahead: {self.ahead})"
            )
        return f", built backwards from there (refused with the one behind: {self.behind})"


@dataclass
class PileDomino:
    """A pile domino no grasp or push reached when the last slot found nothing to pick."""

    x: float
    y: float
    posture: str  # as perception saw it: flat, on edge, upright, leaning
    why: str
    truth: str = ""  # the simulator's name for the nearest domino (report only)


@dataclass
class SectionOutcome:
    """Consecutive standing dominoes struck from their own first (see ``sections``)."""

    first_slot: int  # counted from 1, as in the log
    last_slot: int
    struck: bool = False
    toppled_by_perception: int = 0  # of its dominoes, seen down after every strike
    message: str = ""  # why it was not struck
    round: int = 1  # 2, 3, ...: struck again, what the strikes before left standing


@dataclass
class CycleOutcome:
    """One cycle of ``--cycles``: a layout built (from the pile and what the cycle before
    toppled) and knocked down."""

    cycle: int  # counted from 1
    layout: str
    dominoes: int
    placed: int
    placed_first_attempt: int
    # dominoes the cycle before left lying where perception could fit them, and of them
    # how many were picked up (into the run, or tried and put back on the pile)
    toppled_found: int
    toppled_picked: int
    empty_slots: list[int]  # counted from 1
    toppled_by_perception: int  # dominoes seen down after the strike
    toppled_by_truth: bool | None
    exit_status: int
    simulated_s: float
    wall_s: float
    rss_mb: dict[str, float]  # resident memory of each process at the cycle's end


@dataclass
class RunReport:
    layout: str
    dominoes: list[DominoOutcome]
    pile: int
    seed: int
    built: bool = False  # every slot filled
    empty_slots: list[EmptySlot] = field(default_factory=list)  # given up, built around
    # the safety gaps the planner was asked about before the build: kept, moved, dropped
    safety_gaps: list[GapDecision] = field(default_factory=list)
    # where the stretches the planner was asked about before the build were started
    build_order: list[StretchStart] = field(default_factory=list)
    sections: list[SectionOutcome] = field(default_factory=list)  # in run order
    struck: bool = False  # every section
    toppled_by_perception: bool = False
    toppled_by_truth: bool | None = None
    standing_by_truth: int | None = None
    message: str = ""
    simulated_s: float = 0.0
    wall_s: float = 0.0
    node_restarts: dict[str, int] = field(default_factory=dict)  # nodes started again
    # first requests of a turn asked for before the last placement was checked (``ahead``):
    # how many went out as the descent to the slot started, the moment the pile look
    # answered while the arm placed and retreated, and after the retreat, how many answers
    # served their turn and how many were dropped (another request came, the arm stood
    # elsewhere)
    planned_ahead: dict[str, int] = field(default_factory=lambda: dict.fromkeys(PLANNED_AHEAD, 0))
    # the pile dominoes out of every grasp's and push's reach when a slot last found
    # nothing to pick (empty once a later pick planned)
    pile_out_of_reach: list[PileDomino] = field(default_factory=list)
    # what else the run wrote into the report folder (file names in it): camera pictures
    # before and after the strike, the recording, Meshcat's scene
    files: dict[str, str] = field(default_factory=dict)
    # --cycles: every cycle so far, this run the last (its exit status the worst of them)
    cycles: list[CycleOutcome] = field(default_factory=list)

    @property
    def success(self) -> bool:
        return self.built and self.toppled_by_perception and self.toppled_by_truth is not False

    @property
    def own_exit_status(self) -> int:
        """This run's exit status alone (``sections.exit_status``): 0, 3 partial, or 1."""
        return exit_status(
            len(self.empty_slots),
            len(self.sections),
            sum(s.struck for s in self.sections),
            self.toppled_by_perception,
            self.toppled_by_truth,
        )

    @property
    def exit_status(self) -> int:
        """The arm job's exit status: this run's, or with cycles, the worst of theirs
        (``sections.worst_status``)."""
        return worst_status([self.own_exit_status, *(c.exit_status for c in self.cycles)])

    def summary(self) -> dict:
        placed = [d for d in self.dominoes if d.placed]
        first_try = [d for d in placed if d.attempts == 1 and not d.off_target]
        per_domino = [d.simulated_s for d in placed]
        return {
            "success": self.success,
            "exit_status": self.exit_status,
            "dominoes": len(self.dominoes),
            "placed": len(placed),
            "placed_first_attempt": len(first_try),  # within the tolerance
            "placed_off_target": sum(d.off_target for d in placed),
            "within_tolerance_by_truth": sum(map(_within_tolerance, self.dominoes)),
            "retries": sum(max(d.attempts - 1, 0) for d in self.dominoes),
            "corrected_in_hand": sum(len(d.corrected_in_hand) for d in self.dominoes),
            "put_back_on_pile": sum(len(d.put_back) for d in self.dominoes),
            "debris_swept": sum(len(d.sweeps) for d in self.dominoes),
            "set_aside": sum(len(d.set_aside) for d in self.dominoes),
            "pile_spread": sum(len(d.spreads) for d in self.dominoes),
            "pile_isolated": sum(len(d.isolations) for d in self.dominoes),
            "pile_laid_flat": sum(len(d.laid_flat) for d in self.dominoes),
            "pile_out_of_reach": len(self.pile_out_of_reach),
            **{f"planned_ahead_{k}": n for k, n in self.planned_ahead.items()},
            "empty_slots": [e.slot for e in self.empty_slots],
            **{
                f"gaps_{verdict}": sum(g.verdict == verdict for g in self.safety_gaps)
                for verdict in ("kept", "moved", "dropped")
            },
            "gap_plans": sum(g.plans for g in self.safety_gaps),
            "stretches_started_later": [s.start for s in self.build_order if s.start != s.first],
            "order_plans": sum(s.plans for s in self.build_order),
            "sections_struck": sum(s.struck for s in self.sections),
            "sections": len(self.sections),
            "standing_before_strike_by_truth": self.standing_by_truth,
            "toppled_by_perception": self.toppled_by_perception,
            "toppled_by_truth": self.toppled_by_truth,
            "simulated_s_per_domino_mean": float(np.mean(per_domino)) if per_domino else None,
            "wall_s_per_domino_mean": (
                float(np.mean([d.wall_s for d in placed])) if placed else None
            ),
            "simulated_s_per_domino_by_activity": _by_activity(placed),
            "simulated_s": self.simulated_s,
            "wall_s": self.wall_s,
        }


def _by_activity(placed: list[DominoOutcome]) -> dict[str, float]:
    """Mean simulated seconds per placed domino by activity; "other": the rest (between
    answers: the bring-up's own work and the messages' way)."""
    if not placed:
        return {}
    totals: dict[str, float] = {}
    for outcome in placed:
        for activity, seconds in outcome.simulated_by_activity.items():
            totals[activity] = totals.get(activity, 0.0) + seconds
    totals["other"] = sum(d.simulated_s for d in placed) - sum(totals.values())
    return {activity: round(seconds / len(placed), 2) for activity, seconds in totals.items()}


def _within_tolerance(outcome: DominoOutcome) -> bool:
    """Where the simulator had it before the strike: within TRUTH_TOLERANCE of its target
    (perception's check, which the robot acts on, read 0.5 mm more on average, sd 0.3 mm)."""
    built, (millimetres, degrees) = outcome.truth_built, TRUTH_TOLERANCE
    return built is not None and built.error_mm <= millimetres and built.tilt_deg <= degrees


def write_report(
    report: RunReport, folder: Path, pictures: dict[str, np.ndarray] | None = None
) -> tuple[Path, Path]:
    """run_report.json and run.png; each of ``pictures`` (RGB arrays) as NAME.png."""
    folder.mkdir(parents=True, exist_ok=True)
    for name, rgb in (pictures or {}).items():
        plt.imsave(folder / f"{name}.png", rgb)
        report.files[name] = f"{name}.png"
    json_path, png_path = folder / "run_report.json", folder / "run.png"
    content = {"summary": report.summary(), **asdict(report)}
    json_path.write_text(json.dumps(content, indent=2, allow_nan=False, default=str))
    plot_run(report, png_path)
    return json_path, png_path


def _footprint(x: float, y: float, heading: float) -> np.ndarray:
    along = np.array([math.cos(heading), math.sin(heading)]) * DOMINO_THICKNESS / 2
    across = np.array([-math.sin(heading), math.cos(heading)]) * DOMINO_WIDTH / 2
    centre = np.array([x, y])
    return np.array(
        [
            centre + along + across,
            centre + along - across,
            centre - along - across,
            centre - along + across,
        ]
    )


def plot_run(report: RunReport, path: Path) -> Path:
    """Top-down: target outlines, where each domino stood (truth), where it lay after the
    strike. Without the truth (the simulator died), placed ones are drawn at their targets
    as perception's check counted them."""
    figure, axes = plt.subplots(figsize=(8, 7))
    unseen_by_truth = False
    empty = {e.slot - 1 for e in report.empty_slots}
    for domino in report.dominoes:
        x, y, heading = domino.target
        outline = ("tab:red", "--") if domino.index in empty else ("0.4", "-")
        axes.add_patch(
            Polygon(
                _footprint(x, y, heading), fill=False, edgecolor=outline[0], ls=outline[1], lw=1
            )
        )
        beside = DOMINO_WIDTH / 2 + LABEL_GAP  # on the run's left, not on the next domino
        axes.annotate(
            str(domino.index + 1),  # counted from 1, as in the log
            (x - beside * math.sin(heading), y + beside * math.cos(heading)),
            ha="center",
            va="center",
            fontsize=7,
            color="0.3",
        )
        built = domino.truth_built
        if built is not None:
            colour = "tab:green" if built.tilt_deg < 10 else "tab:orange"
            axes.add_patch(
                Polygon(_footprint(built.x, built.y, built.heading), color=colour, alpha=0.7)
            )
        elif domino.placed:
            unseen_by_truth = True
            axes.add_patch(Polygon(_footprint(x, y, heading), color="tab:blue", alpha=0.5))
        fallen = domino.truth_after_strike
        if fallen is not None and fallen.tilt_deg > 45:
            axes.plot(fallen.x, fallen.y, "x", color="tab:red", ms=6)
    axes.plot([], [], "s", mfc="none", mec="0.4", label="target")
    if empty:
        axes.plot([], [], "s", mfc="none", mec="tab:red", label="empty slot (given up)")
    axes.plot([], [], "s", color="tab:green", label="standing after the build (truth)")
    axes.plot([], [], "s", color="tab:orange", label="placed but not upright (truth)")
    axes.plot([], [], "x", color="tab:red", label="fallen after the strike (truth)")
    if unseen_by_truth:
        axes.plot([], [], "s", color="tab:blue", label="placed, by perception (no truth)")
    axes.set_aspect("equal")
    axes.autoscale_view()
    axes.margins(0.15)
    axes.set_xlabel("x [m] (world)")
    axes.set_ylabel("y [m] (world)")
    summary = report.summary()
    verdict = VERDICTS[report.exit_status]
    axes.set_title(
        f"{report.layout}: {summary['placed']}/{summary['dominoes']} placed "
        f"({summary['placed_first_attempt']} first try), toppled: "
        f"{report.toppled_by_truth} — {verdict}"
    )
    axes.legend(loc="upper left", bbox_to_anchor=(1.02, 1.0), fontsize=8)  # off the run
    axes.grid(alpha=0.3)
    figure.tight_layout()
    figure.savefig(path, dpi=120, bbox_inches="tight")  # the legend beside the axes too
    plt.close(figure)
    return path


def target_of(placement: DominoPlacement) -> tuple[float, float, float]:
    return (placement.x, placement.y, placement.heading)

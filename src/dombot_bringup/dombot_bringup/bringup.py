"""bringup: the DOM-BOT main job, started with ``ros2 run dombot_bringup bringup``.

Starts the nodes a job needs as separate processes (like a launch file), drives them
over ROS, and writes a report. Jobs:

* ``arm`` (default) — the simulated iiwa builds a domino run from a seeded pile and
  knocks it down (sim_node, perception_node, planner_node). Layouts: line, arc,
  circle, spiral, s-curve, or a CSV of x,y points; validated before anything moves.
* ``layer`` — the domino-laying vehicle lays an arc in simulation (layer_node +
  vehicle_sim_node); the settled dominoes are checked against the requested radius.

Examples::

    bringup                                    # 10 dominoes on an arc about the arm base
    bringup --layout line --start 0.45 0.0 --heading 90 --count 8
    bringup --layout s-curve --start 0.45 -0.05 --heading 80 --length 0.45 --amplitude 0.05
    bringup --layout csv --csv my_run.csv --visual
    bringup --layout line --start 0.5 0.1 --count 3 --pile 8 --cycles 3   # build, topple, again
    bringup --count 4 --cycles 2 --next-layout 'line --start 0.5 0.1'      # then a line of 4
    bringup --job layer --radius 0.5 --sweep 270

Exit status: 0 the run was built and knocked down; 3 partial: slots that could not be
filled were left empty (report: ``empty_slots`` and why), the rest was built and knocked
down section by section, every domino seen down; 1 otherwise (nothing stood, a strike
failed or left dominoes standing, a node died); with ``--cycles``, the worst of the
cycles'; 2 layout or options refused; 130 Ctrl-C or SIGTERM (the nodes stopped first).
"""

from __future__ import annotations

import argparse
import copy
import math
import os
import shlex
import sys
from collections.abc import Mapping
from pathlib import Path
from typing import NoReturn

from ament_index_python.packages import PackageNotFoundError, get_package_prefix

from dombot_bringup import layouts
from dombot_bringup.arm_job import run_arm_job
from dombot_bringup.layer_job import PathRejectedError, run_layer_job
from dombot_bringup.pad_room import crowded_slots, crowded_words
from dombot_bringup.process_group import NodeDiedError, say
from dombot_bringup.recording import FOXGLOVE_MISSING, foxglove_available
from dombot_bringup.sections import EXIT_REFUSED
from dombot_bringup.task.cell import CellError
from dombot_bringup.task.settings import ArmJobSettings
from dombot_description.scenario import ScenarioError, load_scenario

MAX_CYCLES = 50  # --cycles: each takes minutes; more is a typo
# the highest ROS_DOMAIN_ID with valid Fast DDS ports (ROS 2 docs, "The ROS_DOMAIN_ID")
MAX_DOMAIN_ID = 232


def node_command(package: str, executable: str, parameters: dict) -> list[str]:
    """argv for an installed node with parameters, found through the ament index like ros2 run."""
    path = Path(get_package_prefix(package)) / "lib" / package / executable
    if not path.is_file():
        raise FileNotFoundError(f"no executable '{executable}' in package '{package}' ({path})")
    overrides = [arg for name, value in parameters.items() for arg in ("-p", f"{name}:={value}")]
    return [str(path), "--ros-args", *overrides]


LAYOUTS = ("line", "arc", "circle", "spiral", "s-curve", "csv")


def add_layout_options(group: argparse._ArgumentGroup | argparse.ArgumentParser) -> None:
    """The options that shape a layout: the first one's and ``--next-layout``'s."""
    group.add_argument(
        "--count",
        type=int,
        default=10,
        help="dominoes in the run (default 10; circle: not used, as many as fit around its "
        "--radius at --spacing)",
    )
    group.add_argument("--spacing", type=float, help="centre spacing [m] (default 60%% of height)")
    group.add_argument("--start", type=float, nargs=2, default=(0.45, 0.0), metavar=("X", "Y"))
    group.add_argument("--heading", type=float, default=90.0, help="line/s-curve heading [deg]")
    group.add_argument(
        "--center",
        type=float,
        nargs=2,
        metavar=("X", "Y"),
        help="arc/circle/spiral centre [m] (arc: the arm base 0 0; circle, spiral: the middle "
        "of the build area)",
    )
    group.add_argument(
        "--radius", type=float, help="arc/circle radius [m] (arc 0.6; circle 0.1; layer 0.5)"
    )
    group.add_argument("--start-angle", type=float, default=5.0, help="arc start [deg] (5)")
    group.add_argument("--inner-radius", type=float, default=0.08, help="spiral [m]")
    group.add_argument("--pitch", type=float, default=0.06, help="spiral [m per turn]")
    group.add_argument("--length", type=float, default=0.45, help="s-curve length [m]")
    group.add_argument("--amplitude", type=float, default=0.05, help="s-curve amplitude [m]")
    group.add_argument("--csv", type=Path, help="x,y points in metres (world frame)")


class NextLayoutParser(argparse.ArgumentParser):
    """``--next-layout``'s words: a layout name and its options; a mistake is a LayoutError
    (exit 2 with the option named), not argparse's exit."""

    def __init__(self) -> None:
        super().__init__(prog="--next-layout", add_help=False)
        self.add_argument("layout", choices=LAYOUTS)
        add_layout_options(self)

    def error(self, message: str) -> NoReturn:
        raise layouts.LayoutError(f"--next-layout: {message}")


def next_layout_args(args: argparse.Namespace) -> argparse.Namespace:
    """The layout options of the cycles after the first: ``--next-layout``'s, the first
    layout's where it gives none."""
    words = shlex.split(args.next_layout or "")
    if not words:
        raise layouts.LayoutError("--next-layout needs a layout name, e.g. 'line --count 3'")
    return NextLayoutParser().parse_args(words, namespace=copy.copy(args))


def parse_args(argv: list[str]) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="bringup", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument("--job", choices=["arm", "layer"], default="arm")
    parser.add_argument("--out", type=Path, default=Path("out"), help="report folder (out/)")
    run = parser.add_argument_group("arm job: the run")
    run.add_argument("--layout", choices=LAYOUTS, default="arc")
    add_layout_options(run)
    run.add_argument(
        "--cycles",
        type=int,
        default=1,
        help="build the layout, knock it down, then build the next from the toppled "
        "dominoes and what is left of the pile, this many times in all (1; 1..50)",
    )
    run.add_argument(
        "--next-layout",
        metavar="'LAYOUT [OPTIONS]'",
        help="with --cycles: the layout of the cycles after the first, in one quoted "
        "argument, e.g. 'line --start 0.5 0.1 --count 3' or 'csv --csv next.csv'; options "
        "not given are the first layout's (default: the first layout again)",
    )
    run.add_argument(
        "--section",
        type=int,
        default=4,
        help="dominoes between safety gaps, filled once the rest stands (4; 0: none)",
    )
    run.add_argument(
        "--gaps-as-laid-out",
        action="store_true",
        help="keep every safety gap where --section puts it (default: the planner is asked "
        "first whether each can be filled between its neighbours; moved or dropped if not)",
    )
    run.add_argument(
        "--run-order",
        action="store_true",
        help="build every stretch between safety gaps from its first slot (default: where "
        "neighbours stand closer than 27 mm, the planner is asked first which slot each "
        "stretch must start from, built backwards from there, then onwards)",
    )
    run.add_argument(
        "--keep-off-target",
        type=float,
        default=6.0,
        help="[mm] an upright domino this far off its target (beyond the 3 mm tolerance) "
        "is left standing, not picked up from within the run again (6; 0: re-pick)",
    )
    run.add_argument(
        "--keep-when-stuck",
        type=float,
        default=12.0,
        help="[mm] ... and this far off once picking it up again failed: it would block its "
        "own slot (12; 0..20)",
    )
    run.add_argument(
        "--place-lead",
        type=float,
        default=0.75,
        help="[mm] release each domino this far ahead of its target along the run: released "
        "dominoes end up 0.75 mm behind on average (0.75; 0..3)",
    )
    run.add_argument(
        "--in-hand-tolerance",
        type=float,
        default=2.0,
        help="[mm] straight above its slot, a held domino whose foot is this far off (or "
        "leaning 1.5°) is carried again from where it is held (2; 0: no check)",
    )
    run.add_argument(
        "--pile-core-shrink",
        type=float,
        default=4.5,
        help="[mm] when no pick plans with its pile, plan again keeping the pads 1.5 mm from "
        "the pile's dominoes shrunk this much a side (4.5: they may push one ~3 mm; 0..12)",
    )
    run.add_argument(
        "--spreads",
        type=int,
        default=2,
        help="when no pick plans even with the pile's cores, push a crowded domino apart "
        "(through its neighbours when the pile is jammed) "
        "and look again, up to this often a slot, before ignoring the pile (2; 0..5)",
    )
    run.add_argument(
        "--record-picks",
        action="store_true",
        help="write each pick's offer, plan and the simulator's truth to OUT/picks/ "
        "(replay one: benchmarks/replay_pick.py)",
    )
    cell = parser.add_argument_group("arm job: the cell")
    cell.add_argument("--pile", type=int, default=30, help="dominoes poured (default 30)")
    cell.add_argument("--seed", type=int, default=0, help="pile seed (default 0)")
    cell.add_argument("--real-time-factor", type=float, default=1.0, help="0: as fast as possible")
    cell.add_argument(
        "--plan-budget",
        type=float,
        default=5.0,
        help="[s] of the planning thread's CPU time per planner request, after which it is "
        "TIMEOUT and the job offers another domino (5; up to 3600); CPU, not wall: a load on "
        "the machine does not change the answers",
    )
    cell.add_argument(
        "--no-plan-ahead",
        dest="plan_ahead",
        action="store_false",
        help="ask for each pick only once the last placement is checked (default: the "
        "planner plans it while the arm retreats and perception checks)",
    )
    cell.add_argument(
        "--no-foresee-refusals",
        dest="foresee_refusals",
        action="store_false",
        help="ask the planner for every offered pick (default: a pick whose every grasp "
        "the planner refuses before any IK, its pads in the pile or its wrist beyond "
        "the elbow's reach, is taken as refused without asking)",
    )
    cell.add_argument(
        "--visual",
        action="store_true",
        help="show the cell in Meshcat (URL in the log); on a terminal the page stays up "
        "at the end until Enter",
    )
    view = parser.add_argument_group("arm job: recording and live view")
    view.add_argument(
        "--record",
        action="store_true",
        help="write every topic to OUT/run.mcap (Foxglove, replay) and Meshcat's "
        "recording to OUT/scene.html",
    )
    view.add_argument(
        "--record-image-rate",
        type=float,
        default=1.0,
        help="[Hz] raw camera images kept per topic in run.mcap (1; 0: none; the rest in full)",
    )
    view.add_argument(
        "--foxglove",
        type=int,
        nargs="?",
        const=8765,
        metavar="PORT",
        help="serve every topic live to the Foxglove app at ws://127.0.0.1:PORT (8765; "
        "needs pip install foxglove-sdk)",
    )
    layer = parser.add_argument_group("layer job")
    layer.add_argument("--sweep", type=float, default=270.0, help="arc angle [deg] (270)")
    layer.add_argument("--speed", type=float, default=0.2, help="vehicle speed [m/s] (0.2)")
    layer.add_argument("--layer-spacing", type=float, default=0.03, help="[m] (0.03)")
    return parser.parse_args(argv)


def make_layout(args: argparse.Namespace, area: layouts.BuildArea) -> list[layouts.DominoPlacement]:
    """The run the options describe; each shape's defaults fit inside ``area``."""
    heading = math.radians(args.heading)
    if args.layout == "line":
        return layouts.line(tuple(args.start), heading, args.count, args.spacing)
    if args.layout == "arc":
        radius = 0.6 if args.radius is None else args.radius
        start = math.radians(args.start_angle)
        center = area.base_xy if args.center is None else tuple(args.center)
        return layouts.arc(center, radius, start, args.count, args.spacing)
    center = area.middle if args.center is None else tuple(args.center)
    if args.layout == "circle":
        return layouts.circle(center, circle_radius(args), args.spacing)
    if args.layout == "spiral":
        return layouts.spiral(center, args.inner_radius, args.pitch, args.count, args.spacing)
    if args.layout == "s-curve":
        return layouts.s_curve(
            tuple(args.start), heading, args.length, args.amplitude, args.count, args.spacing
        )
    if args.csv is None:
        raise layouts.LayoutError("--layout csv needs --csv PATH")
    return layouts.from_csv(args.csv, args.count, args.spacing)


def circle_radius(args: argparse.Namespace) -> float:
    """A circle's radius [m]: ``--radius``, or 0.1 m."""
    return 0.1 if args.radius is None else args.radius


def say_circle_count(args: argparse.Namespace, placements: list[layouts.DominoPlacement]) -> None:
    """For a circle, the log's line of ``circle_count`` (not ``make_layout``'s: benchmarks
    that print JSON build layouts with it too)."""
    if args.layout == "circle":
        say(circle_count(circle_radius(args), args.spacing, len(placements), args.count))


def circle_count(radius: float, spacing: float | None, count: int, asked: int) -> str:
    """The line that says how many dominoes a circle of ``radius`` takes (``count``) and
    why, and that ``--count`` (``asked``) does not set it when it differs."""
    line = (
        f"circle: {count} dominoes, as many as fit around its radius of {radius:.3f} m at a "
        f"spacing of {layouts.resolve_spacing(spacing) * 1e3:.1f} mm, one gap left for the strike"
    )
    if asked != count:
        line += f"; --count {asked} is not used (a circle's count follows --radius and --spacing)"
    return line


def cycle_layouts(
    args: argparse.Namespace, area: layouts.BuildArea
) -> list[tuple[str, list[layouts.DominoPlacement]]]:
    """Each cycle's layout (name, placements), every one validated: the first, then
    ``--next-layout``'s (or the first again) for the ``--cycles`` after it."""
    if not 1 <= args.cycles <= MAX_CYCLES:
        raise layouts.LayoutError(f"--cycles must be 1..{MAX_CYCLES}: {args.cycles}")
    if args.next_layout is not None and args.cycles < 2:
        raise layouts.LayoutError("--next-layout is built from the second cycle on: --cycles 2+")
    first = (args.layout, make_layout(args, area))
    say_circle_count(args, first[1])
    following = first
    if args.next_layout is not None:
        after = next_layout_args(args)
        following = (after.layout, make_layout(after, area))
        say_circle_count(after, following[1])
    chosen = [first] + [following] * (args.cycles - 1)
    distinct = chosen[:2] if following is not first else chosen[:1]  # each checked once
    for number, (name, placements) in enumerate(distinct, 1):
        where = f"cycle {number} ('{name}'): " if following is not first else ""
        try:
            layouts.validate(placements, area)
        except layouts.LayoutError as error:
            raise layouts.LayoutError(f"{where}{error}") from None
        for line in crowded_words(crowded_slots(placements)):
            say(f"{where}layout: {line}")
        if args.pile < len(placements):
            raise layouts.LayoutError(
                f"{where}a run of {len(placements)} needs at least as many dominoes in the "
                f"pile (--pile {args.pile})"
            )
    return chosen


def run_arm(args: argparse.Namespace) -> int:
    scenario = load_scenario()
    area = layouts.BuildArea(*scenario.build_x, *scenario.build_y, *scenario.build_reach)
    chosen = cycle_layouts(args, area)
    if not 1 <= args.pile <= 200:
        raise layouts.LayoutError(f"--pile must be 1..200, got {args.pile}")
    if args.section < 0:
        raise layouts.LayoutError(f"--section must be 0 (no safety gaps) or more: {args.section}")
    if not 0.0 <= args.keep_off_target <= 20.0:  # beyond ~20 mm the next may not topple
        raise layouts.LayoutError(f"--keep-off-target must be 0..20 mm: {args.keep_off_target}")
    if not 0.0 <= args.keep_when_stuck <= 20.0:
        raise layouts.LayoutError(f"--keep-when-stuck must be 0..20 mm: {args.keep_when_stuck}")
    if not 0.0 <= args.place_lead <= 3.0:  # the placement tolerance is 3 mm
        raise layouts.LayoutError(f"--place-lead must be 0..3 mm: {args.place_lead}")
    if not 0.0 <= args.in_hand_tolerance <= 3.0:  # beyond 3 mm the placement has failed
        raise layouts.LayoutError(f"--in-hand-tolerance must be 0..3 mm: {args.in_hand_tolerance}")
    if not 0.0 <= args.pile_core_shrink <= 12.0:  # 12 mm a side leaves a line of a domino
        raise layouts.LayoutError(f"--pile-core-shrink must be 0..12 mm: {args.pile_core_shrink}")
    if not 0 <= args.spreads <= 5:
        raise layouts.LayoutError(f"--spreads must be 0..5: {args.spreads}")
    if not 0.0 < args.plan_budget <= 3600.0:
        raise layouts.LayoutError(f"--plan-budget must be 0..3600 s, not 0: {args.plan_budget}")
    if not 0.0 <= args.record_image_rate <= 100.0:
        raise layouts.LayoutError(
            f"--record-image-rate must be 0..100 Hz: {args.record_image_rate}"
        )
    settings = ArmJobSettings(
        pile=args.pile,
        seed=args.seed,
        section=args.section,
        gap_probe_dominoes=0 if args.gaps_as_laid_out else ArmJobSettings.gap_probe_dominoes,
        order_probe_dominoes=0 if args.run_order else ArmJobSettings.order_probe_dominoes,
        keep_off_target=args.keep_off_target * 1e-3,
        keep_when_stuck=args.keep_when_stuck * 1e-3,
        place_lead=args.place_lead * 1e-3,
        in_hand_tolerance=args.in_hand_tolerance * 1e-3,
        pile_core_shrink=args.pile_core_shrink * 1e-3,
        max_spreads=args.spreads,
        pile_center=tuple(scenario.pile_center),
        real_time_factor=args.real_time_factor,
        plan_budget=args.plan_budget,
        plan_ahead=args.plan_ahead,
        foresee_refusals=args.foresee_refusals,
        meshcat=args.visual,
        record=args.record,
        record_image_rate=args.record_image_rate,
        foxglove_port=args.foxglove,
        record_picks=args.out / "picks" if args.record_picks else None,
    )
    return run_arm_job(args.out, chosen, settings, node_command)


def run_layer(args: argparse.Namespace) -> int:
    radius = 0.5 if args.radius is None else args.radius
    for name, value in (
        ("radius", radius),
        ("sweep", args.sweep),
        ("layer-spacing", args.layer_spacing),
        ("speed", args.speed),
    ):
        if not value > 0:
            raise layouts.LayoutError(f"--{name} must be positive")
    return run_layer_job(args.out, radius, args.sweep, args.layer_spacing, args.speed, node_command)


def domain_problem(environ: Mapping[str, str]) -> str | None:
    """Why ``environ``'s ROS_DOMAIN_ID cannot work, or None. Each node would fail to open
    its Fast DDS ports on its own ("Calculated port number is too high"), and the job
    would wait for nodes that never answer."""
    value = environ.get("ROS_DOMAIN_ID", "").strip()
    if not value or (value.isdigit() and int(value) <= MAX_DOMAIN_ID):
        return None
    return (
        f"ROS_DOMAIN_ID={value!r} cannot work: a domain is a whole number 0-{MAX_DOMAIN_ID} "
        "(Fast DDS's ports for a higher one lie beyond 65535)"
    )


def main(argv: list[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    if args.foxglove is not None and not foxglove_available():
        print(f"bringup: {FOXGLOVE_MISSING}", file=sys.stderr)
        return EXIT_REFUSED
    problem = domain_problem(os.environ)
    if problem:
        print(f"bringup: {problem}", file=sys.stderr)
        return EXIT_REFUSED
    try:
        return run_arm(args) if args.job == "arm" else run_layer(args)
    except layouts.LayoutError as error:
        print(f"bringup: layout rejected: {error}", file=sys.stderr)
        return EXIT_REFUSED
    except NodeDiedError as error:
        print(f"bringup: {error}", file=sys.stderr)
    except (
        TimeoutError,
        FileNotFoundError,
        PackageNotFoundError,
        PathRejectedError,
        CellError,
        ScenarioError,
    ) as error:
        print(f"bringup: {error}", file=sys.stderr)
    except KeyboardInterrupt:
        print("bringup: interrupted; nodes stopped", file=sys.stderr)
        return 130
    return 1


if __name__ == "__main__":
    sys.exit(main())

"""bringup: the DOM-BOT main job, started with ``ros2 run dombot_bringup bringup``.

Starts the nodes a job needs as separate processes (like a launch file), drives
them over ROS, and writes a report. Jobs available now:

* ``layer`` — the domino-laying vehicle lays an arc of dominoes in simulation
  (layer_node + vehicle_sim_node); the settled dominoes are checked against the
  requested radius.

The arm job (build a run from a pile with the simulated iiwa and knock it down)
needs sim_node, perception_node and planner_node; it is not available yet.
"""

from __future__ import annotations

import argparse
import sys
from pathlib import Path

from ament_index_python.packages import PackageNotFoundError, get_package_prefix

from dombot_bringup.layer_job import PathRejectedError, run_layer_job
from dombot_bringup.process_group import NodeDiedError


def node_command(package: str, executable: str, parameters: dict[str, float]) -> list[str]:
    """argv for an installed node with parameters, found through the ament index like ros2 run."""
    path = Path(get_package_prefix(package)) / "lib" / package / executable
    if not path.is_file():
        raise FileNotFoundError(f"no executable '{executable}' in package '{package}' ({path})")
    overrides = [arg for name, value in parameters.items() for arg in ("-p", f"{name}:={value}")]
    return [str(path), "--ros-args", *overrides]


def parse_args(argv: list[str] | None) -> argparse.Namespace:
    parser = argparse.ArgumentParser(
        prog="bringup", description=__doc__, formatter_class=argparse.RawDescriptionHelpFormatter
    )
    parser.add_argument(
        "--job", choices=["layer"], default="layer", help="what to run (default: layer)"
    )
    parser.add_argument(
        "--out",
        type=Path,
        default=Path("out"),
        help="folder for the report and plot (default: out/)",
    )
    parser.add_argument(
        "--radius", type=float, default=0.5, help="arc deposit radius [m] (default 0.5)"
    )
    parser.add_argument("--sweep", type=float, default=270.0, help="arc angle [deg] (default 270)")
    parser.add_argument(
        "--spacing", type=float, default=0.03, help="domino spacing [m] (default 0.03)"
    )
    parser.add_argument(
        "--speed", type=float, default=0.2, help="vehicle speed [m/s] (default 0.2)"
    )
    return parser.parse_args(argv)


def main(argv: list[str] | None = None) -> int:
    args = parse_args(sys.argv[1:] if argv is None else argv)
    for name in ("radius", "sweep", "spacing", "speed"):
        if not getattr(args, name) > 0:
            print(f"bringup: --{name} must be positive", file=sys.stderr)
            return 2
    try:
        return run_layer_job(
            args.out, args.radius, args.sweep, args.spacing, args.speed, node_command
        )
    except NodeDiedError as error:
        print(f"bringup: {error}", file=sys.stderr)
    except (TimeoutError, FileNotFoundError, PackageNotFoundError, PathRejectedError) as error:
        print(f"bringup: {error}", file=sys.stderr)
    except KeyboardInterrupt:
        print("bringup: interrupted; nodes stopped", file=sys.stderr)
        return 130
    return 1


if __name__ == "__main__":
    sys.exit(main())

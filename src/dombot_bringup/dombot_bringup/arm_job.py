"""The arm job's wiring: start the nodes, run the task core through a ``CellClient``,
write the report.

Starts ``sim_node``, ``perception_node`` and ``planner_node`` as separate processes;
the task policy itself (the slot loop, picking, placing, clearing, checks, the strike)
is ``dombot_bringup.task``, which knows the cell only as the ``task.cell.Cell``
protocol. The simulator's ground truth goes into the report only.
"""

from __future__ import annotations

import contextlib
import re
import sys
from collections.abc import Callable, Sequence
from pathlib import Path
from typing import TextIO

import numpy as np
import rclpy

from dombot_bringup.cell_client import CellClient
from dombot_bringup.process_group import NodeDiedError, ProcessGroup
from dombot_bringup.run_report import RunReport, write_report
from dombot_bringup.sections import VERDICTS
from dombot_bringup.task.cycles import Layout, run_cycles
from dombot_bringup.task.settings import ArmJobSettings
from dombot_bringup.task.state import Job, log

NodeCommand = Callable[[str, str, dict], list[str]]
RECORDING_FILE, SCENE_FILE = "run.mcap", "scene.html"  # in the report folder, --record
MESHCAT_URL = re.compile(r"Meshcat: (\S+)")  # sim_node's log line
NEEDED_SERVICES = (
    "/sim/reset",
    "/perception/detect",
    "/perception/check_placement",
    "/plan_place",
    "/plan_strike",
)


def restarted(group: ProcessGroup) -> dict[str, int]:
    """The nodes started again during the job, and how often."""
    return {name: count for name, count in group.restarts().items() if count}


def run_arm_job(
    out_dir: Path,
    cycles: Sequence[Layout],
    settings: ArmJobSettings,
    node_command: NodeCommand,
) -> int:
    """Start the nodes, run the job (a cycle per layout of ``cycles``: built and knocked
    down, the first from a freshly poured pile), write the report; the exit status: 0 full
    success, 3 partial (slots left empty, what stood knocked down), 1 failed; the worst of
    the cycles'."""
    sim_parameters = {
        "domino_count": 0,  # the job's reset pours the pile
        "real_time_factor": settings.real_time_factor,
        "camera_rate": settings.camera_rate,
        "meshcat": settings.meshcat or settings.record,
    }
    if settings.record:  # (an empty value is no parameter rule rcl can parse)
        sim_parameters["meshcat_recording_path"] = str((out_dir / SCENE_FILE).resolve())
    meshcat_urls: list[str] = []
    # writing scene.html and closing run.mcap take a few seconds after the stop signal
    with ProcessGroup(stop_timeout=60.0 if settings.record else 5.0) as group:
        recorder = recorder_command(out_dir, settings, node_command)
        if recorder:
            group.start("record", recorder)
        group.start(
            "sim_node",
            node_command("dombot_sim", "sim_node", sim_parameters),
            on_line=lambda line: meshcat_urls.extend(MESHCAT_URL.findall(line)),
        )
        on_sim_time = {"use_sim_time": True}  # frame ages and timers in simulated seconds
        on_demand = on_sim_time | {"continuous": False}  # the job asks; no CPU spent otherwise
        # perception and planner answer from the request and the scene: one that dies is
        # started again and asked again; the simulator's state cannot be restored
        group.start(
            "perception_node",
            node_command("dombot_perception", "perception_node", on_demand),
            restartable=True,
        )
        # a refusal is remembered for the run: on CPU time it is the search's, not the load's
        group.start(
            "planner_node",
            node_command("dombot_planner", "planner_node", on_sim_time | {"budget_clock": "cpu"}),
            restartable=True,
        )
        rclpy.init()
        client = CellClient(watchdog=group.check, restarts=group.restarts)
        started: list[Job] = []  # each cycle's, as it starts
        # written when the nodes stop, whatever happens: named in the report in OUT/
        recording = {"recording": RECORDING_FILE, "meshcat_scene": SCENE_FILE}
        try:
            group.wait_until(lambda: client.ready(NEEDED_SERVICES), 600.0, "the nodes to be ready")
            if settings.meshcat and meshcat_urls:
                log(f"Meshcat: {meshcat_urls[0]}")
            name, layout = cycles[0]
            log(
                f"nodes ready; building '{name}' ({len(layout)} dominoes) "
                f"from a pile of {settings.pile} (seed {settings.seed})"
                + (f", {len(cycles)} cycles" if len(cycles) > 1 else "")
            )
            jobs = run_cycles(client, cycles, settings, group.resident_mb, started.append)
            group.check()
            job = jobs[-1]
            if len(cycles) > 1:  # each cycle's own report and pictures
                for number, done in enumerate(jobs, 1):
                    done.report.node_restarts = restarted(group)
                    write_report(done.report, out_dir / f"cycle{number}", done.pictures)
            job.report.node_restarts = restarted(group)
            if settings.record:
                job.report.files |= recording
            status = finish_report(job.report, out_dir, job.pictures)
            if settings.meshcat and meshcat_urls:
                hold_viewer(meshcat_urls[0])
        except NodeDiedError as error:
            if started:  # what was built so far, for the user to see
                job = started[-1]
                job.report.node_restarts = restarted(group)
                if settings.record:
                    job.report.files |= recording
                job.report.message = (
                    f"stopped: node '{error.name}' died (exit code {error.returncode})"
                )
                json_path, png_path = write_report(job.report, out_dir, job.pictures)
                log(f"{job.report.message}; partial report: {json_path}  picture: {png_path}")
            raise
        finally:
            client.close()
            rclpy.try_shutdown()
    if settings.record:
        log(f"recording: {out_dir / RECORDING_FILE}  Meshcat scene: {out_dir / SCENE_FILE}")
    return status


def recorder_command(out_dir: Path, settings: ArmJobSettings, node_command: NodeCommand):
    """argv of the recorder for --record and --foxglove (empty: neither), on simulated time."""
    options = []
    if settings.record:
        options += ["-o", str(out_dir / RECORDING_FILE)]
        options += ["--image-rate", str(settings.record_image_rate)]
    if settings.foxglove_port is not None:
        options += ["--foxglove-port", str(settings.foxglove_port)]
    if not options:
        return []
    command = node_command("dombot_bringup", "record", {"use_sim_time": True})
    return command[:1] + options + command[1:]


def finish_report(report: RunReport, out_dir: Path, pictures: dict[str, np.ndarray]) -> int:
    """Write the report, print its summary; the exit status (``sections.exit_status``)."""
    json_path, png_path = write_report(report, out_dir, pictures)
    summary = report.summary()
    log(
        f"{summary['placed']}/{summary['dominoes']} placed "
        f"({summary['placed_first_attempt']} on the first attempt, {summary['retries']} retries), "
        f"toppled: perception {summary['toppled_by_perception']}, "
        f"truth {summary['toppled_by_truth']}; "
        f"{report.simulated_s:.0f} s simulated, {report.wall_s:.0f} s wall"
    )
    log(f"report: {json_path}  picture: {png_path}")
    status = report.exit_status
    print(VERDICTS[status], file=sys.stderr if status else sys.stdout, flush=True)
    return status


def hold_viewer(url: str, stdin: TextIO = sys.stdin) -> None:
    """On a terminal, keep the nodes (and Meshcat's page) up until the user presses Enter;
    elsewhere (CI, a pipe) go on at once."""
    if not stdin.isatty():
        return
    log(f"Meshcat stays at {url}; press Enter to stop")
    with contextlib.suppress(EOFError):
        stdin.readline()

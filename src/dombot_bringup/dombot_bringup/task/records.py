"""What a run leaves for people: the report's truth and pictures, each slot's time by
activity, and the pick records ``benchmarks/replay_pick.py`` replays. Nothing acts on
these."""

from __future__ import annotations

import json
import math
from collections.abc import Mapping

import numpy as np

from dombot_bringup.footprints import footprints_meet
from dombot_bringup.layouts import DOMINO_LENGTH
from dombot_bringup.run_report import TruthPose
from dombot_bringup.task.cell import CellError, Plan, Pose, Segment
from dombot_bringup.task.picking import Candidate, pile_points
from dombot_bringup.task.state import Job, log
from dombot_description import domino_corners, tilt_from_vertical

# Past this tilt a domino has fallen, for the truth as for perception (its
# PlacementConfig.max_tilt). One struck onto debris rested at 41° (arc10_cycles5 seed 1,
# cycle 5): seen down, but not down by a 45° line, which made the run a failure.
FALLEN_TILT_DEG = 15.0

REPORT_CAMERA = "camera_2"  # its frames of the run before and after the strike go in the report
Truth = list[tuple[str, Pose]]  # the simulator's dominoes: names and poses
AGAINST = 0.005  # m: a domino whose footprint comes this close to a slot's lies against it


def truth(job: Job, since: float | None = None) -> Truth:
    """The simulator's dominoes now, or as they lay at any time from ``since`` on (nothing
    moved them since: no wait for the next ground-truth message), for the report only."""
    newer_than = job.cell.sim_time if since is None else min(since, job.cell.sim_time)
    return job.cell.truth(newer_than=newer_than - 0.01)


def nearest_truth(dominoes: Truth, pose: Pose) -> tuple[str, float | None]:
    """The simulator's domino whose centre is nearest ``pose``'s, and how far [mm]."""
    if not dominoes:
        return "", None
    centres = np.array([matrix[:3, 3] for _, matrix in dominoes])
    distances = np.linalg.norm(centres - pose[:3, 3], axis=1)
    nearest = int(np.argmin(distances))
    return dominoes[nearest][0], float(distances[nearest] * 1e3)


def at_slot(dominoes: Truth, target: Pose, held: str) -> str:
    """The simulator's dominoes but ``held`` whose footprint comes within AGAINST of the
    footprint of a domino standing at ``target``: name, where and how tilted, for the log
    after a placement there fell or its descent stalled (report only: nothing acts on it)."""
    slot = domino_corners(target)[:, :2]
    found = [
        f"{name} at {np.round(pose[:2, 3], 3).tolist()} tilted "
        f"{math.degrees(tilt_from_vertical(pose)):.0f}°"
        for name, pose in dominoes
        if name != held and footprints_meet(slot, domino_corners(pose)[:, :2], AGAINST)
    ]
    return ", ".join(found) or "nothing"


def take_picture(job: Job, name: str, not_before: float) -> None:
    """REPORT_CAMERA's view for the report (for people; nothing acts on it)."""
    try:
        job.pictures[name] = job.cell.picture(REPORT_CAMERA, not_before)
    except CellError as error:
        log(f"no picture {name} for the report: {error}")


def record_truth(job: Job, before_strike: bool) -> None:
    """Ground truth for the report: before the strike the simulator domino nearest each
    target (``job.built_bodies``); after it, each placed one's own (the nearest only where
    none stood there: a fallen domino lies nearer the next slot than its own)."""
    dominoes = truth(job)
    if not dominoes:
        return
    names = [name for name, _ in dominoes]
    poses = [matrix for _, matrix in dominoes]
    report = job.report
    centres = np.array([p[:2, 3] for p in poses])
    down = 0
    standing = 0
    for index, (outcome, target) in enumerate(zip(report.dominoes, job.layout, strict=True)):
        distances = np.linalg.norm(centres - [target.x, target.y], axis=1)
        nearest = int(np.argmin(distances))
        built = job.built_bodies.get(index)
        if not before_strike and built in names:
            nearest = names.index(built)
        elif distances[nearest] > (0.02 if before_strike else DOMINO_LENGTH):
            continue
        if before_strike:
            job.built_bodies[index] = names[nearest]
        pose = poses[nearest]
        tilt = math.degrees(tilt_from_vertical(pose))
        along = pose[:3, 2]
        record = TruthPose(
            float(pose[0, 3]),
            float(pose[1, 3]),
            math.atan2(along[1], along[0]),
            tilt,
            float(distances[nearest] * 1e3),
        )
        if before_strike:
            outcome.truth_built = record
            standing += tilt < 10.0
        elif outcome.placed:  # an empty slot's nearest is a neighbour's
            outcome.truth_after_strike = record
            down += tilt > FALLEN_TILT_DEG
    if before_strike:
        report.standing_by_truth = standing
    elif report.struck:
        report.toppled_by_truth = down == sum(d.placed for d in report.dominoes)


def pick_record(
    job: Job, index: int, candidate: Candidate, pile: str, plan: Plan, dominoes: Truth
) -> dict | None:
    """What a pick was planned from and the simulator's truth at the time, to replay it
    offline (``settings.record_picks``); None when not recorded."""
    if job.settings.record_picks is None:
        return None
    names, positions = job.cell.joints()
    grasp = candidate.grasp
    return {
        "slot": index + 1,
        "attempt": job.report.dominoes[index].attempts,
        "source": candidate.source,
        "domino_pose": candidate.pose.tolist(),
        "grasp_pose": None if grasp is None else grasp.tolist(),
        "pile": pile,
        "pile_dominoes": [p.tolist() for p in candidate.neighbours],
        "pile_points": pile_points(job, candidate, pile).tolist(),
        "plan": plan.message,
        "place_pose": job.releases[index].tolist(),
        "start": {"names": names, "positions": positions},
        "segments": [segment_record(s) for s in plan.segments],
        "truth": {name: matrix.tolist() for name, matrix in dominoes},
    }


def write_pick_record(job: Job, record: dict | None, failure: str) -> None:
    if record is None:
        return
    folder = job.settings.record_picks
    folder.mkdir(parents=True, exist_ok=True)
    record["failure"] = failure  # "": carried to the slot
    path = folder / f"pick{job.picks_recorded:03d}_slot{record['slot']}.json"
    path.write_text(json.dumps(record))
    job.picks_recorded += 1


def segment_record(segment: Segment) -> dict:
    """A planned segment as plain numbers (times in s from its start)."""
    trajectory = segment.trajectory
    return {
        "label": segment.label,
        "joint_names": list(trajectory.joint_names),
        "times": trajectory.times.tolist(),
        "positions": trajectory.positions.tolist(),
        "velocities": trajectory.velocities.tolist(),
        "gripper_after": int(segment.gripper_after),
        "gripper_position": segment.gripper_position,
        "gripper_max_effort": segment.gripper_max_effort,
    }


def add_spent(
    into: dict[str, float], spent: Mapping[str, float], before: Mapping[str, float]
) -> dict[str, float]:
    """Add to ``into`` the simulated seconds per activity that ``spent`` grew by since
    ``before``; ``spent`` as it is now, to count from next."""
    for activity, seconds in spent.items():
        grown = seconds - before.get(activity, 0.0)
        if grown:
            into[activity] = round(into.get(activity, 0.0) + grown, 3)
    return dict(spent)

"""A standing run domino set aside, upright beside the pile, to reach what lies by it.

A domino lying in a slot's way between standing neighbours (or beside the run's last
standing one) can leave no grasp and no pusher pose clear of them: in arc10_cycles5 a
run domino knocked over by the placing of the next lay between two standing ones, its
grasps refused ("no collision-free IK") and its sweeps too ("the pusher within
coarse_clearance of a standing domino at every one of 12 pusher orientations"), and its
slot was left empty. A builder lifts a neighbour out, clears the slot and puts the
neighbour back: here the neighbour is picked up and placed upright at a free spot
beside the pile (``staging_spot``), where the pile look finds it as a pile domino; its
slot is built again once this one stands (``loop.requeue``: built earlier, no longer
standing).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import replace

import numpy as np

from dombot_bringup.debris import sweep_pushes
from dombot_bringup.footprints import footprints_meet
from dombot_bringup.layouts import DOMINO_LENGTH, DominoPlacement
from dombot_bringup.task.cell import Detection, PlaceRequest, Pose
from dombot_bringup.task.checks import check
from dombot_bringup.task.clearing import foreseen_strike, sweep_margin, sweep_request
from dombot_bringup.task.geometry import near, placement_pose, spot_of
from dombot_bringup.task.picking import in_its_way, look_at_pile
from dombot_bringup.task.placing import execute
from dombot_bringup.task.state import Job, log
from dombot_description import domino_corners

STAGING_ANGLES = 24  # spots tried around the pile, 15° apart
EMPTY = np.zeros((0, 2))
STAGING_PLANS = 2  # spots asked of the planner per neighbour (the nearest the slot first)


def staging_spots(
    center: Sequence[float],
    ring: float,
    toward: Sequence[float],
    seen: Sequence[Pose],
    points: np.ndarray,
    clearance: float,
) -> list[DominoPlacement]:
    """Upright places on the circle of radius ``ring`` about the pile's ``center`` whose
    footprint keeps ``clearance`` from every ``seen`` domino (4×4 poses) and seen point
    (N×2 or N×3; from the footprint's circumscribed circle), nearest ``toward`` (the
    slot: the shortest carry) first; each faces the arm base as an arc about it would
    (its heading square to the base's radius)."""
    points = np.asarray(points, dtype=float).reshape(len(points), -1) if len(points) else EMPTY
    footprints = [domino_corners(pose)[:, :2] for pose in seen]
    spots = []
    for k in range(STAGING_ANGLES):
        angle = 2 * math.pi * k / STAGING_ANGLES
        x, y = center[0] + ring * math.cos(angle), center[1] + ring * math.sin(angle)
        spot = DominoPlacement(-1, x, y, math.atan2(y, x) + math.pi / 2)
        corners = domino_corners(placement_pose(spot))[:, :2]
        if any(footprints_meet(corners, other, clearance) for other in footprints):
            continue
        radius = float(np.linalg.norm(corners - (x, y), axis=1).max())  # the footprint's
        if np.any(np.linalg.norm(points[:, :2] - (x, y), axis=1) < radius + clearance):
            continue
        spots.append(spot)
    return sorted(spots, key=lambda s: math.dist((s.x, s.y), toward))


def blocked_between(job: Job, index: int) -> list[int]:
    """The standing neighbours of slot ``index`` to set aside while a domino lies in its
    way whose every sweep was refused (``unswept``): first one whose setting aside frees
    one of those sweeps (``frees_a_sweep``), then the one after the slot (nearer the
    run's end: fewer dominoes ahead of it). None once the slot had max_set_asides."""
    if len(job.report.dominoes[index].set_aside) >= job.settings.max_set_asides:
        return []
    way = [pose for pose in in_its_way(job, index) if unswept(job, index, pose)]
    neighbours = [n for n in (index + 1, index - 1) if n in job.state.standing]
    if not way:
        return []
    return sorted(neighbours, key=lambda n: not frees_a_sweep(job, index, n, way))


def unswept(job: Job, index: int, pose: Pose) -> bool:
    """Whether every sweep of the domino at ``pose`` out of slot ``index``'s way was
    refused as the run stands now (``BuildState.sweep_refused``), or none is short enough."""
    pushes = sweep_pushes(pose, job.layout[index], sweep_margin(job))
    spot = spot_of(pose)
    return all(job.state.sweep_refused(spot, d * np.asarray(v)[:2]) for v, d in pushes)


def frees_a_sweep(job: Job, index: int, neighbour: int, way: Sequence[Pose]) -> bool:
    """Whether a sweep of one of ``way`` out of slot ``index``'s way that the planner's
    own geometry refuses with ``neighbour`` standing (``clearing.foreseen_strike``: the
    pusher near a standing or lying domino at every pose, or the domino pushed into one)
    is not refused so without it."""
    lying = job.state.lying()
    without = [pose for k, pose in job.state.standing.items() if k != neighbour]
    for pose in way:
        others = [p for p in lying if p is not pose]
        for direction, distance in sweep_pushes(pose, job.layout[index], sweep_margin(job)):
            request = sweep_request(job, pose, others, direction, distance)
            if foreseen_strike(job, request) and not foreseen_strike(
                job, replace(request, standing=(*without, *others))
            ):
                return True
    return False


def aside_request(
    job: Job, neighbour: int, spot: DominoPlacement, detections: Sequence[Detection]
) -> PlaceRequest:
    """The pick of standing ``neighbour`` and its place at ``spot``: the rest of the run
    and the pile (``detections``) kept clear of, and every lying domino but those within
    a domino length of the neighbour. Those go as pile neighbours, which the lifted
    domino may touch at its pick and the pads nudge (docs/PLANNER.md): in arc10_cycles5
    (seed 2, cycle 4) a domino fallen against the neighbour, as an obstacle, had every
    grasp refused with the held domino "in collision at the pose"."""
    standing = job.state.standing[neighbour]
    others = [pose for k, pose in job.state.standing.items() if k != neighbour]
    lying = job.state.lying()

    def beside(pose: Pose) -> bool:
        return near(spot_of(pose), spot_of(standing), DOMINO_LENGTH)

    return PlaceRequest(
        domino=standing,
        place=placement_pose(spot),
        standing=(*others, *(d.pose for d in detections), *(p for p in lying if not beside(p))),
        pile=tuple(p for p in lying if beside(p)),
        time_budget=job.settings.plan_budget,
    )


def set_aside(job: Job, index: int) -> bool:
    """Pick up a standing neighbour of slot ``index`` (``blocked_between``) and stand it
    at a free spot beside the pile (``staging_spots``, the planner asked for at most
    STAGING_PLANS of them); True once the arm moved. The neighbour's slot is then empty,
    to be built again."""
    neighbours = blocked_between(job, index)
    if not neighbours:
        return False
    settings, state = job.settings, job.state
    detections, unexplained = look_at_pile(job)
    seen = [d.pose for d in detections] + state.lying()
    toward = spot_of(job.targets[index])
    spots = staging_spots(
        settings.pile_center,
        settings.staging_ring,
        toward,
        seen,
        unexplained,
        settings.staging_clearance,
    )
    for neighbour in neighbours:
        standing = state.standing[neighbour]
        for spot in spots[:STAGING_PLANS]:
            plan = job.cell.plan_place(aside_request(job, neighbour, spot, detections))
            where = f"[{spot.x:.3f}, {spot.y:.3f}]"
            if not plan.success:
                log(
                    f"{job.domino(index)}: setting domino {neighbour + 1} aside at {where} "
                    f"refused: {plan.message.split(' (')[0]}"
                )
                continue
            execution = execute(job, plan.segments)
            words = f"domino {neighbour + 1} set aside beside the pile at {where}"
            if not execution.done:  # counted too: where it is now, standing, fallen or held
                job.report.dominoes[index].set_aside.append(f"{words}: {execution.why}")
                log(f"{job.domino(index)}: {words}: {execution.why}")
                check(job, neighbour, just_placed=False)
                return True
            state.standing.pop(neighbour)
            state.left_off.discard(neighbour)
            state.set_aside_after[neighbour] = job.report.dominoes[neighbour].attempts
            job.report.dominoes[neighbour].placed = False
            state.forget_refusals_near(spot_of(standing))
            state.forget_refusals_near(np.array([spot.x, spot.y]))
            job.report.dominoes[index].set_aside.append(words)
            log(
                f"{job.domino(index)}: {words} to reach what lies in its way; "
                f"its slot is built again after this one"
            )
            return True
    return False

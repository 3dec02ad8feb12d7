"""Replay recorded /plan_place requests through the planner: CPU time per request by outcome.

The requests are real ones: those the bring-up's task core sent while building runs out
of poured piles (``bench_pile_picks.py --record-requests FILE`` records them through
``RecordingPlanner``), refusals and plans found only by the fallback tiers (the pads
nudging the pile, turning the domino first) included. Each is planned again with a time
budget (``--budget``, default 60 s) that no answer depends on, and timed by the process's
CPU clock. Prints one JSON object on stdout: CPU seconds per outcome class (success
first tier / success nudged / success regrasp / refused by code; count, total, p50,
p95), and a digest of the answers (success, code, stage, segment count per request) to
compare two planners by, and one of the details (refusal messages, the plans' poses and
sampled joint positions); ``--answers FILE`` writes the answers themselves.

In ``./dombot shell``: ``python benchmarks/bench_plan_replay.py [FILE]``; the baseline
planner side by side with ``PYTHONPATH=OTHER/src/dombot_planner:$PYTHONPATH``.
"""

from __future__ import annotations

import argparse
import cProfile
import hashlib
import json
import os
import pstats
import time
from collections import defaultdict
from dataclasses import replace
from pathlib import Path

import numpy as np
from bench_planner import log
from pydrake.math import RigidTransform

import dombot_planner
from dombot_description.scenario import load_scenario
from dombot_planner.errors import PlanningError
from dombot_planner.pick_place_plan import PickPlacePlan
from dombot_planner.planner import PickPlacePlanner
from dombot_planner.request import PickPlaceRequest
from dombot_planner.settings import PlannerSettings

DEFAULT_FILE = Path(__file__).parent / "data" / "plan_requests.npz"
POSE_FIELDS = ("domino_pose", "place_pose")
LIST_FIELDS = {"standing": "poses", "pile": "poses", "pile_points": "points"}
SCALAR_FIELDS = ("grasp_width", "pads_into_pile", "time_budget", "holding")


class RecordingPlanner(PickPlacePlanner):
    """A PickPlacePlanner that keeps every request it is asked to plan when given a
    ``path``, saved there after each one, so a cut-short run keeps what it recorded."""

    def __init__(self, *args, path: Path | None = None, **kwargs) -> None:
        super().__init__(*args, **kwargs)
        self.path = path
        self.requests: list[PickPlaceRequest] = []

    def plan(self, request: PickPlaceRequest) -> PickPlacePlan:
        if self.path:
            self.requests.append(request)
            save_requests(self.path, self.requests)
        return super().plan(request)


def save_requests(path: Path, requests: list[PickPlaceRequest]) -> None:
    """``requests`` into one compressed .npz: per-request arrays, lists concatenated with
    their lengths; pile points rounded to float32 (< 0.1 µm here), which halves the file."""
    arrays: dict[str, np.ndarray] = {
        name: np.array([getattr(r, name).GetAsMatrix4() for r in requests]) for name in POSE_FIELDS
    }
    arrays["start"] = np.array([r.start for r in requests])
    arrays["has_grasp"] = np.array([r.grasp_pose is not None for r in requests])
    arrays["grasp_pose"] = np.array(
        [np.eye(4) if r.grasp_pose is None else r.grasp_pose.GetAsMatrix4() for r in requests]
    )
    for name in SCALAR_FIELDS:
        arrays[name] = np.array([getattr(r, name) for r in requests])
    for name in ("standing", "pile"):
        arrays[f"{name}_count"] = np.array([len(getattr(r, name)) for r in requests])
        arrays[name] = np.array(
            [p.GetAsMatrix4() for r in requests for p in getattr(r, name)]
        ).reshape(-1, 4, 4)
    arrays["pile_points_count"] = np.array([len(r.pile_points) for r in requests])
    points = np.vstack([np.zeros((0, 3))] + [r.pile_points for r in requests])
    arrays["pile_points"] = points.astype(np.float32)
    path.parent.mkdir(parents=True, exist_ok=True)
    np.savez_compressed(path, **arrays)


def load_requests(path: Path) -> list[PickPlaceRequest]:
    """The requests ``save_requests`` wrote."""
    data = np.load(path)
    lists = {}
    for name in ("standing", "pile", "pile_points"):
        ends = np.cumsum(data[f"{name}_count"])
        lists[name] = np.split(data[name], ends[:-1]) if len(ends) else []
    requests = []
    for i in range(len(data["start"])):
        requests.append(
            PickPlaceRequest(
                domino_pose=RigidTransform(data["domino_pose"][i]),
                place_pose=RigidTransform(data["place_pose"][i]),
                start=data["start"][i].copy(),
                grasp_pose=RigidTransform(data["grasp_pose"][i]) if data["has_grasp"][i] else None,
                grasp_width=float(data["grasp_width"][i]),
                standing=tuple(RigidTransform(m) for m in lists["standing"][i]),
                pile=tuple(RigidTransform(m) for m in lists["pile"][i]),
                pile_points=np.asarray(lists["pile_points"][i], dtype=float).reshape(-1, 3),
                pads_into_pile=bool(data["pads_into_pile"][i]),
                time_budget=float(data["time_budget"][i]),
                holding=bool(data["holding"][i]),
            )
        )
    return requests


def outcome(planner: PickPlacePlanner, request: PickPlaceRequest) -> tuple[dict, str, str]:
    """The planner's answer to ``request``, its outcome class and what else it said: the
    error's message, or the plan's poses and sampled joint positions (to 1 nrad)."""
    try:
        plan = planner.plan(request)
    except PlanningError as error:
        answer = {"success": False, "code": error.code.name, "stage": error.stage}
        return answer, f"refused {error.code.name}", error.message
    answer = {"success": True, "code": "SUCCESS", "stage": "", "segments": len(plan.segments)}
    samples = [s.positions for s in plan.sampled(planner.settings.sample_period)]
    poses = [plan.grasp_pose.GetAsMatrix4(), plan.release_pose.GetAsMatrix4(), *samples]
    details = json.dumps([np.round(p, 9).tolist() for p in poses])
    if plan.regrasped:
        return answer, "success regrasp", details
    return answer, "success nudged" if plan.nudged else "success first tier", details


def digest(values: list) -> str:
    return hashlib.sha256(json.dumps(values, sort_keys=True).encode()).hexdigest()[:16]


def percentile(values: list[float], q: float) -> float:
    return round(float(np.percentile(values, q)), 3)


def main() -> None:
    parser = argparse.ArgumentParser(description=__doc__.split("\n")[0])
    parser.add_argument("file", nargs="?", type=Path, default=DEFAULT_FILE)
    parser.add_argument("--budget", type=float, default=60.0, help="time budget per request [s]")
    parser.add_argument("--first", type=int, default=0, help="replay only the first N (0: all)")
    parser.add_argument("--every", type=int, default=1, help="replay every K-th request")
    parser.add_argument("--answers", type=Path, help="write each request's answer (JSON)")
    parser.add_argument("--profile", type=Path, help="write cProfile stats (CPU clock) here")
    parser.add_argument("--merge", type=Path, nargs="+", help="write FILE from these recordings")
    args = parser.parse_args()
    if args.merge:
        save_requests(args.file, [r for path in args.merge for r in load_requests(path)])
        return
    requests = load_requests(args.file)[:: args.every]
    requests = requests[: args.first or None]
    planner = PickPlacePlanner(load_scenario(), PlannerSettings())
    profile = cProfile.Profile(time.process_time) if args.profile else None
    load_before = os.getloadavg()
    answers, details, cpu = [], [], defaultdict(list)
    for index, request in enumerate(requests):
        request = replace(request, time_budget=args.budget)
        began = time.process_time()
        if profile:
            profile.enable()
        answer, kind, said = outcome(planner, request)
        if profile:
            profile.disable()
        spent = time.process_time() - began
        cpu[kind].append(spent)
        answers.append(answer)
        details.append(said)
        log(f"{index}: {kind} {answer.get('stage', '')} {spent:.2f} s CPU")
    if profile:
        pstats.Stats(profile).dump_stats(args.profile)
    if args.answers:
        args.answers.write_text(json.dumps(answers, indent=1))
    print(
        json.dumps(
            {
                "benchmark": "plan_replay",
                "planner": str(Path(dombot_planner.__file__).parent),
                "requests": len(requests),
                "budget_s": args.budget,
                "cpu_s_total": round(sum(map(sum, cpu.values())), 2),
                "cpu_s": {
                    kind: {
                        "count": len(values),
                        "total": round(sum(values), 2),
                        "p50": percentile(values, 50),
                        "p95": percentile(values, 95),
                    }
                    for kind, values in sorted(cpu.items())
                },
                "answers_digest": digest(answers),
                "details_digest": digest(details),
                "plans_digest": digest(
                    [d for a, d in zip(answers, details, strict=True) if a["code"] == "SUCCESS"]
                ),
                "load_average": {"before": load_before, "after": os.getloadavg()},
            },
            indent=2,
        )
    )


if __name__ == "__main__":
    main()

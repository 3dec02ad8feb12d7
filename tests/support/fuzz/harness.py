"""The fuzz harness: what a case and an endpoint are, how requests are sent over DDS
(services, actions), the ``Report`` that judges every reply, the node processes and
the hypothesis loop that sends batches.

``Endpoint`` is one thing to fuzz: how to send a batch of requests (concurrently) and read
an *outcome* from each reply (``replies``). ``Case`` is one request with the outcomes that
are right for it (None: any outcome, as long as there is one with a message). ``Harness``
sends batches, records a ``Report`` (requests, outcome histogram, worst reply latency,
wrong outcomes, crashes, hangs, RSS per node) and checks that a valid request is served
after each batch. An action's reply is a ``GoalReply`` (the goal's final status and
result, or REJECTED), sent by ``action_sender``.
"""

from __future__ import annotations

import math
import time
from collections import Counter
from collections.abc import Callable, Collection, Iterator, Sequence
from contextlib import ExitStack, contextmanager
from dataclasses import dataclass, field
from pathlib import Path
from subprocess import Popen

from action_msgs.msg import GoalStatus
from hypothesis import HealthCheck, Phase, given, seed, settings
from hypothesis import strategies as st
from rclpy.action import ActionClient
from rclpy.node import Node

from support.ros_processes import installed_node, spin_until

# ------------------------------------------------------------------ cases and endpoints


@dataclass(frozen=True)
class Case:
    """One request, what was broken in it, and the outcomes that are right for it."""

    request: object
    what: str
    expect: frozenset[str] | None = None  # None: any outcome with a message


@dataclass
class Endpoint:
    """A service, action or topic under test. ``send(requests, timeout, alive)`` sends
    them at once and gives each reply (None: none within the timeout, or the serving
    process died: ``alive()`` turned false); ``outcome(reply)`` names
    it; ``problem(reply)`` says what is wrong with a reply regardless of the request."""

    name: str
    node: str  # the process serving it (Harness.processes key)
    send: Callable[[list, float, Callable[[], bool]], list]
    outcome: Callable[[object], str]
    valid: Case  # served after every batch
    problem: Callable[[object], str | None] = lambda reply: (
        None if reply.message else "empty message"
    )


def service_sender(node: Node, service_type, name: str) -> Callable:
    client = node.create_client(service_type, name)

    def send(requests: list, timeout: float, alive: Callable[[], bool]) -> list:
        assert spin_until(node, client.service_is_ready, timeout), f"{name} not available"
        futures = [client.call_async(request) for request in requests]
        spin_until(node, lambda: all(f.done() for f in futures) or not alive(), timeout)
        replies = [f.result() if f.done() else None for f in futures]
        for future in futures:
            if not future.done():
                client.remove_pending_request(future)
        return replies

    return send


@dataclass(frozen=True)
class GoalReply:
    """How an action goal ended: its GoalStatus and result (None when rejected)."""

    status: int
    result: object | None


def action_sender(node: Node, action_type, name: str) -> Callable:
    """Sends goals at once; each reply a GoalReply once the goal has ended."""
    client = ActionClient(node, action_type, name)

    def send(goals: list, timeout: float, alive: Callable[[], bool]) -> list:
        assert spin_until(node, client.server_is_ready, timeout), f"{name} not available"
        sent = [client.send_goal_async(goal) for goal in goals]
        results: list = [None] * len(goals)

        def ended() -> bool:
            for i, future in enumerate(sent):
                if results[i] is None and future.done():
                    handle = future.result()
                    results[i] = handle.get_result_async() if handle.accepted else REJECTED
            return all(r is REJECTED or (r is not None and r.done()) for r in results)

        spin_until(node, lambda: ended() or not alive(), timeout)
        return [
            r
            if r is REJECTED
            else (GoalReply(r.result().status, r.result().result) if r and r.done() else None)
            for r in results
        ]

    return send


REJECTED = GoalReply(GoalStatus.STATUS_UNKNOWN, None)  # the goal response said no

# ------------------------------------------------------------------ the harness


def rss_mb(pid: int) -> float:
    for line in Path(f"/proc/{pid}/status").read_text().splitlines():
        if line.startswith("VmRSS:"):
            return int(line.split()[1]) / 1024
    return math.nan


@dataclass
class Report:
    requests: Counter = field(default_factory=Counter)  # per endpoint
    outcomes: dict[str, Counter] = field(default_factory=dict)  # endpoint → outcome → count
    worst_latency: dict[str, float] = field(default_factory=dict)  # s, per endpoint
    wrong: list[str] = field(default_factory=list)  # wrong outcomes and bad replies
    hangs: list[str] = field(default_factory=list)
    crashes: list[str] = field(default_factory=list)
    unserved: list[str] = field(default_factory=list)  # a valid request after a batch failed
    rss_mb: dict[str, dict[str, float]] = field(default_factory=dict)  # node → before/after

    def as_json(self) -> dict:
        return {
            "requests": dict(self.requests),
            "outcomes": {name: dict(counts) for name, counts in self.outcomes.items()},
            "worst_latency_s": {k: round(v, 3) for k, v in self.worst_latency.items()},
            "wrong": self.wrong[:50],
            "wrong_count": len(self.wrong),
            "hangs": self.hangs,
            "crashes": self.crashes,
            "unserved": self.unserved,
            "rss_mb": self.rss_mb,
        }


class Harness:
    """Sends batches of cases to endpoints served by ``processes`` (name → Popen)."""

    def __init__(self, processes: dict[str, Popen], timeout: float) -> None:
        self.processes = processes
        self.timeout = timeout  # s a reply may take (generous: a search ends before its budget)
        self.report = Report()

    def running(self, endpoint: Endpoint) -> Callable[[], bool]:
        process = self.processes[endpoint.node]
        return lambda: process.poll() is None

    def alive(self, endpoint: Endpoint) -> bool:
        process = self.processes[endpoint.node]
        if process.poll() is None:
            return True
        note = f"{endpoint.node} exited with {process.returncode} during {endpoint.name}"
        if note not in self.report.crashes:
            self.report.crashes.append(note)
        return False

    def rss(self, stage: str) -> None:
        for name, process in self.processes.items():
            if process.poll() is None:
                self.report.rss_mb.setdefault(name, {})[stage] = round(rss_mb(process.pid), 1)

    def warm_up(self, endpoint: Endpoint, timeout: float = 300.0) -> None:
        """Send the valid request until it is served (nodes start, cameras begin to
        publish); these requests are not counted."""
        deadline = time.monotonic() + timeout
        while time.monotonic() < deadline and self.alive(endpoint):
            [reply] = endpoint.send([endpoint.valid.request], self.timeout, self.running(endpoint))
            if reply is not None and endpoint.outcome(reply) in endpoint.valid.expect:
                return
            time.sleep(1.0)
        raise AssertionError(f"{endpoint.name}: the valid request was not served in {timeout} s")

    def run(self, endpoint: Endpoint, cases: Sequence[Case]) -> list:
        """Send ``cases`` at once, judge every reply, then check a valid request is served."""
        replies = self._send(endpoint, list(cases))
        self._send(endpoint, [endpoint.valid], after_batch=True)
        return replies

    def _send(self, endpoint: Endpoint, cases: list[Case], after_batch: bool = False) -> list:
        if not self.alive(endpoint):  # counted: a crash ends a long run's loop too
            self.report.requests[endpoint.name] += len(cases)
            return [None] * len(cases)
        began = time.monotonic()
        requests = [case.request for case in cases]
        replies = endpoint.send(requests, self.timeout, self.running(endpoint))
        latency = time.monotonic() - began
        report = self.report
        report.requests[endpoint.name] += len(cases)
        worst = report.worst_latency.get(endpoint.name, 0.0)
        report.worst_latency[endpoint.name] = max(worst, latency)
        outcomes = report.outcomes.setdefault(endpoint.name, Counter())
        for case, reply in zip(cases, replies, strict=True):
            label = f"{endpoint.name} {case.what}"
            if reply is None:
                if self.alive(endpoint):
                    report.hangs.append(f"{label}: no reply within {self.timeout} s")
                outcomes["no reply"] += 1
                continue
            outcome = endpoint.outcome(reply)
            outcomes[outcome] += 1
            problem = endpoint.problem(reply)
            if problem is None and case.expect is not None and outcome not in case.expect:
                problem = f"{outcome}, expected {sorted(case.expect)}"
            if problem is not None:
                (report.unserved if after_batch else report.wrong).append(
                    f"{label}: {problem} ({getattr(reply, 'message', '')[:200]})"
                )
        return replies


# ------------------------------------------------------------------ running


SIM_ARGUMENTS = ("domino_count:=3", "camera_rate:=2.0", "ground_truth_rate:=1.0")


FUZZED_NODES = {
    "planner_node": ("dombot_planner", ()),
    "sim_node": ("dombot_sim", SIM_ARGUMENTS),
    "perception_node": ("dombot_perception", ("use_sim_time:=true", "continuous:=false")),
    "layer_node": ("dombot_layer", ()),
}
NEEDS = {"perception_node": {"sim_node"}}  # its images and clock


@contextmanager
def fuzzed_nodes(
    logs: Path, serving: Collection[str] = tuple(FUZZED_NODES)
) -> Iterator[dict[str, Popen]]:
    """The ``serving`` nodes and those they need: planner_node, sim_node (3 dominoes),
    perception_node (sim time; on demand, as the bring-up runs it: streaming, it kept
    sim_node rendering four cameras all along), layer_node, each its own process, logging to
    ``logs``/NAME.log (a fuzzed node logs every refusal: a pipe nobody reads would fill up
    and block it)."""
    wanted = set(serving).union(*(NEEDS.get(name, set()) for name in serving))
    with ExitStack() as stack:
        processes = {}
        for name, (package, parameters) in FUZZED_NODES.items():
            if name not in wanted:
                continue
            arguments = ["--ros-args", *(a for p in parameters for a in ("-p", p))]
            log = stack.enter_context((logs / f"{name}.log").open("w"))
            processes[name] = stack.enter_context(
                installed_node(package, name, *arguments, output=log)
            )
        yield processes


def fuzz(
    harness: Harness,
    endpoint: Endpoint,
    cases: st.SearchStrategy[Case],
    batches: int,
    random_seed: int | None = None,
    most_at_once: int = 10,
    fewest_at_once: int = 1,
) -> None:
    """``batches`` batches of ``fewest_at_once`` to ``most_at_once`` cases sent at once;
    derandomized (the same cases every run) when ``random_seed`` is None, else drawn with
    that seed. No shrinking: the report keeps every failure."""
    chosen = settings(
        max_examples=batches,
        derandomize=random_seed is None,
        deadline=None,
        database=None,
        phases=[Phase.generate],
        suppress_health_check=list(HealthCheck),
    )

    @chosen
    @given(batch=st.lists(cases, min_size=fewest_at_once, max_size=most_at_once))
    def run(batch: list[Case]) -> None:
        harness.run(endpoint, batch)

    if random_seed is not None:
        run = seed(random_seed)(run)
    run()

"""``ros2 topic|service|node`` verbs, run from a short-lived node (there is no daemon)."""

from __future__ import annotations

import itertools
import math
import os
import time
from collections import deque
from collections.abc import Iterator
from contextlib import contextmanager

import rclpy
from rclpy.node import Node
from rclpy.qos import DurabilityPolicy, QoSProfile, ReliabilityPolicy

from dombot_ros2.interfaces import load_type
from dombot_ros2.message_yaml import message_to_yaml, parse_yaml_values, set_message_fields
from dombot_ros2.packages import CommandError


@contextmanager
def graph_node(spin_time: float, settle_limit: float = 10.0) -> Iterator[Node]:
    """A hidden node whose view of the graph has settled.

    There is no daemon holding the graph, so each command discovers it anew, and Fast
    DDS announces other participants and their endpoints over a second or more on a
    loaded machine: answered after a fixed spin, six ``service list`` calls with
    layer_node up printed 0, 7, 0, 0, 7 and 7 lines. So spin ``spin_time``, then on
    while no other node is seen or the set of nodes, topics and services still changed
    within the last ``QUIET`` seconds, at most ``settle_limit`` seconds (a graph that
    is really empty is reported after that long).
    """
    rclpy.init()
    node = rclpy.create_node(f"_ros2cli_{os.getpid()}", start_parameter_services=False)
    try:
        spin_for(node, spin_time)
        if settle_limit > 0:
            _settle(node, settle_limit)
        yield node
    finally:
        node.destroy_node()
        rclpy.try_shutdown()


QUIET = 1.0  # s without a change in the graph before it counts as discovered


def _settle(node: Node, limit: float) -> None:
    deadline = time.monotonic() + limit
    seen, changed = _graph_snapshot(node), time.monotonic()
    while time.monotonic() < deadline:
        spin_for(node, 0.1)
        now = _graph_snapshot(node)
        if now != seen:
            seen, changed = now, time.monotonic()
        elif _others(node, seen) and time.monotonic() - changed >= QUIET:
            return


def _graph_snapshot(node: Node) -> tuple:
    return (
        sorted(node.get_node_names_and_namespaces()),
        sorted((name, tuple(types)) for name, types in node.get_topic_names_and_types()),
        sorted((name, tuple(types)) for name, types in node.get_service_names_and_types()),
    )


def _others(node: Node, snapshot: tuple) -> bool:
    return any(name != node.get_name() for name, _ in snapshot[0])


def spin_for(node: Node, seconds: float) -> None:
    deadline = time.monotonic() + seconds
    while time.monotonic() < deadline:
        rclpy.spin_once(node, timeout_sec=min(0.05, max(0.0, deadline - time.monotonic())))


def _visible(name: str, include_hidden: bool) -> bool:
    return include_hidden or not any(part.startswith("_") for part in name.split("/"))


# ---------------------------------------------------------------- topics
def topic_list(node: Node, show_types: bool, include_hidden: bool) -> list[str]:
    return [
        f"{name} [{', '.join(types)}]" if show_types else name
        for name, types in sorted(node.get_topic_names_and_types())
        if _visible(name, include_hidden)
    ]


def topic_type(node: Node, topic: str, wait: float) -> str:
    deadline = time.monotonic() + wait
    while True:
        types = dict(node.get_topic_names_and_types()).get(topic)
        if types:
            return types[0]
        if time.monotonic() > deadline:
            raise CommandError(
                f"Could not determine the type for the passed topic '{topic}'; "
                "pass the type explicitly"
            )
        spin_for(node, 0.1)


def _qos_matching_publishers(node: Node, topic: str) -> QoSProfile:
    """Reliable/transient-local only if every publisher offers it, as ros2cli chooses."""
    infos = node.get_publishers_info_by_topic(topic)
    qos = QoSProfile(depth=10)
    reliable = infos and all(i.qos_profile.reliability == ReliabilityPolicy.RELIABLE for i in infos)
    latched = infos and all(
        i.qos_profile.durability == DurabilityPolicy.TRANSIENT_LOCAL for i in infos
    )
    qos.reliability = ReliabilityPolicy.RELIABLE if reliable else ReliabilityPolicy.BEST_EFFORT
    qos.durability = DurabilityPolicy.TRANSIENT_LOCAL if latched else DurabilityPolicy.VOLATILE
    return qos


def topic_echo(node: Node, topic: str, type_name: str | None, once: bool, wait: float) -> None:
    message_type = load_type(type_name or topic_type(node, topic, wait), kind="msg")
    received = deque()

    def on_message(message) -> None:
        received.append(message)

    node.create_subscription(message_type, topic, on_message, _qos_matching_publishers(node, topic))
    while True:
        rclpy.spin_once(node, timeout_sec=0.1)
        while received:
            print(message_to_yaml(received.popleft()) + "---", flush=True)
            if once:
                return


def topic_hz(node: Node, topic: str, type_name: str | None, window: int, wait: float) -> None:
    message_type = load_type(type_name or topic_type(node, topic, wait), kind="msg")
    stamps: deque[float] = deque(maxlen=window + 1)

    def on_message(_message) -> None:
        stamps.append(time.monotonic())

    node.create_subscription(message_type, topic, on_message, _qos_matching_publishers(node, topic))
    next_report = time.monotonic() + 1.0
    while True:
        rclpy.spin_once(node, timeout_sec=0.05)
        if time.monotonic() >= next_report:
            next_report += 1.0
            print(_rate_report(list(stamps)), flush=True)


def _rate_report(stamps: list[float]) -> str:
    if len(stamps) < 2:
        return "no new messages"
    gaps = [b - a for a, b in itertools.pairwise(stamps)]
    mean = sum(gaps) / len(gaps)
    std = math.sqrt(sum((g - mean) ** 2 for g in gaps) / len(gaps))
    return (
        f"average rate: {1.0 / mean:.3f}\n\tmin: {min(gaps):.3f}s max: {max(gaps):.3f}s "
        f"std dev: {std:.5f}s window: {len(gaps) + 1}"
    )


def topic_info(node: Node, topic: str, verbose: bool, wait: float) -> list[str]:
    try:
        topic_type(node, topic, wait)
    except CommandError:
        raise CommandError(f"Unknown topic '{topic}'") from None
    types = dict(node.get_topic_names_and_types()).get(topic)
    publishers = node.get_publishers_info_by_topic(topic)
    subscribers = node.get_subscriptions_info_by_topic(topic)
    lines = [f"Type: {types[0]}", "", f"Publisher count: {len(publishers)}", ""]
    lines += _endpoint_lines(publishers) if verbose else []
    lines += [f"Subscription count: {len(subscribers)}"]
    lines += (["", *_endpoint_lines(subscribers)]) if verbose else []
    return lines


def _endpoint_lines(infos) -> list[str]:
    lines = []
    for info in infos:
        lines += [
            f"Node name: {info.node_name}",
            f"Node namespace: {info.node_namespace}",
            f"Topic type: {info.topic_type}",
            f"Endpoint type: {info.endpoint_type.name}",
            f"QoS profile:\n  Reliability: {info.qos_profile.reliability.name}\n"
            f"  Durability: {info.qos_profile.durability.name}",
            "",
        ]
    return lines


def message_from(type_name: str, values: str):
    """The message of ``type_name`` that ``values`` (YAML) describe; raises a clean error
    on an unknown type, bad YAML or a field the type lacks."""
    message = load_type(type_name, kind="msg")()
    set_message_fields(message, parse_yaml_values(values))
    return message


def topic_pub(node: Node, topic: str, message, rate: float, times: int) -> None:
    publisher = node.create_publisher(type(message), topic, 10)
    print("publisher: beginning loop", flush=True)
    count = 0
    while times <= 0 or count < times:
        count += 1
        publisher.publish(message)
        print(f"publishing #{count}: {message!r}\n", flush=True)
        spin_for(node, 1.0 / rate)


# ---------------------------------------------------------------- services
def service_list(node: Node, show_types: bool, include_hidden: bool) -> list[str]:
    return [
        f"{name} [{', '.join(types)}]" if show_types else name
        for name, types in sorted(node.get_service_names_and_types())
        if _visible(name, include_hidden)
    ]


def service_type(node: Node, service: str) -> str:
    types = dict(node.get_service_names_and_types()).get(service)
    if not types:
        raise CommandError(f"Unknown service '{service}'")
    return types[0]


def service_call(node: Node, service: str, type_name: str, values: str, timeout: float) -> None:
    service_class = load_type(type_name, kind="srv")
    request = service_class.Request()
    set_message_fields(request, parse_yaml_values(values))
    client = node.create_client(service_class, service)
    deadline = time.monotonic() + timeout
    announced = False
    while not client.service_is_ready():
        if not announced:
            print("waiting for service to become available...", flush=True)
            announced = True
        if time.monotonic() > deadline:
            raise CommandError(no_server("service", service, timeout))
        spin_for(node, 0.1)
    print(f"requester: making request: {request!r}\n", flush=True)
    future = client.call_async(request)
    while not future.done():
        if time.monotonic() > deadline:
            raise CommandError(f"no response from '{service}' within {timeout:.0f} s")
        rclpy.spin_once(node, timeout_sec=0.1)
    print(f"response:\n{future.result()!r}\n", flush=True)


def no_server(kind: str, name: str, timeout: float) -> str:
    return (
        f"no server for {kind} '{name}' appeared within {timeout:g} s: start the node that "
        f"serves it (ros2 {kind} list shows what is served now)"
    )


# ---------------------------------------------------------------- nodes
def node_list(node: Node, include_hidden: bool) -> list[str]:
    names = {
        f"{namespace.rstrip('/')}/{name}"
        for name, namespace in node.get_node_names_and_namespaces()
    }
    return sorted(name for name in names if _visible(name, include_hidden))


def await_node(node: Node, full_name: str, timeout: float) -> bool:
    """Whether ``full_name`` joins the graph within ``timeout``: on a loaded machine a named
    node may be discovered after the graph first looked settled."""
    deadline = time.monotonic() + timeout
    while full_name not in node_list(node, include_hidden=True):
        if time.monotonic() > deadline:
            return False
        spin_for(node, 0.1)
    return True


def node_info(node: Node, full_name: str) -> list[str]:
    namespace, _, name = full_name.rpartition("/")
    namespace = namespace or "/"
    if not await_node(node, full_name, 5.0):
        raise CommandError(f"Unable to find node '{full_name}'")
    spin_for(node, 0.5)  # its endpoints are announced just after the node itself
    sections = [
        ("Subscribers", node.get_subscriber_names_and_types_by_node(name, namespace)),
        ("Publishers", node.get_publisher_names_and_types_by_node(name, namespace)),
        ("Service Servers", node.get_service_names_and_types_by_node(name, namespace)),
        ("Service Clients", node.get_client_names_and_types_by_node(name, namespace)),
    ]
    lines = [full_name]
    for title, entries in sections:
        lines.append(f"  {title}:")
        lines += [f"    {topic}: {', '.join(types)}" for topic, types in sorted(entries)]
    return lines

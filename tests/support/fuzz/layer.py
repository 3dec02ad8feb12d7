"""layer_node's inputs: a probe that reads its status stream as replies, the strategies
for target radii, paths and parameters, and the layer endpoints."""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence

from geometry_msgs.msg import PoseStamped
from hypothesis import strategies as st
from nav_msgs.msg import Path as PathMessage
from rcl_interfaces.msg import Parameter, ParameterType, ParameterValue
from rcl_interfaces.srv import SetParameters
from rclpy.node import Node
from std_msgs.msg import Float64

from dombot_msgs.msg import WheelVelocities
from support.fuzz.harness import Case, Endpoint, service_sender
from support.fuzz.replies import layer_outcome
from support.fuzz.values import HUGE, any_float
from support.ros_processes import spin_until


class LayerProbe:
    """Publishes to layer_node's input topics and reads what its status stream says."""

    def __init__(self, node: Node) -> None:
        self.node = node
        self.status: list[WheelVelocities] = []
        node.create_subscription(WheelVelocities, "/layer/wheel_velocities", self.status.append, 50)
        self.radius_pub = node.create_publisher(Float64, "/layer/target_radius", 10)
        self.path_pub = node.create_publisher(PathMessage, "/layer/path", 10)
        self.sentinel = 1.0

    def _confirm(
        self,
        publish: Callable[[], None],
        seen: Callable[[WheelVelocities], bool],
        timeout: float,
        alive: Callable[[], bool],
    ) -> WheelVelocities | None:
        """Publish until a status ``seen`` arrives (a subscriber may join late)."""
        self.status.clear()

        def arrived() -> bool:
            if any(seen(s) for s in self.status) or not alive():
                return True
            publish()
            return False

        if not spin_until(self.node, arrived, timeout) or not alive():
            return None
        return next(s for s in self.status if seen(s))

    def radius(
        self, radius: float, timeout: float, alive: Callable[[], bool]
    ) -> WheelVelocities | None:
        def seen(s: WheelVelocities) -> bool:
            if math.isnan(radius):
                return s.status == WheelVelocities.STATUS_INVALID and "NaN" in s.message
            return s.deposit_radius == radius

        return self._confirm(
            lambda: self.radius_pub.publish(Float64(data=radius)), seen, timeout, alive
        )

    def path(
        self, path: PathMessage, timeout: float, alive: Callable[[], bool]
    ) -> WheelVelocities | None:
        """The status that answered ``path``: a sentinel radius published after it must
        arrive (the node handled the path and still serves); the answer is the last
        status about a path before the sentinel's."""
        self.status.clear()
        self.path_pub.publish(path)
        self.sentinel += 1e-6
        sentinel = self.radius(self.sentinel, timeout, alive)
        if sentinel is None:
            return None
        about = [s for s in self.status if s.message.startswith("path")]
        return about[-1] if about else sentinel


def radius_cases() -> st.SearchStrategy[Case]:
    return st.one_of(
        st.just(Case(math.nan, "NaN radius", frozenset({"STATUS_INVALID"}))),
        st.one_of(
            st.sampled_from([math.inf, -math.inf, *HUGE, 0.0, -0.0, 1e-300]),
            st.floats(allow_nan=False),
        ).map(lambda r: Case(r, "any radius", frozenset({"STATUS_OK", "STATUS_UNREACHABLE"}))),
    )


def path_message(points: Sequence[tuple[float, float]]) -> PathMessage:
    path = PathMessage()
    path.header.frame_id = "layer_start"
    for x, y in points:
        stamped = PoseStamped()
        stamped.pose.position.x, stamped.pose.position.y = x, y
        path.poses.append(stamped)
    return path


def path_cases() -> st.SearchStrategy[Case]:
    coordinate = st.one_of(any_float(), st.floats(-2, 2))
    return st.one_of(
        st.lists(st.tuples(coordinate, coordinate), max_size=8).map(
            lambda p: Case(path_message(p), "random path")
        ),
        st.integers(0, 3).map(lambda n: Case(path_message([(0.0, 0.0)] * n), "degenerate path")),
        st.sampled_from([10_001, 100_000]).map(
            lambda n: Case(path_message([(0.001 * i, 0.0) for i in range(n)]), f"path of {n} poses")
        ),
    )


def layer_parameter_cases() -> st.SearchStrategy[Case]:
    names = st.sampled_from(
        [
            "forward_speed",
            "deposit_spacing",
            "command_rate",
            "geometry.d_tw",
            "geometry.wheel_radius",
        ]
    )
    return st.tuples(names, st.one_of(any_float(), st.just(-0.0))).map(
        lambda a: Case(
            Parameter(
                name=a[0],
                value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=a[1]),
            ),
            f"{a[0]} = {a[1]}",
            None if (math.isfinite(a[1]) and a[1] > 0) else frozenset({"refused"}),
        )
    )


def layer_endpoints(node: Node) -> list[Endpoint]:
    """/layer/target_radius, /layer/path, layer_node's parameters."""
    probe = LayerProbe(node)
    set_parameters = service_sender(node, SetParameters, "/layer_node/set_parameters")

    def one_by_one(send_one):
        return lambda items, timeout, alive: [send_one(item, timeout, alive) for item in items]

    def parameters(items, timeout, alive):
        requests = [SetParameters.Request(parameters=[p]) for p in items]
        replies = set_parameters(requests, timeout, alive)
        return [r.results[0] if r is not None else None for r in replies]

    restore = Parameter(
        name="forward_speed",
        value=ParameterValue(type=ParameterType.PARAMETER_DOUBLE, double_value=0.1),
    )
    no_problem = lambda reply: None  # noqa: E731  a status always carries a state
    return [
        Endpoint(
            "/layer/target_radius",
            "layer_node",
            one_by_one(probe.radius),
            layer_outcome,
            Case(0.5, "valid radius", frozenset({"STATUS_OK"})),
            no_problem,
        ),
        Endpoint(
            "/layer/path",
            "layer_node",
            one_by_one(probe.path),
            layer_outcome,
            Case(
                path_message([(0, 0), (0.1, 0), (0.2, 0)]), "valid path", frozenset({"STATUS_OK"})
            ),
            no_problem,
        ),
        Endpoint(
            "/layer_node/set_parameters",
            "layer_node",
            parameters,
            lambda r: "accepted" if r.successful else "refused",
            Case(restore, "restore forward_speed", frozenset({"accepted"})),
            lambda r: None if r.successful or r.reason else "refused without a reason",
        ),
    ]

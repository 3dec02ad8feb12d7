"""The vehicle job: lay an arc of dominoes with the simulated domino-laying vehicle over ROS.

Starts ``layer_node`` and ``vehicle_sim_node`` as separate processes, sends the
arc as a deposit path, records where the simulated trolley laid each domino, and
checks what the source document is about: once the trolley has settled, the
dominoes lie on a circle of the requested radius. It also reports how far each
domino landed from the requested curve, including the transient where the
vehicle turns into the arc.
"""

from __future__ import annotations

import itertools
import json
import math
import time
from dataclasses import asdict, dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
import rclpy
from geometry_msgs.msg import PoseArray, PoseStamped
from nav_msgs.msg import Path as PathMessage
from rclpy.node import Node
from rclpy.parameter import Parameter
from scipy.spatial import cKDTree

from dombot_adapters.node_shutdown import stop_signal_thread
from dombot_bringup.process_group import ProcessGroup, say
from dombot_layer.geometry import VehicleGeometry
from dombot_layer.paths import rig_length
from dombot_msgs.msg import WheelVelocities

RADIUS_TOLERANCE = 1e-4  # m: settled dominoes must lie on the requested circle this well


@dataclass
class LayerReport:
    job: str
    deposit_radius_m: float
    sweep_deg: float
    spacing_m: float
    forward_speed_m_per_s: float
    dominoes_laid: int
    dominoes_expected: int
    settled_dominoes: int
    settled_radius_m: float
    settled_radius_error_m: float
    spacing_min_m: float
    spacing_max_m: float
    max_deviation_from_curve_m: float
    median_deviation_from_curve_m: float
    wall_time_s: float
    success: bool


def arc_points(radius: float, sweep: float, count: int = 200) -> np.ndarray:
    """A left arc starting at the origin heading +x (layer_node uses the shape only)."""
    angle = np.linspace(0.0, sweep, count)
    return radius * np.column_stack([np.sin(angle), 1.0 - np.cos(angle)])


def requested_curve(geometry: VehicleGeometry, radius: float, sweep: float) -> np.ndarray:
    """Where the dominoes should go in the vehicle's start frame: layer_node's straight
    lead-in of one rig length from the deposit point's start, then the arc."""
    lead = rig_length(geometry)
    start = np.array([-lead, -geometry.d_t])
    straight = np.column_stack([np.linspace(0.0, lead, 50), np.zeros(50)])
    return np.vstack(
        [start + straight, start + np.array([lead, 0.0]) + arc_points(radius, sweep)[1:]]
    )


class LayerClient(Node):
    """Sends the path, watches the commands and collects the laid dominoes."""

    def __init__(self) -> None:
        super().__init__(
            "bringup_layer", parameter_overrides=[Parameter("use_sim_time", value=False)]
        )
        self.status: WheelVelocities | None = None
        self.deposits = np.empty((0, 2))
        self.vehicle_seen = False
        self.create_subscription(WheelVelocities, "/layer/wheel_velocities", self._on_status, 10)
        self.create_subscription(PoseArray, "/layer/deposits", self._on_deposits, 10)
        self.path_pub = self.create_publisher(PathMessage, "/layer/path", 10)

    def _on_status(self, message: WheelVelocities) -> None:
        self.status = message

    def _on_deposits(self, message: PoseArray) -> None:
        self.vehicle_seen = True
        self.deposits = np.array([[p.position.x, p.position.y] for p in message.poses]).reshape(
            -1, 2
        )

    def send_path(self, points: np.ndarray) -> None:
        message = PathMessage()
        message.header.frame_id = "layer_start"
        for x, y in points:
            pose = PoseStamped()
            pose.pose.position.x, pose.pose.position.y = float(x), float(y)
            message.poses.append(pose)
        self.path_pub.publish(message)


def run_layer_job(
    out_dir: Path, radius: float, sweep_deg: float, spacing: float, speed: float, node_command
) -> int:
    """Run the job; ``node_command(package, executable, parameters)`` builds a node's argv."""
    geometry = VehicleGeometry()
    sweep = math.radians(sweep_deg)
    path = arc_points(radius, sweep)
    started = time.monotonic()
    parameters = {"deposit_spacing": spacing, "forward_speed": speed}
    with ProcessGroup() as group:
        group.start("layer_node", node_command("dombot_layer", "layer_node", parameters))
        group.start(
            "vehicle_sim_node",
            node_command("dombot_layer", "vehicle_sim_node", {"deposit_spacing": spacing}),
        )
        rclpy.init()
        try:
            client = LayerClient()
            spin_while(
                group, client, lambda: client.status is None, 60, "layer_node's first command"
            )
            spin_while(
                group, client, lambda: not client.vehicle_seen, 60, "vehicle_sim_node's first tick"
            )
            spin_while(
                group,
                client,
                lambda: client.path_pub.get_subscription_count() == 0,
                30,
                "layer_node to subscribe to /layer/path",
            )
            client.send_path(path)
            spin_while(
                group,
                client,
                lambda: client.status.status == WheelVelocities.STATUS_STOPPED,
                30,
                "layer_node to take the path",
            )
            if client.status.status != WheelVelocities.STATUS_OK:
                raise PathRejectedError(client.status.message)
            say(f"laying a {sweep_deg:.0f}° arc of radius {radius} m at {speed} m/s ...")
            spin_while(
                group,
                client,
                lambda: client.status.status == WheelVelocities.STATUS_OK,
                4 * (radius * sweep + 1.0) / speed + 60,
                "the path to finish",
                progress=client,
            )
            spin_for(client, 0.5)
            deposits = client.deposits.copy()
        finally:
            stop_signal_thread()  # before rclpy's global executor goes with the context
            rclpy.try_shutdown()
    curve = requested_curve(geometry, radius, sweep)
    report = evaluate(
        rig_length(geometry),
        curve,
        deposits,
        radius,
        sweep_deg,
        spacing,
        speed,
        time.monotonic() - started,
    )
    write_outputs(out_dir, report, curve, deposits)
    return 0 if report.success else 1


class PathRejectedError(RuntimeError):
    """layer_node refused the run (e.g. a curve tighter than the vehicle can lay)."""


def spin_while(
    group: ProcessGroup,
    node: Node,
    condition,
    timeout: float,
    what: str,
    progress: LayerClient | None = None,
) -> None:
    deadline = time.monotonic() + timeout
    last_report = 0
    while condition():
        group.check()
        if time.monotonic() > deadline:
            raise TimeoutError(f"timed out after {timeout:.0f} s waiting for {what}")
        rclpy.spin_once(node, timeout_sec=0.1)
        if progress is not None and len(progress.deposits) >= last_report + 10:
            last_report = len(progress.deposits)
            say(f"{last_report} dominoes laid")


def spin_for(node: Node, seconds: float) -> None:
    end = time.monotonic() + seconds
    while time.monotonic() < end:
        rclpy.spin_once(node, timeout_sec=0.05)


def evaluate(
    rig: float,
    curve: np.ndarray,
    deposits: np.ndarray,
    radius: float,
    sweep_deg: float,
    spacing: float,
    speed: float,
    wall_time: float,
) -> LayerReport:
    total = float(np.sum(np.linalg.norm(np.diff(curve, axis=0), axis=1)))
    expected = int(total // spacing) + 1
    deviation = cKDTree(_densify(curve)).query(deposits)[0] if len(deposits) else np.array([np.inf])
    # Settled: from the middle of the arc until the vehicle, a rig length ahead of
    # the deposit point, straightens out for the lead-out.
    lead = int(rig / spacing) + 1
    arc_count = int(radius * math.radians(sweep_deg) // spacing)
    settled = deposits[lead + arc_count // 2 : lead + arc_count - lead]
    fitted = _fit_circle_radius(settled) if len(settled) >= 3 else math.nan
    gaps = (
        np.linalg.norm(np.diff(deposits, axis=0), axis=1)
        if len(deposits) > 1
        else np.array([math.nan])
    )
    error = abs(fitted - radius)
    return LayerReport(
        job="layer",
        deposit_radius_m=radius,
        sweep_deg=sweep_deg,
        spacing_m=spacing,
        forward_speed_m_per_s=speed,
        dominoes_laid=len(deposits),
        dominoes_expected=expected,
        settled_dominoes=len(settled),
        settled_radius_m=fitted,
        settled_radius_error_m=error,
        spacing_min_m=float(gaps.min()),
        spacing_max_m=float(gaps.max()),
        max_deviation_from_curve_m=float(deviation.max()),
        median_deviation_from_curve_m=float(np.median(deviation)),
        wall_time_s=wall_time,
        success=bool(abs(len(deposits) - expected) <= 1 and error <= RADIUS_TOLERANCE),
    )


def _fit_circle_radius(points: np.ndarray) -> float:
    """Algebraic (Kåsa) circle fit: solve x² + y² + D x + E y + F = 0 by least squares."""
    a = np.column_stack([points, np.ones(len(points))])
    b = -(points**2).sum(axis=1)
    d, e, f = np.linalg.lstsq(a, b, rcond=None)[0]
    return float(math.sqrt(d * d / 4 + e * e / 4 - f))


def _densify(path: np.ndarray, step: float = 1e-4) -> np.ndarray:
    pieces = [
        np.linspace(a, b, max(2, int(np.linalg.norm(b - a) / step)))
        for a, b in itertools.pairwise(path)
    ]
    return np.vstack(pieces)


def write_outputs(
    out_dir: Path, report: LayerReport, curve: np.ndarray, deposits: np.ndarray
) -> None:
    out_dir.mkdir(parents=True, exist_ok=True)
    (out_dir / "layer_report.json").write_text(json.dumps(asdict(report), indent=2))
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(*curve.T, "k-", lw=1, label="requested run (lead-in + arc)")
    ax.plot(*deposits.T, "r.", ms=5, label=f"laid by the simulated vehicle ({len(deposits)})")
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (vehicle start frame)")
    ax.set_ylabel("y [m]")
    error_mm = report.settled_radius_error_m * 1e3
    deviation_mm = report.max_deviation_from_curve_m * 1e3
    ax.set_title(
        f"Domino layer over ROS: settled radius error {error_mm:.4f} mm\n"
        f"max distance from the requested curve {deviation_mm:.1f} mm"
    )
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    fig.tight_layout()
    fig.savefig(out_dir / "layer_run.png", dpi=110)
    plt.close(fig)
    verdict = "SUCCESS" if report.success else "FAILED"
    say(
        f"{verdict}: {report.dominoes_laid}/{report.dominoes_expected} dominoes laid; "
        f"settled arc radius {report.settled_radius_m:.5f} m for {report.deposit_radius_m} m "
        f"requested (error {error_mm:.4f} mm, limit {RADIUS_TOLERANCE * 1e3:.1f} mm); "
        f"spacing {report.spacing_min_m * 1e3:.1f}-{report.spacing_max_m * 1e3:.1f} mm; "
        f"max distance from the requested curve {deviation_mm:.1f} mm "
        f"(turn-in and lead-out transients); {report.wall_time_s:.1f} s wall"
    )
    say(f"report: {out_dir / 'layer_report.json'}, plot: {out_dir / 'layer_run.png'}")

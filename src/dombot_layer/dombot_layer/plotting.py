"""Figures for docs/LAYER.md: the vehicle geometry, r_d(r_m), and simulated laying runs."""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np
from matplotlib.axes import Axes
from matplotlib.patches import Arc as ArcPatch
from matplotlib.patches import Polygon, Rectangle

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import (
    LayerKinematics,
    deposit_radius,
    forward,
    wheel_angular_velocities,
)
from dombot_layer.paths import Arc, Straight, schedule_segments, trace_segments
from dombot_layer.vehicle_sim import SimulationResult, circle_center, simulate

SPEED = 0.1  # m/s, forward speed of the runs in the figures


@dataclass(frozen=True)
class Panel:
    """One simulated run to draw, with the deposit path it was asked to lay."""

    title: str
    result: SimulationResult
    requested: np.ndarray  # (n, 2) m


def write_doc_figures(kinematics: LayerKinematics, folder: Path) -> list[Path]:
    """Regenerate every figure docs/LAYER.md shows (``bench_layer.py --figures``)."""
    folder = Path(folder)
    return [
        plot_geometry(kinematics.geometry, 0.25, folder / "layer_geometry.png"),
        plot_deposit_curve(kinematics, folder / "layer_deposit_radius.png"),
        plot_simulation(
            [_circle_run(kinematics, 0.3, 3.0), _s_curve_run(kinematics)],
            folder / "layer_sim.png",
        ),
    ]


def _circle_run(kinematics: LayerKinematics, radius: float, distance: float) -> Panel:
    """Start straight, then hold the wheel speeds inverse kinematics gives for r_d."""
    midpoint = kinematics.midpoint_radius(radius)
    left, right = wheel_angular_velocities(kinematics.geometry, midpoint, SPEED)
    result = simulate(kinematics.geometry, lambda t: (left, right), distance / SPEED, 0.01)
    angle = np.linspace(0.0, 2 * math.pi, 400)
    circle = circle_center(midpoint) + abs(radius) * np.column_stack([np.cos(angle), np.sin(angle)])
    return Panel(f"circle r_d = {radius} m, from straight", result, circle)


def _s_curve_run(kinematics: LayerKinematics) -> Panel:
    """A deposit path of a straight, a left and a right arc, played with look-ahead."""
    turn = 0.3 * 1.5 * math.pi
    segments = [Straight(0.3), Arc(0.3, turn), Arc(-0.3, turn)]
    schedule = schedule_segments(kinematics, segments, SPEED, 0.02, look_ahead=True)
    result = simulate(kinematics.geometry, schedule.command_at, schedule.duration, 0.02, 0.0, 0.02)
    title = "path: 0.3 m straight, ¾ turn left, ¾ turn right, r_d = 0.3 m (look-ahead)"
    return Panel(title, result, trace_segments(segments))


@dataclass(frozen=True)
class _Sketch:
    """The figure's points in the frame of eqs (1)–(9); E is D's foot on the trolley axis."""

    geometry: VehicleGeometry
    theta: float
    phi: float
    along: np.ndarray  # trolley axis, P → W
    across: np.ndarray  # trolley's right, away from O in a left turn
    o: np.ndarray
    m: np.ndarray
    p: np.ndarray
    w: np.ndarray
    e: np.ndarray
    d: np.ndarray

    @classmethod
    def at(cls, g: VehicleGeometry, r_m: float) -> _Sketch:
        theta = forward(g, r_m).theta
        along = np.array([math.cos(theta), -math.sin(theta)])
        across = np.array([math.sin(theta), math.cos(theta)])
        p = np.array([g.d_p, r_m])
        w = p + g.d_tw * along
        e = w + g.d_l * along
        o, m, d = np.zeros(2), np.array([0.0, r_m]), e + g.d_t * across
        return cls(g, theta, math.atan2(g.d_t, g.d_l), along, across, o, m, p, w, e, d)


def plot_geometry(geometry: VehicleGeometry, midpoint_radius: float, path: Path) -> Path:
    """Top view in the frame of eqs (1)–(9): O at the origin, M at (0, r_m), left turn."""
    s = _Sketch.at(geometry, midpoint_radius)
    fig, (ax, detail) = plt.subplots(1, 2, figsize=(12, 8), width_ratios=(2.2, 1))
    _draw_bodies(ax, s)
    for start, end, style in (
        (s.o, s.m, "b:"),
        (s.o, s.w, "g:"),
        (s.o, s.d, "r:"),
        (s.o, s.p, "k:"),
    ):
        _line(ax, start, end, style, lw=1)
    _line(ax, s.m, s.p, "b-", lw=3)
    _line(ax, s.p, s.w, "g-", lw=3)
    _draw_deposit_offset(ax, s, labelled=False)
    for point, text, offset in (
        (s.o, "O", (-14, -4)),
        (s.m, "M", (-16, 6)),
        (s.p, "P", (4, 6)),
        (s.w, "W", (-18, -4)),
        (s.d, "D", (6, -2)),
    ):
        ax.plot(*point, "ko", ms=4)
        ax.annotate(text, point, textcoords="offset points", xytext=offset, fontsize=13)
    _label_lengths(ax, s)
    _draw_angles(ax, s, midpoint_radius)
    _right_angle(ax, s.m, np.array([1.0, 0.0]), np.array([0.0, -1.0]))
    _right_angle(ax, s.w, -s.along, -s.across)
    _draw_deposit_offset(detail, s, labelled=True)
    low, high = detail.get_xlim(), detail.get_ylim()
    frame = Rectangle((low[0], high[0]), low[1] - low[0], high[1] - high[0], fill=False, ec="m")
    ax.add_patch(frame)
    ax.annotate(
        "drives towards −x, turning left about O\n+ d_t is the vehicle's right",
        (0.98, 0.015),
        xycoords="axes fraction",
        ha="right",
        fontsize=9,
    )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (along the tractor, pointing backwards)")
    ax.set_ylabel("y [m] (from O through M)")
    ax.set_title(
        "Domino layer geometry in the frame of eqs (1)–(9)\n"
        f"θ = {math.degrees(s.theta):.1f}°, φ = {math.degrees(s.phi):.1f}°: "
        f"r_m = {midpoint_radius:.3f} m → r_d = {deposit_radius(geometry, midpoint_radius):.3f} m"
    )
    ax.grid(alpha=0.25)
    return _save(fig, path)


def _line(ax: Axes, start: np.ndarray, end: np.ndarray, style: str, **kwargs: object) -> None:
    ax.plot(*zip(start, end, strict=True), style, **kwargs)


def _draw_bodies(ax: Axes, s: _Sketch) -> None:
    """Tractor body with its drive wheels, trolley wheel, domino and travel direction."""
    g, m = s.geometry, s.m
    half_track = g.d_w / 2
    body = Rectangle(
        (m[0] - 0.04, m[1] - 0.7 * half_track), g.d_p + 0.06, 1.4 * half_track, alpha=0.4
    )
    body.set(facecolor="lightsteelblue", edgecolor="b")
    ax.add_patch(body)
    for side in (-1, 1):
        corner = (m[0] - g.wheel_radius, m[1] + side * half_track - 0.008)
        ax.add_patch(Rectangle(corner, 2 * g.wheel_radius, 0.016, fc="tab:blue"))
    track = (m + np.array([0.0, half_track]), m - np.array([0.0, half_track]))
    ax.annotate("", *track, arrowprops={"arrowstyle": "<->", "color": "b"})
    ax.annotate("$d_w$", m + np.array([0.005, 0.6 * half_track]), color="b", fontsize=12)
    normal = np.array([s.along[1], -s.along[0]])
    corners = [
        s.w + a * 0.025 * s.along + b * 0.006 * normal
        for a, b in ((-1, -1), (1, -1), (1, 1), (-1, 1))
    ]
    ax.add_patch(Polygon(corners, fc="tab:blue"))
    ax.add_patch(Rectangle(s.d - np.array([0.006, 0.003]), 0.012, 0.006, fc="r"))
    top = m[1] + 0.7 * half_track + 0.012
    ax.annotate(
        "travel",
        (m[0] - 0.035, top),
        (m[0] + 0.02, top),
        arrowprops={"arrowstyle": "->"},
        va="center",
    )


def _draw_deposit_offset(ax: Axes, s: _Sketch, labelled: bool) -> None:
    """W → E (d_l, along the trolley) → D (d_t, across it); z = |WD| at angle φ."""
    _line(ax, s.w, s.e, "m--", lw=1.5)
    _line(ax, s.e, s.d, "m--", lw=1.5)
    _line(ax, s.w, s.d, "m-", lw=1)
    if not labelled:
        return
    g = s.geometry
    _line(ax, s.w - 0.03 * s.along, s.w, "g-", lw=3)
    _line(ax, s.e, s.e + 0.015 * s.along, "k:", lw=1)  # trolley axis, extended
    ax.plot(*np.array([s.w, s.d]).T, "ko", ms=4)
    for point, text, offset in ((s.w, "W", (6, 6)), (s.d, "D", (8, -4)), (s.e, "E", (-16, -12))):
        ax.annotate(text, point, textcoords="offset points", xytext=offset, fontsize=13)
    for start, end, text, offset in (
        (s.w, s.e, "$d_l$", (-26, -10)),
        (s.e, s.d, "$d_t$", (4, -16)),
        (s.w, s.d, "z", (0, 8)),
    ):
        where = (start + end) / 2
        ax.annotate(text, where, textcoords="offset points", xytext=offset, color="m", fontsize=13)
    _angle_arc(ax, s.w, 0.018, -math.degrees(s.theta), math.degrees(s.phi - s.theta), "φ", "m")
    _right_angle(ax, s.e, -s.along, s.across, size=0.004)
    ax.set_title(f"deposit offset (detail): d_l = {g.d_l} m, d_t = {g.d_t} m", fontsize=10)
    ax.set_aspect("equal")
    ax.grid(alpha=0.25)
    corner_low = np.minimum(s.w, s.d) - 0.016
    corner_high = np.maximum(s.w, s.d) + 0.016
    ax.set_xlim(corner_low[0], corner_high[0])
    ax.set_ylim(corner_low[1], corner_high[1])


def _label_lengths(ax: Axes, s: _Sketch) -> None:
    labels = (
        (s.m, s.p, "$d_p$", "b", (0, 6)),
        (s.p, s.w, "$d_{tw}$", "g", (8, 0)),
        (s.o, s.m, "$r_m$", "b", (-22, 0)),
        (s.o, s.d, "$r_d$", "r", (2, -14)),
        (s.o, s.w, "$R_w$", "g", (-4, 6)),
    )
    for start, end, text, colour, offset in labels:
        ax.annotate(
            text,
            (start + end) / 2,
            textcoords="offset points",
            xytext=offset,
            color=colour,
            fontsize=12,
        )


def _draw_angles(ax: Axes, s: _Sketch, r_m: float) -> None:
    """α = ∠MPO, β = ∠OPW and θ, between the trolley and the tractor axis, at P."""
    alpha = math.degrees(math.atan2(r_m, s.geometry.d_p))
    theta = math.degrees(s.theta)
    beta = 180.0 - alpha - theta
    _angle_arc(ax, s.p, 0.05, 180.0, 180.0 + alpha, "α", "tab:orange")
    _angle_arc(ax, s.p, 0.07, 180.0 + alpha, 180.0 + alpha + beta, "β", "tab:purple")
    _angle_arc(ax, s.p, 0.05, 360.0 - theta, 360.0, "θ", "k")
    _line(ax, s.p, s.p + np.array([0.09, 0.0]), "k:", lw=1)  # tractor axis, extended


def _angle_arc(
    ax: Axes, centre: np.ndarray, radius: float, start: float, end: float, text: str, colour: str
) -> None:
    """An angle from ``start`` to ``end`` degrees (anticlockwise), labelled at its middle."""
    ax.add_patch(
        ArcPatch(centre, 2 * radius, 2 * radius, theta1=start, theta2=end, color=colour, lw=1.5)
    )
    middle = math.radians((start + end) / 2)
    where = centre + 1.3 * radius * np.array([math.cos(middle), math.sin(middle)])
    ax.annotate(text, where, color=colour, fontsize=13, ha="center", va="center")


def _right_angle(
    ax: Axes, corner: np.ndarray, first: np.ndarray, second: np.ndarray, size: float = 0.012
) -> None:
    square = [corner + size * first, corner + size * (first + second), corner + size * second]
    ax.plot(*np.array(square).T, "k-", lw=0.8)


def plot_simulation(panels: list[Panel], path: Path) -> Path:
    """Drive-axle path, trolley-wheel path and laid dominoes (top view), one panel per run."""
    fig, axes = plt.subplots(1, len(panels), figsize=(7 * len(panels), 7), squeeze=False)
    for ax, panel in zip(axes[0], panels, strict=True):
        result = panel.result
        ax.plot(*result.midpoint.T, "b-", lw=1.5, label="drive-axle midpoint M")
        ax.plot(*result.trolley_wheel.T, "g-", lw=1.0, label="trolley wheel W")
        ax.plot(*result.deposits.T, "r.", ms=3, label=f"laid dominoes ({len(result.deposits)})")
        ax.plot(*panel.requested.T, "k--", lw=0.8, label="requested deposit path")
        ax.set_aspect("equal")
        ax.set_xlabel("x [m]")
        ax.set_ylabel("y [m]")
        ax.set_title(panel.title, fontsize=10)
        ax.legend(fontsize=8, loc="best")
        ax.grid(alpha=0.3)
    fig.suptitle("Simulated domino layer: M starts at the origin heading +x, trolley in line")
    return _save(fig, path)


def plot_deposit_curve(kinematics: LayerKinematics, path: Path) -> Path:
    """r_d against r_m for both turn directions, with the minimum laying radii marked."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    r = np.geomspace(kinematics.geometric_limit + 1e-9, 2.0, 2000)
    for side, style in (("left", "b"), ("right", "r")):
        sign = 1.0 if side == "left" else -1.0
        r_d = np.abs(forward(kinematics.geometry, sign * r).deposit_radius)
        ax.plot(r, r_d, style, label=f"{side} turn")
        ax.axhline(kinematics.minimum_laying_radius(side), color=style, ls=":", lw=0.8)
    ax.plot(r, r, "k:", lw=0.8, label="$r_d = r_m$")
    ax.set_xscale("log")
    ax.set_yscale("log")
    ax.set_xlabel("|$r_m$| [m]")
    ax.set_ylabel("|$r_d$| [m]")
    ax.set_title("Deposit radius against midpoint radius (dotted: minimum laying radii)")
    ax.legend()
    ax.grid(alpha=0.3, which="both")
    return _save(fig, path)


def _save(fig: plt.Figure, path: Path) -> Path:
    path = Path(path)
    path.parent.mkdir(parents=True, exist_ok=True)
    fig.tight_layout()
    fig.savefig(path, dpi=110)
    plt.close(fig)
    return path

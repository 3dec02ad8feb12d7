"""Figures for people: the vehicle geometry, and a simulated laying run."""

from __future__ import annotations

import math
from pathlib import Path

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt
import numpy as np

from dombot_layer.geometry import VehicleGeometry
from dombot_layer.kinematics import LayerKinematics, forward
from dombot_layer.vehicle_sim import SimulationResult


def plot_geometry(geometry: VehicleGeometry, midpoint_radius: float, path: Path) -> Path:
    """Top view in the source's frame (O at the origin, M at (0, r_m)), lengths labelled."""
    g = geometry
    result = forward(g, midpoint_radius)
    theta = result.theta
    m = np.array([0.0, midpoint_radius])
    p = np.array([g.d_p, midpoint_radius])
    w = p + g.d_tw * np.array([math.cos(theta), -math.sin(theta)])
    phi = math.atan2(g.d_t, g.d_l)
    d = w + g.deposit_offset * np.array([math.cos(phi - theta), math.sin(phi - theta)])
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(*zip(np.zeros(2), m, strict=True), "k:", lw=1)
    ax.plot(*zip(np.zeros(2), w, strict=True), "k:", lw=1)
    ax.plot(*zip(np.zeros(2), d, strict=True), "r:", lw=1)
    ax.plot(*zip(m, p, strict=True), "b-", lw=3, label="tractor centre line (M→P, $d_p$)")
    ax.plot(*zip(p, w, strict=True), "g-", lw=3, label="trolley (P→W, $d_{tw}$)")
    ax.plot(*zip(w, d, strict=True), "m--", lw=2, label="W→D ($z$; $d_l$ along, $d_t$ across)")
    for xy, text in ((np.zeros(2), "O"), (m, "M"), (p, "P"), (w, "W"), (d, "D")):
        ax.plot(*xy, "ko", ms=5)
        ax.annotate(text, xy, textcoords="offset points", xytext=(6, 6), fontsize=12)
    wheel_offset = np.array([0.0, g.d_w / 2])
    for side in (-1, 1):
        ax.plot(*(m + side * wheel_offset), "bs", ms=10)
    ax.plot([], [], "bs", label="drive wheels ($d_w$ apart)")
    for radius, style, name in (
        (midpoint_radius, "b", "$r_m$"),
        (abs(result.deposit_radius), "r", "$r_d$"),
    ):
        t = np.linspace(-0.3, 0.9, 200)
        ax.plot(
            radius * np.sin(t), radius * np.cos(t), style, lw=0.8, alpha=0.6, label=f"{name} circle"
        )
    ax.annotate(
        f"θ = {math.degrees(theta):.1f}°, φ = {math.degrees(phi):.1f}°\n"
        f"$r_m$ = {midpoint_radius:.3f} m → $r_d$ = {result.deposit_radius:.3f} m\n"
        "vehicle drives towards −x (left turn about O)",
        (0.02, 0.02),
        xycoords="axes fraction",
        fontsize=10,
    )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m] (along the vehicle, backwards)")
    ax.set_ylabel("y [m] (from O through M)")
    ax.set_title("Domino layer geometry (frame of eqs (1)–(9))")
    ax.legend(loc="upper right", fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_simulation(
    result: SimulationResult,
    path: Path,
    deposit_radius: float | None = None,
    center: np.ndarray | None = None,
) -> Path:
    """Vehicle path, trolley-wheel path and the laid dominoes (top view)."""
    fig, ax = plt.subplots(figsize=(7, 7))
    ax.plot(*result.midpoint.T, "b-", lw=1.5, label="drive-axle midpoint M")
    ax.plot(*result.trolley_wheel.T, "g-", lw=1.0, label="trolley wheel W")
    ax.plot(*result.deposits.T, "r.", ms=3, label=f"laid dominoes ({len(result.deposits)})")
    if deposit_radius is not None and center is not None:
        t = np.linspace(0, 2 * math.pi, 400)
        ax.plot(
            center[0] + abs(deposit_radius) * np.cos(t),
            center[1] + abs(deposit_radius) * np.sin(t),
            "k--",
            lw=0.8,
            label=f"predicted $r_d$ = {deposit_radius:.3f} m",
        )
    ax.set_aspect("equal")
    ax.set_xlabel("x [m]")
    ax.set_ylabel("y [m]")
    ax.set_title("Simulated domino layer (starts at the origin heading +x)")
    ax.legend(fontsize=8)
    ax.grid(alpha=0.3)
    return _save(fig, path)


def plot_deposit_curve(kinematics: LayerKinematics, path: Path) -> Path:
    """r_d against r_m for both turn directions, with the minimum laying radii marked."""
    fig, ax = plt.subplots(figsize=(7, 4.5))
    r = np.geomspace(kinematics.geometric_limit + 1e-9, 2.0, 2000)
    for sign, side, style in ((1.0, "left", "b"), (-1.0, "right", "r")):
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

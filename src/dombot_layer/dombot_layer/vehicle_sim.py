"""Simulation of the tractor–trolley rig from wheel velocities, independent of eqs (1)–(9).

State: midpoint M of the drive axle (x, y), tractor heading ψ, trolley heading
ψ_t (direction from the trolley wheel W to the pivot P), and the arc length the
deposit point has travelled. The drive wheels roll without slip (unicycle
kinematics for M); the trolley is hinged at P and its wheel cannot slide
sideways, so W's velocity is along the trolley: ψ̇_t = (Ṗ · n_t) / d_tw with n_t
the trolley's left normal. A domino is laid each time the deposit point has
travelled another ``spacing`` metres. Nothing here uses the closed-form
kinematics, so agreement with them is a real check.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

from dombot_layer.geometry import VehicleGeometry

WheelCommand = Callable[[float], tuple[float, float]]


@dataclass(frozen=True)
class SimulationResult:
    time: np.ndarray  # s, samples of the trajectory
    midpoint: np.ndarray  # (n, 2) m, M
    heading: np.ndarray  # (n,) rad, tractor
    trolley_heading: np.ndarray  # (n,) rad, direction W → P
    trolley_wheel: np.ndarray  # (n, 2) m, W
    deposit_point: np.ndarray  # (n, 2) m, D
    deposits: np.ndarray  # (k, 2) m, laid dominoes
    deposit_times: np.ndarray  # (k,) s

    @property
    def trolley_angle(self) -> np.ndarray:
        """Tractor heading − trolley heading [rad]: eq. (9)'s θ in a steady left turn, −θ right."""
        return self.heading - self.trolley_heading


def _points(geometry: VehicleGeometry, state: np.ndarray) -> tuple[np.ndarray, ...]:
    """Pivot P, trolley wheel W and deposit point D for states of shape (5, n)."""
    x, y, psi, psi_t = state[0], state[1], state[2], state[3]
    forward = np.array([np.cos(psi), np.sin(psi)])
    trolley = np.array([np.cos(psi_t), np.sin(psi_t)])
    trolley_left = np.array([-np.sin(psi_t), np.cos(psi_t)])
    pivot = np.array([x, y]) - geometry.d_p * forward
    wheel = pivot - geometry.d_tw * trolley
    deposit = wheel - geometry.d_l * trolley - geometry.d_t * trolley_left  # + d_t = right
    return pivot, wheel, deposit


def _dynamics(
    geometry: VehicleGeometry, command: WheelCommand
) -> Callable[[float, np.ndarray], np.ndarray]:
    g = geometry

    def rates(t: float, state: np.ndarray) -> np.ndarray:
        left, right = command(t)
        v = g.wheel_radius * (left + right) / 2.0
        omega = g.wheel_radius * (right - left) / g.d_w
        psi, psi_t = state[2], state[3]
        forward = np.array([np.cos(psi), np.sin(psi)])
        pivot_velocity = v * forward - omega * g.d_p * np.array([-np.sin(psi), np.cos(psi)])
        trolley_left = np.array([-np.sin(psi_t), np.cos(psi_t)])
        psi_t_rate = pivot_velocity @ trolley_left / g.d_tw
        trolley = np.array([np.cos(psi_t), np.sin(psi_t)])
        # D = P − (d_tw + d_l)·e_t − d_t·n_t, and ė_t = ψ̇_t n_t, ṅ_t = −ψ̇_t e_t.
        deposit_velocity = pivot_velocity + psi_t_rate * (
            -(g.d_tw + g.d_l) * trolley_left + g.d_t * trolley
        )
        return np.array(
            [v * forward[0], v * forward[1], omega, psi_t_rate, np.hypot(*deposit_velocity)]
        )

    return rates


def _integrate(
    geometry: VehicleGeometry,
    command: WheelCommand,
    t_span: tuple[float, float],
    initial: np.ndarray,
    max_step: float,
):
    # Tight tolerances keep integration error far below the 0.1 mm the kinematics are checked to.
    solution = solve_ivp(
        _dynamics(geometry, command),
        t_span,
        initial,
        method="DOP853",
        rtol=1e-11,
        atol=1e-12,
        dense_output=True,
        max_step=max_step,
    )
    if not solution.success:
        raise RuntimeError(f"vehicle simulation failed: {solution.message}")
    return solution


def simulate(
    geometry: VehicleGeometry,
    command: WheelCommand,
    duration: float,
    spacing: float,
    initial_trolley_angle: float = 0.0,
    max_step: float = 0.05,
) -> SimulationResult:
    """Integrate from M at the origin heading +x, the trolley heading ``initial_trolley_angle``.

    The trolley's heading is the direction W → P [rad]: 0 is in line behind the
    tractor, −θ of eq. (9) its steady state in a left turn, +θ in a right turn.

    ``command(t)`` gives (left, right) wheel angular velocities in rad/s. A domino
    is laid at the start and after every further ``spacing`` metres.
    """
    if not (duration > 0 and spacing > 0):
        raise ValueError("duration and spacing must be positive")
    initial = np.array([0.0, 0.0, 0.0, initial_trolley_angle, 0.0])
    solution = _integrate(geometry, command, (0.0, duration), initial, max_step)
    deposit_times = _crossing_times(solution, np.arange(0.0, solution.y[4, -1], spacing))
    deposits = _points(geometry, solution.sol(deposit_times))[2]
    _, wheel, deposit = _points(geometry, solution.y)
    return SimulationResult(
        time=solution.t,
        midpoint=solution.y[:2].T,
        heading=solution.y[2],
        trolley_heading=solution.y[3],
        trolley_wheel=wheel.T,
        deposit_point=deposit.T,
        deposits=deposits.T,
        deposit_times=deposit_times,
    )


def _crossing_times(solution, marks: np.ndarray) -> np.ndarray:
    """Times at which the deposit arc length (monotonic) passes each mark."""
    if marks.size == 0:
        return np.empty(0)
    fine_t = np.linspace(solution.t[0], solution.t[-1], max(2001, 20 * solution.t.size))
    travelled = solution.sol(fine_t)[4]
    times = np.interp(marks, travelled, fine_t)
    for _ in range(2):  # Newton polish on the dense output
        values = solution.sol(times)[4]
        slope = (solution.sol(times + 1e-6)[4] - solution.sol(times - 1e-6)[4]) / 2e-6
        times = times - (values - marks) / np.where(slope > 0, slope, np.inf)
    return times


class VehicleSimulator:
    """The same model stepped in real time by wheel commands, for a ROS node."""

    def __init__(self, geometry: VehicleGeometry, spacing: float, max_step: float = 0.05) -> None:
        if not spacing > 0:
            raise ValueError(f"spacing must be positive, got {spacing}")
        self.geometry = geometry
        self.spacing = spacing
        self.max_step = max_step
        self.time = 0.0
        self.state = np.zeros(5)
        self.next_mark = 0.0

    def step(self, left: float, right: float, dt: float) -> np.ndarray:
        """Advance ``dt`` seconds at constant wheel velocities; return the dominoes laid (k, 2)."""
        if not dt > 0:
            return np.empty((0, 2))
        solution = _integrate(
            self.geometry,
            lambda t: (left, right),
            (self.time, self.time + dt),
            self.state,
            self.max_step,
        )
        travelled = solution.y[4, -1]
        marks = (
            np.arange(self.next_mark, travelled, self.spacing)
            if travelled > self.next_mark
            else np.empty(0)
        )
        times = _crossing_times(solution, marks)
        self.next_mark = float(marks[-1] + self.spacing) if marks.size else self.next_mark
        self.time += dt
        self.state = solution.y[:, -1]
        return _points(self.geometry, solution.sol(times))[2].T if times.size else np.empty((0, 2))

    def pose(self) -> tuple[float, float, float]:
        """Midpoint M (x, y) and tractor heading [rad]."""
        return float(self.state[0]), float(self.state[1]), float(self.state[2])

    def trolley_wheel(self) -> np.ndarray:
        return _points(self.geometry, self.state[:, None])[1][:, 0]


def circle_center(midpoint_radius: float) -> np.ndarray:
    """Centre O of the circle M drives on from the start pose (M at the origin heading +x)."""
    return np.array([0.0, midpoint_radius])

"""The toppling-wave speed of a straight domino run, after van Leeuwen's model.

J. M. J. van Leeuwen, "The domino effect", Am. J. Phys. 78, 721 (2010) (arXiv
physics/0401018): rigid dominoes of height ``h`` and thickness ``w`` stand at pitch ``d``
(centre to centre, what the layouts call the spacing). A falling domino turns about its
front bottom edge without slipping on the table; when its top edge reaches the next
domino it stays in contact (a fully inelastic collision) and the edge slides down the
next one's back face with Coulomb friction ``mu``. The fallen dominoes lean on each other
as a train driven by the newest one, so the train has one degree of freedom, the head's
tilt. Between collisions the train moves under gravity and the contact forces; each
collision is an impulse that brings the new domino into the train. The collision times
settle to a constant interval ``T`` and the wave speed is ``d / T``.

This module integrates those equations (numerically, with scipy) rather than quoting the
paper's curves, so the comparison in ``benchmarks/bench_wave.py`` is computed. It
imports no ROS and no Drake.
"""

from __future__ import annotations

import math
from dataclasses import dataclass

import numpy as np
from scipy.integrate import solve_ivp

GRAVITY = 9.81  # m/s²


@dataclass(frozen=True)
class Row:
    """A straight row: domino height and thickness [m], pitch [m], domino–domino friction."""

    height: float
    thickness: float
    pitch: float
    mu: float = 0.0

    def __post_init__(self) -> None:
        if not 0.0 < self.thickness < self.pitch < self.height + self.thickness:
            raise ValueError(
                "need 0 < thickness < pitch < height + thickness (else the dominoes touch "
                f"or a falling one misses the next): got {self}"
            )
        if self.mu < 0.0:
            raise ValueError(f"mu must be >= 0, got {self.mu}")

    @property
    def hit_angle(self) -> float:
        """Tilt [rad] at which a domino's top edge reaches the next one's back face."""
        return math.asin((self.pitch - self.thickness) / self.height)


@dataclass(frozen=True)
class Wave:
    crossings: np.ndarray  # s from the strike until domino k passed the threshold tilt
    hits: np.ndarray  # s from the strike until domino k + 1 was struck
    speed: float  # m/s: pitch over the steady interval between collisions


def _e_a(theta: np.ndarray) -> np.ndarray:
    """Each domino's forward face normal (unit, x-z plane) at tilt ``theta``."""
    return np.stack([np.cos(theta), -np.sin(theta)], axis=-1)


def _e_b(theta: np.ndarray) -> np.ndarray:
    """Each domino's up axis (unit, x-z plane) at tilt ``theta``."""
    return np.stack([np.sin(theta), np.cos(theta)], axis=-1)


class Train:
    """The leaning train of dominoes 0 … n (n the head) of a row; angles from the head's."""

    def __init__(self, row: Row, size: int):
        self.row, self.size = row, size
        self.inertia = (row.height**2 + row.thickness**2) / 3.0  # per unit mass, about the edge

    def angles(self, head: float) -> tuple[np.ndarray, np.ndarray]:
        """Tilts of dominoes 0 … n and their derivatives with respect to the head's tilt.

        Contact of domino i's top edge on i+1's back face:
        h·sin(θᵢ − θᵢ₊₁) = d·cos θᵢ₊₁ − w, solved for θᵢ going back from the head.
        """
        h, w, d = self.row.height, self.row.thickness, self.row.pitch
        theta = np.empty(self.size)
        slope = np.empty(self.size)
        theta[-1], slope[-1] = head, 1.0
        for i in range(self.size - 2, -1, -1):
            nxt = theta[i + 1]
            s = np.clip((d * math.cos(nxt) - w) / h, -1.0, 1.0)
            theta[i] = nxt + math.asin(s)
            dsin = -d * math.sin(nxt) / h  # d s / d θᵢ₊₁
            dtheta = 1.0 + dsin / max(math.sqrt(1.0 - s * s), 1e-12)
            slope[i] = dtheta * slope[i + 1]
        return theta, slope

    def _contact_terms(
        self, theta: np.ndarray, rate: np.ndarray
    ) -> tuple[np.ndarray, np.ndarray, np.ndarray]:
        """Per contact i (domino i's top edge on i+1's back face): the generalized forces
        of a unit normal force with its friction, the constraint's gradient and the
        velocity part of its second derivative (g = h·sin(a − b) − d·cos b + w = 0)."""
        h, w, d, mu = self.row.height, self.row.thickness, self.row.pitch, self.row.mu
        a, b, ra, rb = theta[:-1], theta[1:], rate[:-1], rate[1:]
        up = h * np.cos(a - b) - d * np.sin(b)  # contact, up i+1's face from its pivot
        up_rate = -h * np.sin(a - b) * (ra - rb) - d * np.cos(b) * rb
        slide = np.where(np.abs(up_rate) > 1e-9, np.sign(up_rate), -1.0)  # edge slides down
        force = _e_a(b) + (mu * slide)[:, None] * _e_b(b)  # on i+1, per unit normal force
        lever_next = w * _e_b(b) + up[:, None] * _e_a(b)  # d(contact on i+1)/d(tilt of i+1)
        lever_this = h * _e_a(a)  # d(top edge of i)/d(tilt of i)
        contacts = np.arange(self.size - 1)
        forces = np.zeros((self.size, self.size - 1))
        forces[contacts + 1, contacts] = np.sum(force * lever_next, axis=1)
        forces[contacts, contacts] = -np.sum(force * lever_this, axis=1)
        gradient = np.zeros((self.size - 1, self.size))
        gradient[contacts, contacts] = h * np.cos(a - b)
        gradient[contacts, contacts + 1] = -h * np.cos(a - b) + d * np.sin(b)
        curvature = -h * np.sin(a - b) * (ra - rb) ** 2 + d * np.cos(b) * rb**2
        return forces, gradient, curvature

    def gravity(self, theta: np.ndarray) -> np.ndarray:
        """Generalized gravity force per unit mass on each domino about its pivot."""
        h, w = self.row.height, self.row.thickness
        return -GRAVITY * (0.5 * w * np.cos(theta) - 0.5 * h * np.sin(theta))

    def acceleration(self, head: float, head_rate: float) -> float:
        """The head's angular acceleration (the train's equations with the contact forces)."""
        theta, slope = self.angles(head)
        rate = slope * head_rate
        n = self.size
        if n == 1:
            return float(self.gravity(theta)[0] / self.inertia)
        forces, gradient, curvature = self._contact_terms(theta, rate)
        system = np.zeros((2 * n - 1, 2 * n - 1))
        system[:n, :n] = self.inertia * np.eye(n)
        system[:n, n:] = -forces
        system[n:, :n] = gradient
        rhs = np.concatenate([self.gravity(theta), -curvature])
        return float(np.linalg.solve(system, rhs)[n - 1])

    def collide(self, head: float, head_rate: float) -> float:
        """The new head's tilt rate just after this train's head strikes the next domino.

        Fully inelastic: after the impulse every contact, the new one included, holds;
        the impulses carry friction as the contact forces do.
        """
        grown = Train(self.row, self.size + 1)
        theta, slope = self.angles(head)
        theta = np.append(theta, 0.0)
        before = np.append(slope * head_rate, 0.0)
        n = grown.size
        forces, gradient, _ = grown._contact_terms(theta, before)
        system = np.zeros((2 * n - 1, 2 * n - 1))
        system[:n, :n] = grown.inertia * np.eye(n)
        system[:n, n:] = -forces
        system[n:, :n] = gradient
        rhs = np.concatenate([grown.inertia * before, np.zeros(n - 1)])
        return float(np.linalg.solve(system, rhs)[n - 1])


def wave(
    row: Row,
    initial_rate: float,
    dominoes: int = 40,
    threshold: float = math.radians(2.0),
    train_limit: int = 20,
) -> Wave:
    """Topple ``dominoes`` of ``row``, the first from upright at ``initial_rate`` [rad/s]
    (the strike); the steady speed from the last third of the collisions.

    ``threshold`` [rad] must not exceed the hit angle: each domino passes it while it is
    the head. Dominoes more than ``train_limit`` behind the head lie on each other and
    barely move; leaving them out changes the speed by far less than 0.1 %.
    """
    if not 0.0 < threshold <= row.hit_angle:
        raise ValueError(f"threshold must be in (0, {row.hit_angle:.4f}] rad, got {threshold}")
    head, rate, now = 0.0, initial_rate, 0.0
    crossings, hits = [], []
    for struck in range(dominoes):
        train = Train(row, min(struck + 1, train_limit))

        def motion(_t: float, y: np.ndarray, train: Train = train) -> list[float]:
            return [y[1], train.acceleration(y[0], y[1])]

        def crossed(_t: float, y: np.ndarray) -> float:
            return y[0] - threshold

        def reached(_t: float, y: np.ndarray) -> float:
            return y[0] - row.hit_angle

        crossed.direction = reached.direction = 1.0
        reached.terminal = True
        solution = solve_ivp(
            motion, (0.0, 10.0), [head, rate], events=[crossed, reached], rtol=1e-8, atol=1e-10
        )
        if solution.t_events[0].size == 0 and head < threshold:
            raise RuntimeError(f"the wave stopped: domino {struck} never passed the threshold")
        crossings.append(now + float(solution.t_events[0][0]) if head < threshold else now)
        if struck == dominoes - 1:
            break
        if solution.status != 1:
            raise RuntimeError(f"the wave stopped: domino {struck + 1} was never struck")
        now += float(solution.t_events[1][0])
        hits.append(now)
        head, rate = 0.0, train.collide(row.hit_angle, float(solution.y_events[1][0][1]))
    steady = np.diff(hits)[-max(len(hits) // 3, 1) :]
    return Wave(np.array(crossings), np.array(hits), float(row.pitch / np.mean(steady)))

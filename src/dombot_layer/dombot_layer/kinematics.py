"""Forward and inverse kinematics of the domino layer (eqs (1)–(12) of the source).

Radii are signed: positive turns left (the centre O on the vehicle's left),
negative turns right, ``±inf`` drives straight. The source's equations are
written for a left turn; a right turn is their mirror image, in which the
deposit point's lateral offset ``d_t`` points the other way relative to O.

Forward: midpoint radius r_m → trolley angle θ, deposit point, deposit radius r_d,
by eqs (1)–(9). Inverse: exact and closed-form. The trolley wheel W rolls on a
circle about O, so O lies on W's axle line and the deposit point D sits ``d_l``
along the trolley and ``±d_t`` across it from that line:

    r_d² = d_l² + (R_w + s·d_t)²,   R_w² = r_m² + d_p² − d_tw²   (s = +1 left, −1 right)

with R_w the radius of W's circle. Both steps invert in closed form. Of the two
roots, R_w = √(r_d² − d_l²) − s·d_t lies on the *laying branch*, the one connected
to straight driving (r_m → ∞), on which r_d grows with r_m; steering continuously
out of a straight keeps the vehicle there, so it is the solution returned, and
``all_midpoint_radii`` also lists the other where it exists. The smallest |r_d| on
the laying branch is the minimum laying radius.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from enum import IntEnum
from typing import Literal, NamedTuple

import numpy as np

from dombot_layer.geometry import VehicleGeometry

Turn = Literal["left", "right", "both"]
FloatOrArray = float | np.ndarray
SquareRoot = Callable[[FloatOrArray], FloatOrArray]  # math.sqrt-like or np.sqrt
TURNS = {"left": 1.0, "right": -1.0}  # turn direction → sign of its radii


class UnreachableRadiusError(ValueError):
    """A deposit radius the vehicle cannot lay; ``reason`` says why."""

    def __init__(self, radius: float, reason: str) -> None:
        self.radius = radius
        self.reason = reason
        super().__init__(f"cannot lay dominoes on radius {float(radius):.6g} m: {reason}")


class RadiusStatus(IntEnum):
    """Per-radius outcome of the vectorized inverse; anything but REACHABLE is invalid."""

    REACHABLE = 0
    NAN = 1  # the requested radius is NaN
    ZERO = 2  # r_d = 0 has no turn direction
    BELOW_MINIMUM = 3  # |r_d| below the minimum laying radius for that turn
    SPIN_ON_THE_SPOT = 4  # needs r_m = 0, which no forward speed commands


class InverseResult(NamedTuple):
    """Vectorized inverse kinematics; ``midpoint_radius`` is NaN where not ``valid``."""

    midpoint_radius: np.ndarray
    valid: np.ndarray
    status: np.ndarray  # RadiusStatus values


@dataclass(frozen=True)
class ForwardResult:
    """Eqs (1)–(9) in the frame of the source: O at the origin, M at (0, |r_m|).

    ``x``/``y`` are the deposit point in that frame (x along the vehicle, pointing
    backwards, y from O through M); ``deposit_radius`` carries the turn's sign.
    """

    theta: np.ndarray | float
    x: np.ndarray | float
    y: np.ndarray | float
    deposit_radius: np.ndarray | float


def _sqrt_or_nan(value: float) -> float:
    """math.sqrt with numpy's domain behaviour: NaN instead of an exception."""
    return math.sqrt(value) if value >= 0.0 else math.nan


def _turn_sign(radius: np.ndarray | float) -> np.ndarray:
    """+1 for left turns (including +0 and +inf), −1 for right turns."""
    return np.where(np.signbit(radius), -1.0, 1.0)


def _arccos_limit_and_spin_radius(geometry: VehicleGeometry) -> tuple[float, float]:
    """(L, S): the smallest |r_m| eq. (8) allows, and R_w when r_m = 0; one is zero.

    R_w² = r_m² + d_p² − d_tw² = (r_m − L)(r_m + L) + S², written so that R_w is
    exactly zero at r_m = L instead of a rounding error that could be negative.
    """
    excess = geometry.d_tw**2 - geometry.d_p**2
    return math.sqrt(max(excess, 0.0)), math.sqrt(max(-excess, 0.0))


def trolley_wheel_radius(
    geometry: VehicleGeometry, midpoint_radius: np.ndarray | float
) -> np.ndarray | float:
    """R_w, radius of the trolley wheel's circle about O; NaN below the arccos limit."""
    limit, spin = _arccos_limit_and_spin_radius(geometry)
    r = np.abs(np.asarray(midpoint_radius, dtype=float))
    with np.errstate(invalid="ignore"):
        return np.sqrt((r - limit) * (r + limit) + spin * spin)


def forward(geometry: VehicleGeometry, midpoint_radius: np.ndarray | float) -> ForwardResult:
    """Eqs (1)–(9), vectorized; NaN where r_m is outside the arccos domain of eq. (8).

    θ = π − atan(r_m/d_p) − acos(d_tw/ρ) (eq. 9) is evaluated as
    atan2(d_p, r_m) + atan2(d_tw, R_w), the same angle: it avoids cancelling two
    angles near π/2 at large radii and an arccos argument rounded above 1 at the limit.
    """
    r_m = np.asarray(midpoint_radius, dtype=float)
    sign = _turn_sign(r_m)
    r = np.abs(r_m)
    theta = np.arctan2(geometry.d_p, r) + np.arctan2(
        geometry.d_tw, trolley_wheel_radius(geometry, r)
    )
    phi = np.arctan2(sign * geometry.d_t, geometry.d_l)  # eq. (4)
    z = geometry.deposit_offset  # eq. (5)
    x = geometry.d_p + geometry.d_tw * np.cos(theta) + z * np.cos(phi - theta)  # eq. (1)
    y = r - geometry.d_tw * np.sin(theta) + z * np.sin(phi - theta)  # eq. (2)
    r_d = sign * np.hypot(x, y)  # eq. (3); inf when r_m is
    if r_m.ndim == 0:
        return ForwardResult(float(theta), float(x), float(y), float(r_d))
    return ForwardResult(theta, x, y, r_d)


def deposit_radius(
    geometry: VehicleGeometry, midpoint_radius: np.ndarray | float
) -> np.ndarray | float:
    """r_d for r_m (signed); NaN outside the geometric domain."""
    return forward(geometry, midpoint_radius).deposit_radius


class LayerKinematics:
    """Inverse kinematics and domain limits of one vehicle geometry."""

    def __init__(self, geometry: VehicleGeometry) -> None:
        self.geometry = geometry
        self._limit, self._spin_radius = _arccos_limit_and_spin_radius(geometry)
        starts = {turn: self._branch_start(sign) for turn, sign in TURNS.items()}
        self._minimum = {turn: radius for turn, (radius, _) in starts.items()}
        # False where the branch starts at r_m = 0: its minimum needs spinning on the spot.
        self._minimum_is_laid = {turn: laid for turn, (_, laid) in starts.items()}

    @property
    def geometric_limit(self) -> float:
        """Smallest |r_m| for which eq. (8)'s arccos is defined (trolley wheel on O)."""
        return self._limit

    def _branch_start(self, sign: float) -> tuple[float, bool]:
        """|r_d| where the laying branch starts (R_w = max(S, −s·d_t)); is r_m > 0 there?"""
        outward = sign * self.geometry.d_t  # D's offset away from O, across the trolley
        start = max(self._spin_radius, -outward)
        midpoint = self._midpoint_from_wheel(start, _sqrt_or_nan)
        return math.hypot(self.geometry.d_l, start + outward), midpoint > 0.0

    def minimum_laying_radius(self, turn: Turn = "both") -> float:
        """Smallest |r_d| on the laying branch; 'both' gives the larger of the two turns."""
        if turn == "both":
            return max(self._minimum.values())
        if turn not in self._minimum:
            raise ValueError(f"turn must be 'left', 'right' or 'both', got {turn!r}")
        return self._minimum[turn]

    def _laying_midpoint(
        self, target: FloatOrArray, sign: FloatOrArray, sqrt: SquareRoot
    ) -> FloatOrArray:
        """|r_m| on the laying branch for |r_d| = ``target``; NaN where no real root exists.

        Written once for floats (``sqrt`` from math, ~1 µs) and arrays (numpy's).
        (r_d − d_l)(r_d + d_l) rather than r_d² − d_l² avoids cancellation near d_l.
        """
        g = self.geometry
        wheel = sqrt((target - g.d_l) * (target + g.d_l)) - sign * g.d_t  # R_w
        return self._midpoint_from_wheel(wheel, sqrt)

    def _midpoint_from_wheel(self, wheel: FloatOrArray, sqrt: SquareRoot) -> FloatOrArray:
        """|r_m| from R_w, the inverse of ``trolley_wheel_radius``; NaN where R_w < S."""
        spin = self._spin_radius
        return sqrt((wheel - spin) * (wheel + spin) + self._limit**2)

    def midpoint_radii(self, deposit_radii: np.ndarray | float) -> InverseResult:
        """Vectorized inverse kinematics on the laying branch, with a status per radius."""
        r_d = np.asarray(deposit_radii, dtype=float)
        sign = _turn_sign(r_d)
        target = np.abs(r_d)
        with np.errstate(invalid="ignore"):
            r_m = sign * self._laying_midpoint(target, sign, np.sqrt)
        left = sign > 0
        minimum = np.where(left, self._minimum["left"], self._minimum["right"])
        laid = np.where(left, self._minimum_is_laid["left"], self._minimum_is_laid["right"])
        spins = ~(np.abs(r_m) > 0.0) | ((target == minimum) & ~laid)
        status = np.select(
            [np.isnan(r_d), r_d == 0.0, target < minimum, spins],
            [
                RadiusStatus.NAN,
                RadiusStatus.ZERO,
                RadiusStatus.BELOW_MINIMUM,
                RadiusStatus.SPIN_ON_THE_SPOT,
            ],
            RadiusStatus.REACHABLE,
        )
        valid = status == RadiusStatus.REACHABLE
        return InverseResult(np.where(valid, r_m, np.nan), valid, status)

    def midpoint_radius(self, radius: float) -> float:
        """Inverse kinematics for one radius; raises ``UnreachableRadiusError`` with the reason.

        Same formula and validity test as ``midpoint_radii`` in plain floats; the
        array path only words the error.
        """
        r_d = float(radius)
        sign = math.copysign(1.0, r_d)
        turn = "left" if sign > 0 else "right"
        minimum = self._minimum[turn]
        if abs(r_d) > minimum or (abs(r_d) == minimum and self._minimum_is_laid[turn]):
            r_m = self._laying_midpoint(abs(r_d), sign, _sqrt_or_nan)
            if r_m > 0.0:
                return sign * r_m
        status = RadiusStatus(int(self.midpoint_radii(r_d).status))
        raise UnreachableRadiusError(radius, self._reason(status, r_d))

    def _reason(self, status: RadiusStatus, radius: float) -> str:
        turn = "right" if math.copysign(1.0, radius) < 0 else "left"
        minimum = f"the minimum laying radius {self._minimum[turn]:.6g} m of this geometry"
        return {
            RadiusStatus.NAN: "the radius is NaN",
            RadiusStatus.ZERO: "a zero radius has no turn direction",
            RadiusStatus.BELOW_MINIMUM: f"below {minimum} for a {turn} turn",
            RadiusStatus.SPIN_ON_THE_SPOT: (
                f"{minimum} for a {turn} turn needs turning on the spot (r_m = 0), "
                "which no forward speed commands"
            ),
        }[status]

    def all_midpoint_radii(self, radius: float) -> list[float]:
        """Every r_m (same turn direction) giving this r_d, the laying-branch one first.

        The second root R_w = −s·d_t − √(r_d² − d_l²) exists only where the deposit
        offset points at O (right turns for d_t > 0), for r_d up to z.
        """
        laying = self.midpoint_radius(radius)
        if math.isinf(laying):
            return [laying]
        target = abs(float(radius))
        sign = math.copysign(1.0, laying)
        root = math.sqrt((target - self.geometry.d_l) * (target + self.geometry.d_l))
        other_wheel = -sign * self.geometry.d_t - root
        if root == 0.0 or other_wheel < self._spin_radius:
            return [laying]
        other = self._midpoint_from_wheel(other_wheel, _sqrt_or_nan)
        return [laying, sign * other] if other > 0.0 else [laying]


def wheel_radii(
    geometry: VehicleGeometry, midpoint_radius: np.ndarray | float
) -> tuple[np.ndarray | float, np.ndarray | float]:
    """Eqs (10), (11): radii of the inner and outer drive wheels' circles (unsigned)."""
    r = np.abs(midpoint_radius)
    return r - geometry.d_w / 2.0, r + geometry.d_w / 2.0


def wheel_speed_ratio(
    geometry: VehicleGeometry, midpoint_radius: np.ndarray | float
) -> np.ndarray | float:
    """Eq. (12): inner/outer wheel speed, 1 when driving straight."""
    r = np.abs(np.asarray(midpoint_radius, dtype=float))
    with np.errstate(invalid="ignore"):
        ratio = np.where(np.isinf(r), 1.0, (r - geometry.d_w / 2.0) / (r + geometry.d_w / 2.0))
    return float(ratio) if np.ndim(midpoint_radius) == 0 else ratio


def wheel_angular_velocities(
    geometry: VehicleGeometry,
    midpoint_radius: np.ndarray | float,
    forward_speed: np.ndarray | float,
) -> tuple[np.ndarray | float, np.ndarray | float]:
    """Left and right wheel angular velocities [rad/s]; M moves at ``forward_speed`` m/s.

    With the signed r_m, the left wheel runs on r_m − d_w/2 and the right on
    r_m + d_w/2 for either turn direction: the vehicle's yaw rate is v / r_m.
    """
    curvature = 1.0 / np.asarray(midpoint_radius, dtype=float)
    speed = np.asarray(forward_speed, dtype=float)
    left = speed * (1.0 - curvature * geometry.d_w / 2.0) / geometry.wheel_radius
    right = speed * (1.0 + curvature * geometry.d_w / 2.0) / geometry.wheel_radius
    if np.ndim(midpoint_radius) == 0 and np.ndim(forward_speed) == 0:
        return float(left), float(right)
    return left, right

"""Forward and inverse kinematics of the domino layer (eqs (1)–(12) of the source).

Radii are signed: positive turns left (the centre O on the vehicle's left),
negative turns right, ``±inf`` drives straight. The source's equations are
written for a left turn; a right turn is their mirror image, in which the
deposit point's lateral offset ``d_t`` points the other way relative to O.

Forward: midpoint radius r_m → trolley angle θ, deposit point, deposit radius r_d.
Inverse: r_d → r_m on the *laying branch*, the r_m interval connected to straight
driving (r_m → ∞) on which r_d grows with r_m. Steering continuously from a
straight run into a curve keeps the vehicle on that branch, so that is the
solution returned; ``all_midpoint_radii`` lists the others where the geometry
has them. The smallest |r_d| on the branch is the minimum laying radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from functools import cached_property

import numpy as np
from scipy.optimize import brentq, minimize_scalar

from dombot_layer.geometry import VehicleGeometry

TABLE_SIZE = 4097  # samples of the laying branch used to start the vectorized inverse
MAX_NEWTON_STEPS = 80  # bisection fallback bound; ordinary radii converge in 2–4
FAR_RADIUS = 1e6  # m; beyond this the branch is r_d ≈ r_m + const to double precision


class UnreachableRadiusError(ValueError):
    """A deposit radius the vehicle cannot lay; ``reason`` says why."""

    def __init__(self, radius: float, reason: str) -> None:
        self.radius = radius
        self.reason = reason
        super().__init__(f"cannot lay dominoes on radius {radius!r} m: {reason}")


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


def _turn_sign(radius: np.ndarray | float) -> np.ndarray | float:
    return np.where(np.asarray(radius) < 0, -1.0, 1.0)


def forward(geometry: VehicleGeometry, midpoint_radius: np.ndarray | float) -> ForwardResult:
    """Eqs (1)–(9), vectorized; NaN where r_m is outside the geometric domain."""
    r_m = np.asarray(midpoint_radius, dtype=float)
    sign = _turn_sign(r_m)
    r = np.abs(r_m)
    with np.errstate(invalid="ignore", divide="ignore"):
        rho = np.hypot(r, geometry.d_p)
        # θ = π − atan(r/d_p) − acos(d_tw/ρ) (eq. 9), written as atan(d_p/r) + asin(d_tw/ρ)
        # to avoid cancelling two angles near π/2 on large radii.
        theta = np.arctan2(geometry.d_p, r) + np.arcsin(geometry.d_tw / rho)
        phi = np.arctan2(sign * geometry.d_t, geometry.d_l)  # eq. (4)
        z = geometry.deposit_offset  # eq. (5)
        x = geometry.d_p + geometry.d_tw * np.cos(theta) + z * np.cos(phi - theta)  # eq. (1)
        y = r - geometry.d_tw * np.sin(theta) + z * np.sin(phi - theta)  # eq. (2)
        r_d = sign * np.hypot(x, y)  # eq. (3)
    straight = np.isinf(r)
    r_d = np.where(straight, r_m, r_d)
    theta = np.where(straight, 0.0, theta)
    if np.ndim(midpoint_radius) == 0:
        return ForwardResult(float(theta), float(x), float(y), float(r_d))
    return ForwardResult(theta, x, y, r_d)


def deposit_radius(
    geometry: VehicleGeometry, midpoint_radius: np.ndarray | float
) -> np.ndarray | float:
    """r_d for r_m (signed); NaN outside the geometric domain."""
    return forward(geometry, midpoint_radius).deposit_radius


def _deposit_radius_scalar(geometry: VehicleGeometry, r: float, sign: float) -> float:
    """|r_d| for |r_m| = r with plain ``math``: ~1 µs, for the scalar root finder."""
    rho = math.hypot(r, geometry.d_p)
    theta = math.atan2(geometry.d_p, r) + math.asin(geometry.d_tw / rho)
    phi = math.atan2(sign * geometry.d_t, geometry.d_l)
    z = geometry.deposit_offset
    x = geometry.d_p + geometry.d_tw * math.cos(theta) + z * math.cos(phi - theta)
    y = r - geometry.d_tw * math.sin(theta) + z * math.sin(phi - theta)
    return math.hypot(x, y)


def _deposit_radius_slope(
    geometry: VehicleGeometry, r: np.ndarray, sign: float
) -> tuple[np.ndarray, np.ndarray]:
    """|r_d| and d|r_d|/d|r_m| by differentiating eqs (1)–(9), for Newton steps."""
    c, d_p = geometry.d_tw, geometry.d_p
    rho2 = r * r + d_p * d_p
    rho = np.sqrt(rho2)
    theta = np.arctan2(d_p, r) + np.arcsin(c / rho)
    dtheta = -d_p / rho2 - c * r / (rho2 * np.sqrt(np.maximum(rho2 - c * c, 1e-300)))
    phi = math.atan2(sign * geometry.d_t, geometry.d_l)
    z = geometry.deposit_offset
    cos_t, sin_t = np.cos(theta), np.sin(theta)
    cos_pt, sin_pt = np.cos(phi - theta), np.sin(phi - theta)
    x = d_p + c * cos_t + z * cos_pt
    y = r - c * sin_t + z * sin_pt
    dx = (-c * sin_t + z * sin_pt) * dtheta
    dy = 1.0 - (c * cos_t + z * cos_pt) * dtheta
    r_d = np.hypot(x, y)
    return r_d, (x * dx + y * dy) / r_d


@dataclass(frozen=True)
class _Branch:
    """The laying branch for one turn direction, sampled for fast inversion."""

    r_min: float  # smallest |r_m| on the branch
    r_d_min: float  # minimum laying radius |r_d|
    r_m_table: np.ndarray
    log_r_d_table: np.ndarray


class LayerKinematics:
    """Kinematics of one vehicle geometry; precomputes the laying branches once."""

    def __init__(self, geometry: VehicleGeometry) -> None:
        self.geometry = geometry

    @property
    def geometric_limit(self) -> float:
        """Smallest |r_m| for which eq. (8)'s arccos is defined (trolley wheel at O)."""
        g = self.geometry
        return math.sqrt(max(g.d_tw**2 - g.d_p**2, 0.0))

    @cached_property
    def _left(self) -> _Branch:
        return self._laying_branch(1.0)

    @cached_property
    def _right(self) -> _Branch:
        return self._laying_branch(-1.0)

    def _branch(self, sign: float) -> _Branch:
        return self._left if sign > 0 else self._right

    def _laying_branch(self, sign: float) -> _Branch:
        lower = max(self.geometric_limit, 1e-9)
        r_grid = np.geomspace(lower, FAR_RADIUS, 20001)
        r_d = np.abs(deposit_radius(self.geometry, sign * r_grid))
        falling = np.nonzero(np.diff(r_d) <= 0.0)[0]
        if falling.size:
            k = int(falling[-1]) + 1  # r_d rises monotonically from r_grid[k] on
            lo, hi = r_grid[max(k - 1, 0)], r_grid[min(k + 1, r_grid.size - 1)]
            best = minimize_scalar(
                lambda r: _deposit_radius_scalar(self.geometry, r, sign),
                bounds=(lo, hi),
                method="bounded",
                options={"xatol": 1e-13},
            )
            r_min = float(best.x)
        else:
            r_min = lower
        r_table = np.geomspace(r_min, FAR_RADIUS, TABLE_SIZE)
        r_d_table = np.abs(deposit_radius(self.geometry, sign * r_table))
        return _Branch(r_min, float(r_d_table[0]), r_table, np.log(r_d_table))

    def minimum_laying_radius(self, turn: str = "both") -> float:
        """Smallest |r_d| on the laying branch for 'left', 'right' or 'both' (the larger)."""
        if turn == "left":
            return self._left.r_d_min
        if turn == "right":
            return self._right.r_d_min
        return max(self._left.r_d_min, self._right.r_d_min)

    def midpoint_radius(self, radius: float) -> float:
        """Inverse kinematics for one radius: brentq on a bracket from the branch table."""
        r_d = float(radius)
        self._check_scalar(r_d)
        if math.isinf(r_d):
            return r_d
        sign = 1.0 if r_d > 0 else -1.0
        branch = self._branch(sign)
        target = abs(r_d)
        k = int(np.searchsorted(branch.log_r_d_table, math.log(target)))
        if k >= branch.r_m_table.size:
            lo, hi = branch.r_m_table[-1], target + 2 * self._rig_length
        else:
            lo, hi = branch.r_m_table[max(k - 1, 0)], branch.r_m_table[k]
        root = brentq(
            lambda r: _deposit_radius_scalar(self.geometry, r, sign) - target,
            lo,
            hi,
            xtol=1e-14,
            rtol=4 * np.finfo(float).eps,
        )
        return sign * root

    def _check_scalar(self, r_d: float) -> None:
        if math.isnan(r_d):
            raise UnreachableRadiusError(r_d, "the radius is NaN")
        if r_d == 0.0:
            raise UnreachableRadiusError(
                r_d, "a zero radius has no turn direction; the vehicle cannot turn on the spot"
            )
        if math.isinf(r_d):
            return
        turn = "left" if r_d > 0 else "right"
        minimum = self.minimum_laying_radius(turn)
        if abs(r_d) < minimum:
            raise UnreachableRadiusError(
                r_d,
                f"below the minimum laying radius {minimum:.6g} m of this geometry "
                f"for a {turn} turn",
            )

    def midpoint_radii(self, deposit_radii: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        """Vectorized inverse kinematics: (r_m, valid); r_m is NaN where not valid.

        A table lookup on the laying branch starts safeguarded Newton steps
        (clipped to the table bracket), which converge to round-off in a few steps.
        """
        r_d = np.asarray(deposit_radii, dtype=float)
        result = np.full(r_d.shape, np.nan)
        infinite = np.isinf(r_d)
        result[infinite] = r_d[infinite]
        valid = infinite.copy()
        for sign in (1.0, -1.0):
            branch = self._branch(sign)
            pick = np.isfinite(r_d) & (np.sign(r_d) == sign) & (np.abs(r_d) >= branch.r_d_min)
            if np.any(pick):
                result[pick] = sign * self._invert_on_branch(branch, np.abs(r_d[pick]), sign)
                valid |= pick
        return result, valid

    def _invert_on_branch(self, branch: _Branch, target: np.ndarray, sign: float) -> np.ndarray:
        log_target = np.log(target)
        table = branch.log_r_d_table
        k = np.clip(np.searchsorted(table, log_target), 1, table.size - 1)
        lo, hi = branch.r_m_table[k - 1], branch.r_m_table[k]
        beyond = log_target > table[-1]
        hi = np.where(beyond, target + 2 * self._rig_length, hi)
        lo = np.where(beyond, branch.r_m_table[-1], lo)
        weight = np.clip((log_target - table[k - 1]) / (table[k] - table[k - 1]), 0.0, 1.0)
        r = np.where(beyond, target, lo * (hi / lo) ** weight)
        return self._safeguarded_newton(r, lo, hi, target, sign)

    def _safeguarded_newton(
        self, r: np.ndarray, lo: np.ndarray, hi: np.ndarray, target: np.ndarray, sign: float
    ) -> np.ndarray:
        """Newton on a monotonic bracket; a step leaving the bracket bisects instead.

        Near the geometric limit dr_d/dr_m is unbounded and plain Newton stalls
        against the bracket, so the bracket shrinks on every step and bisection
        guarantees convergence there.
        """
        tolerance = 4 * np.finfo(float).eps * np.maximum(target, 1.0)
        active = np.arange(r.size)
        for _ in range(MAX_NEWTON_STEPS):
            value, slope = _deposit_radius_slope(self.geometry, r[active], sign)
            residual = value - target[active]
            done = np.abs(residual) <= tolerance[active]
            below = residual < 0
            lo[active] = np.where(below, r[active], lo[active])
            hi[active] = np.where(below, hi[active], r[active])
            with np.errstate(divide="ignore", invalid="ignore"):
                step = r[active] - residual / slope
            inside = (step > lo[active]) & (step < hi[active])
            r[active] = np.where(
                done, r[active], np.where(inside, step, 0.5 * (lo[active] + hi[active]))
            )
            active = active[~done]
            if active.size == 0:
                break
        return r

    @property
    def _rig_length(self) -> float:
        g = self.geometry
        return g.d_p + g.d_tw + g.deposit_offset

    def all_midpoint_radii(self, radius: float) -> list[float]:
        """Every r_m (same turn direction) with this r_d, laying-branch solution first."""
        r_d = float(radius)
        if not math.isfinite(r_d) or r_d == 0.0:
            self._check_scalar(r_d)
            return [r_d]
        sign = 1.0 if r_d > 0 else -1.0
        target = abs(r_d)
        branch = self._branch(sign)
        roots = []
        if target >= branch.r_d_min:
            roots.append(abs(self.midpoint_radius(r_d)))
        lower = max(self.geometric_limit, 1e-12)
        if branch.r_min > lower:
            grid = np.linspace(lower, branch.r_min, 2001)
            gap = np.abs(deposit_radius(self.geometry, sign * grid)) - target
            for i in np.nonzero(np.sign(gap[:-1]) * np.sign(gap[1:]) <= 0)[0]:
                if gap[i] == 0.0:
                    roots.append(float(grid[i]))
                elif gap[i + 1] != 0.0:
                    roots.append(
                        brentq(
                            lambda r: _deposit_radius_scalar(self.geometry, r, sign) - target,
                            grid[i],
                            grid[i + 1],
                            xtol=1e-14,
                        )
                    )
        if not roots:
            self._check_scalar(r_d)
        return [sign * r for r in roots]


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

"""Whether two footprints on the table meet: separating axes of their convex hulls (no ROS).

One test for the layout's overlapping dominoes (``layouts.validate``), a lying domino in
a slot's keep-out (``task.geometry.in_the_way``) and the dominoes a sweep carries along
(``debris.carried_along``). The hull is found exactly (Andrew's monotone chain), not
joggled, so a footprint touching another meets it whatever the order of its corners.
"""

from __future__ import annotations

import numpy as np


def hull(points: np.ndarray) -> np.ndarray:
    """The convex hull of ``points`` (N×2, any order, repeats allowed: a domino's eight
    corners seen from above) as its corners counter-clockwise, collinear ones left out."""
    ordered = sorted({(float(x), float(y)) for x, y in np.asarray(points, dtype=float)})
    if len(ordered) < 3:
        raise ValueError(f"a footprint needs 3 distinct points, not {len(ordered)}")

    def chain(sequence: list[tuple[float, float]]) -> list[tuple[float, float]]:
        kept: list[tuple[float, float]] = []
        for point in sequence:
            while len(kept) >= 2 and _turn(kept[-2], kept[-1], point) <= 0.0:
                kept.pop()
            kept.append(point)
        return kept[:-1]  # the last is the other chain's first

    corners = np.array(chain(ordered) + chain(ordered[::-1]))
    if len(corners) < 3:
        raise ValueError("a footprint needs an area: its points lie on a line")
    return corners


def _turn(o: tuple[float, float], a: tuple[float, float], b: tuple[float, float]) -> float:
    """> 0 when o → a → b turns counter-clockwise."""
    return (a[0] - o[0]) * (b[1] - o[1]) - (a[1] - o[1]) * (b[0] - o[0])


def footprints_meet(a: np.ndarray, b: np.ndarray, gap: float = 0.0) -> bool:
    """Whether the convex hulls of points ``a`` and ``b`` (N×2) come within ``gap`` [m] of
    each other: no edge normal of either hull has all of the other beyond ``gap`` (strictly;
    touching footprints meet). Exact at ``gap`` 0; beyond, near two corners it errs towards
    meeting (the corners' distance is more than their distance along either's normals)."""
    a, b = np.asarray(a, dtype=float), np.asarray(b, dtype=float)
    for points, other in ((a, b), (b, a)):
        corners = hull(points)
        edges = np.roll(corners, -1, axis=0) - corners
        normals = np.column_stack([edges[:, 1], -edges[:, 0]])  # outward: counter-clockwise
        normals /= np.linalg.norm(normals, axis=1, keepdims=True)
        beyond = other @ normals.T - np.sum(normals * corners, axis=1)  # points × edges
        if np.any(np.all(beyond > gap, axis=0)):
            return False
    return True

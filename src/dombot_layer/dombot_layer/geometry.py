"""The measured dimensions of the domino-laying vehicle, validated once.

Frame and lengths (docs/LAYER.md has the figure): the tractor is a
differential-drive vehicle; M is the midpoint of its front (drive) axle. The
trolley hangs on a pivot P that lies ``d_p`` behind M on the tractor's centre
line. The trolley's wheel axle is centred at W, ``d_tw`` behind P along the
trolley's centre line. The deposit point D, where a domino leaves the trolley,
lies ``d_l`` further back along the trolley's centre line from W and ``d_t``
across it: positive ``d_t`` is towards the vehicle's right. ``d_w`` is the
distance between the drive wheels, ``wheel_radius`` their radius.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, fields

MAX_DIMENSION = 100.0  # m: any larger vehicle dimension is a typo (and overflows eq. 9)


@dataclass(frozen=True)
class VehicleGeometry:
    """Lengths in metres; every one positive except ``d_t``, which may be zero or negative.

    The defaults are a small tabletop layer for 48 × 24 × 7.5 mm dominoes: 16 cm
    track, 6 cm wheels, a 15 cm trolley hitched 10 cm behind the drive axle, and
    a chute 4 cm behind the trolley axle and 2 cm to the right. ``d_p ≥ d_tw`` is
    accepted: eq. (8) then has no arccos limit and the tightest circle needs the
    tractor to spin on the spot, which the kinematics refuse as a target.
    """

    d_p: float = 0.10  # front-axle midpoint M → trolley pivot P, along the tractor
    d_tw: float = 0.15  # pivot P → trolley wheel axle W, along the trolley
    d_l: float = 0.04  # W → deposit point D, along the trolley (backwards)
    d_t: float = 0.02  # W → deposit point D, across the trolley (+ = vehicle's right)
    d_w: float = 0.16  # distance between the drive wheels
    wheel_radius: float = 0.03

    def __post_init__(self) -> None:
        for field in fields(self):
            value = getattr(self, field.name)
            if isinstance(value, bool) or not isinstance(value, int | float):
                raise ValueError(f"VehicleGeometry.{field.name} must be a number, got {value!r}")
            if not math.isfinite(value) or abs(value) > MAX_DIMENSION:
                raise ValueError(
                    f"VehicleGeometry.{field.name} must be finite and at most "
                    f"{MAX_DIMENSION} m, got {value}"
                )
            if field.name != "d_t" and value <= 0.0:
                raise ValueError(f"VehicleGeometry.{field.name} must be positive, got {value} m")

    @property
    def deposit_offset(self) -> float:
        """z of eq. (5): distance from the trolley wheel axle to the deposit point."""
        return math.hypot(self.d_l, self.d_t)

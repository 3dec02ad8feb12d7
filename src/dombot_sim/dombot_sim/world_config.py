"""What a CellWorld is built with (``WorldConfig``) and the contact models and
approximations it offers: checked when the config is made, before anything is built."""

from __future__ import annotations

from dataclasses import dataclass, field

from pydrake.multibody.plant import ContactModel, DiscreteContactApproximation

from dombot_description import DOMINO_SIZE
from dombot_sim.control import ArmGains, GripperSettings
from dombot_sim.sleeping import SleepSettings

CONTACT_MODELS = {
    "hydroelastic": ContactModel.kHydroelasticWithFallback,
    "point": ContactModel.kPoint,  # ignores the hydroelastic properties; for comparison
}
CONTACT_APPROXIMATIONS = {
    "tamsi": DiscreteContactApproximation.kTamsi,
    "sap": DiscreteContactApproximation.kSap,
    "similar": DiscreteContactApproximation.kSimilar,
    "lagged": DiscreteContactApproximation.kLagged,
}


@dataclass(frozen=True)
class WorldConfig:
    scenario_path: str | None = None  # None: dombot_description's default scenario
    time_step: float = 0.001  # s
    contact_approximation: str = "similar"
    contact_model: str = "hydroelastic"
    cameras: bool = True
    meshcat: bool = False
    domino_capacity: int = 30  # bodies in the plant; a larger reset rebuilds it
    # length, width, thickness [m]; another set (the wave benchmark's) keeps the density
    domino_size: tuple[float, float, float] = DOMINO_SIZE
    settle_limit: float = 10.0  # s simulated: a pile still moving after this is reported
    pour_wave_size: int = 6
    # while the cell is still (``CellWorld.still``) the clock advances without stepping
    skip_still: bool = True
    sleep: SleepSettings = field(default_factory=SleepSettings)
    arm_gains: ArmGains = field(default_factory=ArmGains)
    gripper: GripperSettings = field(default_factory=GripperSettings)

    def __post_init__(self) -> None:
        if not self.time_step > 0.0:
            raise ValueError(f"time_step must be positive, got {self.time_step}")
        if self.contact_approximation not in CONTACT_APPROXIMATIONS:
            raise ValueError(
                f"contact_approximation must be one of {sorted(CONTACT_APPROXIMATIONS)}, "
                f"got {self.contact_approximation!r}"
            )
        if self.contact_model not in CONTACT_MODELS:
            raise ValueError(
                f"contact_model must be one of {sorted(CONTACT_MODELS)}, got {self.contact_model!r}"
            )
        if len(self.domino_size) != 3 or not all(0.0 < x < 1.0 for x in self.domino_size):
            raise ValueError(f"domino_size must be 3 lengths in (0, 1) m, got {self.domino_size}")
        if self.domino_capacity < 0 or self.pour_wave_size < 1:
            raise ValueError("domino_capacity must be >= 0 and pour_wave_size >= 1")

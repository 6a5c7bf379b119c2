"""What hangs under the parachute: the two numbers the drag law needs, and where they came from.

The descent rate depends on the payload only through mass and Cd·A (drag coefficient times canopy
area), so a payload is those two numbers plus a note of their source. Nominal canopy areas are not
the same thing as effective Cd·A; the profiles below say which is which, because the calibration
work (``drs calibrate``) replaces these starting values with fitted ones.
"""

from __future__ import annotations

import math
from dataclasses import dataclass, replace

from predictor.errors import PredictorError

DRS_EFFECTIVE_CDA_M2 = 0.43
"""Chosen to reproduce the two 2019 DRS drops (Sirks et al. 2020, JINST 15 P05014: ~37 min from ~30 km).

It is 0.38 × (0.97 × nominal 4 ft area); the test payload's fitted 1.358 m² is 0.39 × (0.97 × nominal
7 ft area), so both Rocketman canopies fly at the same fraction of their nominal drag area.
"""


@dataclass(frozen=True)
class Payload:
    mass_kg: float
    cda_m2: float
    name: str = "custom"
    source: str = "given by the operator"

    def __post_init__(self) -> None:
        if not (math.isfinite(self.mass_kg) and self.mass_kg > 0.0):
            raise PredictorError(f"payload mass must be a positive number of kg, got {self.mass_kg!r}")
        if not (math.isfinite(self.cda_m2) and self.cda_m2 > 0.0):
            raise PredictorError(f"payload Cd·A must be a positive number of m², got {self.cda_m2!r}")

    def overridden(self, mass_kg: float | None = None, cda_m2: float | None = None) -> Payload:
        """The same profile with some values replaced; the source says which were replaced."""
        if mass_kg is None and cda_m2 is None:
            return self
        changed = [label for label, value in (("mass", mass_kg), ("Cd·A", cda_m2)) if value is not None]
        return replace(
            self,
            mass_kg=self.mass_kg if mass_kg is None else mass_kg,
            cda_m2=self.cda_m2 if cda_m2 is None else cda_m2,
            source=f"{self.source}; {' and '.join(changed)} overridden by the operator",
        )

    def to_dict(self) -> dict[str, object]:
        return {"name": self.name, "mass_kg": self.mass_kg, "cda_m2": self.cda_m2, "source": self.source}


PROFILES: dict[str, Payload] = {
    "drs": Payload(
        mass_kg=1.029,
        cda_m2=DRS_EFFECTIVE_CDA_M2,
        name="drs",
        source=(
            "DRS capsule, 1.029 kg under a 4 ft Rocketman (Sirks et al. 2020); effective Cd·A 0.43 m², "
            "the value that reproduces the paper's measured ~37 min fall from ~30 km in the standard "
            "atmosphere (0.97 × the nominal 4 ft area would give 1.13 m² and 60 min)"
        ),
    ),
    "superbit-test": Payload(
        mass_kg=1.608,
        cda_m2=1.358,
        name="superbit-test",
        source=(
            "SuperBIT 2018–2019 test payload under a 7 ft Rocketman; mass 1.608 kg and effective "
            "Cd·A 1.358 m² (0.97 × 1.4 m²) from pyBalloon param_file.py 2019-08, the values those flights "
            "were predicted with (the nominal 7 ft area would give Cd·A ≈ 3.5 m², far slower than measured)"
        ),
    ),
}


def payload_profile(name: str) -> Payload:
    try:
        return PROFILES[name]
    except KeyError:
        raise PredictorError(
            f"unknown payload profile {name!r}; known profiles: {', '.join(sorted(PROFILES))}"
        ) from None

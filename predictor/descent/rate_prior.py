"""What a flight's own rate factor λ is expected to be before any of its descent has been seen.

Why: payload, canopy, rigging and mass differ from flight to flight, so each descent falls at its own
multiple λ of the calibrated law's rate, while the law's *shape* (how the rate changes with height) is
shared. The calibration fits the shape with each flight's λ free and keeps the spread of those λ as
this prior: a pre-flight prediction flies the prior's median and carries its spread into the
descent-time and landing uncertainty; live re-prediction starts from it and updates it with the
flight's own descent. λ is log-normal across flights (a factor, never negative), so the prior is the
median and the standard deviation of ln λ.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from typing import Any

from predictor.errors import PredictorError

LOG_SIGMA_LIMITS = (0.0, 1.0)
"""ln λ spreads wider than ±1 (a factor e either way) are not a payload family, they are several."""
MEDIAN_LIMITS = (0.2, 5.0)
"""The same bounds the calibration fits a flight's λ within: outside them the law, not λ, is wrong."""


@dataclass(frozen=True)
class RatePrior:
    median: float
    """The typical λ across the calibration flights (the factor on the shape's rate)."""
    log_sigma: float
    """The standard deviation of ln λ across those flights: how far one flight's λ may be from the median."""
    flights: int
    """How many flights the prior was estimated from (its own uncertainty shrinks with it)."""

    def __post_init__(self) -> None:
        if not (MEDIAN_LIMITS[0] <= self.median <= MEDIAN_LIMITS[1]) or not math.isfinite(self.median):
            raise PredictorError(
                f"rate prior median λ {self.median!r} is outside {MEDIAN_LIMITS[0]}–{MEDIAN_LIMITS[1]}"
            )
        if not (LOG_SIGMA_LIMITS[0] <= self.log_sigma <= LOG_SIGMA_LIMITS[1]) or not math.isfinite(
            self.log_sigma
        ):
            raise PredictorError(
                f"rate prior log_sigma {self.log_sigma!r} is outside {LOG_SIGMA_LIMITS[0]}–{LOG_SIGMA_LIMITS[1]}"
            )
        if self.flights < 1:
            raise PredictorError(f"rate prior needs at least one flight, got {self.flights}")

    def to_dict(self) -> dict[str, Any]:
        return {"median": self.median, "log_sigma": self.log_sigma, "flights": self.flights}


@dataclass(frozen=True)
class PreflightSpread:
    """How far a flight's own λ falls from the λ a pre-flight prediction flies, measured held out.

    Why not the prior's sd: the prior is the spread about the median under the live law's shape, while
    before release the pre-flight gate may fly another law (on every training set so far the plain law,
    λ = 1, where the flights' median is not 1). A flight's λ then misses the flown one by the scatter
    AND by the median's offset from it, so the spread is the root mean square of ln(λᵢ / λ flown) over
    the calibration flights, each flown with the pre-flight law fitted without it.
    """

    log_sigma: float
    """RMS of ln(λᵢ / λ flown), held out."""
    flights: int

    def __post_init__(self) -> None:
        if not (LOG_SIGMA_LIMITS[0] <= self.log_sigma <= LOG_SIGMA_LIMITS[1]) or not math.isfinite(
            self.log_sigma
        ):
            raise PredictorError(
                f"pre-flight spread log_sigma {self.log_sigma!r} is outside {LOG_SIGMA_LIMITS[0]}–{LOG_SIGMA_LIMITS[1]}"
            )
        if self.flights < 1:
            raise PredictorError(f"pre-flight spread needs at least one flight, got {self.flights}")

    def to_dict(self) -> dict[str, Any]:
        return {"log_sigma": self.log_sigma, "flights": self.flights}

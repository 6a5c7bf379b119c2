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
        _check_spread("rate prior", self.log_sigma, self.flights)

    def to_dict(self) -> dict[str, Any]:
        return {"median": self.median, "log_sigma": self.log_sigma, "flights": self.flights}


@dataclass(frozen=True)
class PreflightSpread:
    """How far a flight's fall departs from what a pre-flight prediction flies, measured held out, as a
    σ of ln λ about the flown λ: the pre-flight descent-time interval flies λ·e^(±σ).

    Why not the prior's sd: the prior is the spread about the median under the live law's shape, while
    before release the pre-flight gate may fly another law (on every training set so far the plain law,
    λ = 1, where the flights' median is not 1), so a flight misses it by the scatter AND by the median's
    offset. So σ is measured on the calibration flights' descent times, each flown with the pre-flight
    law fitted without it: ln(predicted / measured descent time) is, for a law whose terms all scale the
    rate, exactly the λ the flight needed to land on time, about the flown one. Why the 68.3 % quantile
    of its size and not its root mean square (or that of each flight's own λ): the interval claims one
    flight in three outside, and a few large misses (a SuperBIT flight at λ 1.53) make the RMS a ±1σ
    that held 90 % of held-out flights (docs/calibration/preflight-held-out.md); the quantile held
    60–73 % on every split.
    """

    log_sigma: float
    """The |ln(predicted / measured descent time)| that 68.3 % of the held-out flights stay within."""
    flights: int

    def __post_init__(self) -> None:
        _check_spread("pre-flight spread", self.log_sigma, self.flights)

    def to_dict(self) -> dict[str, Any]:
        return {"log_sigma": self.log_sigma, "flights": self.flights}


def _check_spread(what: str, log_sigma: float, flights: int) -> None:
    """The checks a spread of ln λ shares, whichever law it is about: within ``LOG_SIGMA_LIMITS`` and
    measured on at least one flight."""
    if not (LOG_SIGMA_LIMITS[0] <= log_sigma <= LOG_SIGMA_LIMITS[1]) or not math.isfinite(log_sigma):
        raise PredictorError(
            f"{what} log_sigma {log_sigma!r} is outside {LOG_SIGMA_LIMITS[0]}–{LOG_SIGMA_LIMITS[1]}"
        )
    if flights < 1:
        raise PredictorError(f"{what} needs at least one flight, got {flights}")

"""What the spread of λ does to a pre-flight prediction: the descent time and landing at λ's ±1σ.

Why fly it and not scale it: a pre-flight prediction flies the model's pre-flight law with one λ (the
prior's median, or 1 where the pre-flight gate found the median no better held out), but the next
flight will fall at its own λ, e^(±σ) either side for one flight in three. σ is the model's
``preflight_spread``: the |ln(predicted / measured descent time)| that 68.3 % of the pre-flight law's
held-out predictions stay within, so the offset of the flights' median from a flown λ = 1 is in it (a file before schema 6 has none and
flies the prior's sd of ln λ, measured about the live law's median under its shape, which no longer
flies before release). Were every
term a factor on the rate, the fall time would be the median's × e^(∓σ) and no run would be needed; a
time-since-release term (a deployment delay) does not scale with λ, and where the landing goes depends
on how long each wind layer acts on the payload, which only a flight through the same weather tells. So
the model is flown twice more, at λ = median·e^(−σ) (slow, the latest landing) and median·e^(+σ)
(fast, the earliest): two runs of the same deterministic kernel, milliseconds each.

What it is not: a change to the landing ellipse. The model's ellipse was fitted on held-out flights
flown with the pre-flight law, so their λ scatter is already inside it; the interval says how much
of the descent-time and landing uncertainty is this one cause.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from typing import Any

from predictor.descent import DescentRateScale, Term
from predictor.prediction import GEOD, CalibratedModel, Prediction


@dataclass(frozen=True)
class PriorSpread:
    """The prediction flown at the rate prior's median and at its ±1σ of λ."""

    log_sigma: float
    """The σ of ln λ flown: the model's pre-flight spread (the prior's sd in a file without one)."""
    rate_factors: tuple[float, float]
    """λ at −1σ (slow) and +1σ (fast)."""
    descent_s: tuple[float, float, float]
    """Descent time at the slow λ, the median, the fast λ."""
    landing_shift_km: tuple[float, float]
    """How far the slow and the fast flight land from the median's landing."""

    def to_dict(self) -> dict[str, Any]:
        slow, median, fast = self.descent_s
        return {
            "what": "the model's pre-flight law flown at its λ and at λ·e^(±σ), σ the held-out spread of "
            "the flights' own λ about it: one flight in three falls outside; already inside the fitted "
            "ellipse, not added to it",
            "log_sigma": self.log_sigma,
            "rate_factor_slow": self.rate_factors[0],
            "rate_factor_fast": self.rate_factors[1],
            "descent_s": {"slow": slow, "median": median, "fast": fast},
            "descent_sigma_s": (slow - fast) / 2.0,
            "landing_shift_km": {"slow": self.landing_shift_km[0], "fast": self.landing_shift_km[1]},
        }

    def line(self) -> str:
        slow, median, fast = self.descent_s
        return (
            f"λ ±1σ     descent {fast / 60:.1f}–{slow / 60:.1f} min (±{(slow - fast) / 120:.1f} min "
            f"about {median / 60:.1f}) at λ {self.rate_factors[1]:.3g}–{self.rate_factors[0]:.3g} "
            f"(σ ln λ {self.log_sigma:.3g}); lands {self.landing_shift_km[1]:.2f} / "
            f"{self.landing_shift_km[0]:.2f} km from the median's (fast / slow)"
        )


def descent_spread(
    model: CalibratedModel, central: Prediction, fly: Callable[[tuple[Term, ...]], Prediction]
) -> PriorSpread | None:
    """The spread of ``central`` (flown with the model's pre-flight law) over λ; ``fly`` flies the same
    release with other terms. None when the model states no spread of λ (none is claimed)."""
    if model.preflight_spread is not None:
        sigma = model.preflight_spread.log_sigma
    elif model.rate_prior is not None:
        sigma = model.rate_prior.log_sigma
    else:
        return None
    # What a pre-flight prediction flies: the calibration saves its λ (the median under the pre-flight
    # terms, or 1 where the gate kept the median out) as the first term; a file without it flies λ = 1.
    law = model.preflight_law()
    first = law[0] if law else None
    median = float(first.scale) if isinstance(first, DescentRateScale) else 1.0
    shape = law[1:] if isinstance(first, DescentRateScale) else law
    factors = (median * math.exp(-sigma), median * math.exp(sigma))
    slow, fast = (fly((DescentRateScale(scale=factor), *shape)) for factor in factors)

    def shift_km(other: Prediction) -> float:
        here, there = central.landing, other.landing
        _, _, metres = GEOD.inv(here.lon, here.lat, there.lon, there.lat)
        return float(metres) / 1000.0

    return PriorSpread(
        log_sigma=sigma,
        rate_factors=factors,
        descent_s=(slow.descent_s, central.descent_s, fast.descent_s),
        landing_shift_km=(shift_km(slow), shift_km(fast)),
    )

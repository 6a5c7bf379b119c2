"""How much of the descent's own measured wind error to carry down: a gain learned from training flights.

Why: live re-prediction adds the wind error the descent measured over its last 2 km below the capsule
(decaying with L = 4 km, ``predictor.prediction.live``). Whether that error is still there in the air
the capsule has yet to fall through is a property of the weather and of how far from the descent the
forecast was measured, not a constant: on the real flights it carried (SuperBIT, EOSS), in a forecast
error field correlated over 2.5 km in height it did not (the hard independent worlds), and a fixed L
learned on one payload cannot tell the two apart. So the correction is flown times a gain g per report
height, learned from the training flights' own landings.

The landing predicted with a gain g is the landing without the wind plus g times the displacement D
the full correction adds (exactly so in a horizontally uniform cube, the weather of ``drs live
evaluate``: the added wind is a velocity summed into the drift, and it does not move the vertical).
So g is the least-squares slope of the training flights' landing miss without the wind,
m = truth − landing without the wind, on D (east and north in km): ĝ = Σ m·D / Σ |D|², flights being
the independent units. Its standard error σ is the sandwich one over the flights (no flight's D or
miss is assumed typical), and the gain flown is ĝ shrunk toward 0 by it, ĝ·(1 − σ²/ĝ²)₊ (the
empirical-Bayes mean under a normal prior on g centred on 0, no correction, whose width is what ĝ
says beyond its noise), held within 0–1: never against the measured error, never more than all of it.

Why shrunk toward 0 and not the least-squares slope: on 8–30 flights ĝ is noisy, and issue #30's
rule is that no choice learned on so few flights may make a flight worse than the plain restart; an
unsure gain gives up part of the correction, an unsure switch gives up none or all of it.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass

import numpy as np

from predictor.prediction import GEOD

GAIN_LIMITS = (0.0, 1.0)
"""The gain flown is held within these (none of the measured error carried, or all of it)."""


def local_km(lat0: float, lon0: float, lat: float, lon: float) -> np.ndarray:
    """(east, north) km of (lat, lon) from (lat0, lon0), along the geodesic's initial bearing."""
    azimuth, _, distance = GEOD.inv(lon0, lat0, lon, lat)
    angle = math.radians(float(azimuth))
    return np.array([math.sin(angle), math.cos(angle)]) * float(distance) / 1000.0


@dataclass(frozen=True)
class GainSample:
    """One training flight at one report height: its landing miss without the wind correction and the
    displacement the full correction adds, both (east, north) km from the landing without it."""

    miss_km: tuple[float, float]
    displacement_km: tuple[float, float]


@dataclass(frozen=True)
class GainFit:
    """The wind gain at one report height, as fitted on the training flights."""

    gain: float
    """Flown: ``raw`` shrunk toward 0 by ``sigma`` and held within ``GAIN_LIMITS``."""
    raw: float
    """ĝ, the least-squares slope (0 with no displacement to fit on)."""
    sigma: float
    """Its standard error over the flights (∞: fewer than 2 flights with a displacement)."""
    flights: int


def fit_gain(samples: Sequence[GainSample]) -> GainFit:
    """ĝ = Σ m·D / Σ |D|², its sandwich standard error over the flights, and the gain flown:
    ĝ·(1 − σ²/ĝ²)₊ within ``GAIN_LIMITS`` (the module docstring says why)."""
    m = np.array([s.miss_km for s in samples], dtype=float).reshape(-1, 2)
    d = np.array([s.displacement_km for s in samples], dtype=float).reshape(-1, 2)
    norm = float(np.sum(d * d))
    used = int(np.sum(np.any(d != 0.0, axis=1)))
    if norm <= 0.0 or used < 2:
        return GainFit(0.0, 0.0, math.inf, used)
    raw = float(np.sum(m * d)) / norm
    # Each flight's score D·(m − ĝD), squared and summed: the slope's variance with no assumption that
    # the residuals are alike from flight to flight; n / (n − 1) for the slope fitted on them.
    score = np.sum(d * (m - raw * d), axis=1)
    sigma = math.sqrt(float(score @ score) * used / (used - 1)) / norm
    # A slope against the measured error (raw ≤ 0) is held at none of it, never at a negative zero.
    shrunk = raw * max(0.0, 1.0 - sigma**2 / raw**2) if raw > 0.0 else GAIN_LIMITS[0]
    return GainFit(min(max(shrunk, GAIN_LIMITS[0]), GAIN_LIMITS[1]), raw, sigma, used)


def gained(lat0: float, lon0: float, lat1: float, lon1: float, gain: float) -> tuple[float, float]:
    """The landing ``gain`` of the way from (lat0, lon0), without the wind correction, to (lat1, lon1),
    with all of it: where the correction times ``gain`` lands in a horizontally uniform cube."""
    azimuth, _, distance = GEOD.inv(lon0, lat0, lon1, lat1)
    lon, lat, _ = GEOD.fwd(lon0, lat0, azimuth, gain * distance)
    return float(lat), float(lon)


def gain_sample(
    without: tuple[float, float], with_wind: tuple[float, float], truth: tuple[float, float]
) -> GainSample:
    """One flight's sample from its landings (lat, lon) without and with the full wind correction and
    its measured landing."""
    miss = local_km(*without, *truth)
    displacement = local_km(*without, *with_wind)
    return GainSample((float(miss[0]), float(miss[1])), (float(displacement[0]), float(displacement[1])))

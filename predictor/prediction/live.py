"""Live re-prediction during a descent: restart from each position report, and learn from the fall so far.

Why: during descent the capsule reports its position (every ~2 minutes over Iridium, every second from
a logger). Each report is the best possible release point for a new prediction (measured position,
altitude and time), and the reports so far measure two things the forecast got wrong:

* the **descent rate**: this flight's own factor λ on the flown model's descent law (its shape: the
  drag law with the terms a calibrated model carries). Payload, canopy, rigging and mass differ from
  flight to flight, so λ does too, while the shape is shared (``predictor.descent.RatePrior``). What
  the next prediction needs is λ of the descent still to come, so that is what is estimated: a
  Bayesian update (``update_rate``) of the prior for the rest of the descent at this height (the law
  itself, as wide as the evaluation flights' remaining λ was from it there) with the record's own
  measurement. The record is its time-at-altitude against the law from its top over the last
  ``RECORD_WINDOW_M`` (a Huber fit with a free time offset, each fix weighing the height it spans and at
  most one independent fix per ``INDEPENDENT_DROP_M``, so that a record of any cadence says the same;
  its variance widened for the correlated swing of a 1 Hz record), less how such a
  record's λ departs from the remaining descent's at this height, with that departure's spread
  (``RateDiscrepancy``, median and MAD over the evaluation flights). The posterior λ multiplies the
  law below the capsule (``DescentRateScale``) and its σ is stated beside the prediction;
* the **wind**: the measured mean velocity between two reports minus the forecast's mean velocity
  over the same altitudes. An error at altitude does not simply continue to the ground (the jet and
  the stratosphere are different air), so the recent error is applied below the capsule with a weight
  exp(−Δz / L) that decays with the altitude distance Δz from the capsule (``BinnedWind`` in 250 m
  bins), in the bands the model's live settings fly it in (``predictor.calibration.live_evaluation``:
  L = 4 km below 12.5 km above the ground), times a gain per report height (``WindGain``) that the
  model's own training flights learned: how much of the error measured above was still there below
  them, which depends on the weather and the forecast, not on the payload.

The ellipse shrinks with what is left: σ∥ and σ⊥ are the errors the model's own evaluation measured at
the report's height above the ground (``LiveErrorModel``); a model without live settings of its own
flies the SuperBIT evaluation's ellipse and every prediction says so (``LivePrediction.notes``).

Time-since-release terms (a canopy that opens late) keep counting from the release, never from the
report: each prediction from a report starts that long after the top of the descent record.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Protocol

import numpy as np

from predictor.descent import PROFILES, BinnedWind, DescentRateScale, Payload, RatePrior, Release, Term
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError
from predictor.prediction.landings import Prediction, Track, iso_z, predict
from predictor.prediction.setup import FlightSetup
from predictor.prediction.uncertainty import GEOD, LAUNCH, ErrorModel, parametric_ellipse

WIND_BIN_M = 250.0
RATE_FACTOR_LIMITS = (0.5, 2.0)
"""A measured rate factor outside this is a bad fix or a failed canopy, not a calibration."""
CONSTANT_WIND_M = 1e11
"""A decay length this long (JSON has no ∞) carries the measured wind error unchanged to the ground."""
MIN_PAIR_DROP_M = 200.0
"""Report pairs closer in altitude than this say too little about rate or wind (GNSS noise)."""
HUBER_K = 1.345
"""Huber's constant: 95 % efficiency on Gaussian residuals, bounded influence of a swing or a bad fix."""
FIT_ITERATIONS = 8
RECORD_WINDOW_M = 6000.0
"""λ is measured on the record's last 6 km of fall (at least its last two fixes), not from its top.

Why: a flight's departure from the law is not one number; on the SuperBIT flights it grows or shrinks
with height, so the recent fall says more about the rest than the whole record does. Chosen on those
30 flights, leave-one-flight-out, against the record from the top (held-out remaining-time error from
20 km 155 s against 170 s) and a 3 km window (149 s, but 10 km worse); docs/planning/live-reprediction.md."""
INDEPENDENT_DROP_M = 250.0
"""A record counts at most one independent fix per 250 m of fall, whatever its cadence.

Why: the fixes of a dense record are not independent (the capsule swings for tens of seconds, GNSS
altitude errors drift), and the record's departure from the rest of the descent, not its sampling
noise, is the error that matters (``RateDiscrepancy``). With each fix weighted by the height it spans
and the count capped by the height, a 1 Hz and a 5-minute record of one descent give the same λ and
nearly the same σ; counted fix by fix, a 1 Hz record claimed a σ of a fraction of a percent and the
prior no longer counted."""
CHECK_DROPS_M = (1500.0, 3000.0)
"""How far above a report the flight's own evidence asks each candidate to predict the fall to it."""
CHECK_GRID_M = 250.0
MAX_LAG1_CORRELATION = 0.98
"""The correlation of consecutive residuals is capped here: a record that is one smooth swing still
counts as at least 1 % of its fixes."""


def by_height(height_km: float, heights_km: Sequence[float], column: Sequence[float]) -> float:
    """A table measured at a few heights, read at any: linear between them, held beyond them."""
    order = np.argsort(heights_km)
    return float(np.interp(height_km, np.asarray(heights_km)[order], np.asarray(column)[order]))


DISTANCE_RATIO_LIMITS = (0.2, 5.0)
"""X / X̄ is held within these: the ellipse grows with the distance at most 5^β-fold, and never
shrinks to nothing on a descent right beside its ascent."""
LIVE_PROBABILITIES = (0.6827, 0.9545)
"""The contours every live ellipse carries beside the standard n-σ ones: the regions that hold 68.3 %
and 95.4 % of a bivariate normal (n = 1.515 and 2.486). What issue #30's "the live ellipse's 1σ holds
60–75 %, its 2σ 80–95 %" is read as: the 1-D meaning of 1σ and 2σ (68 %, 95 %), carried to two
dimensions as the contour of that probability, not the n = 1 ellipse (39.3 %). The files say so in
each contour's ``probability``; the held-out coverage of these two contours is in every live report."""


@dataclass(frozen=True)
class LiveErrorModel:
    """σ∥ and σ⊥ (km, along and across the report→landing bearing) against height above the ground,
    widened by how far from the descent still to come its winds were measured; and the σ of the law's
    remaining time beyond λ's own.

    Measured, not modelled: at each checkpoint of the real-flight evaluation, σ = a(h)·(X / X̄(h))^β,
    a(h) per height and one β over all of them, by maximum likelihood on the errors of what ships,
    then scaled so that the 68.3 % region holds 68.3 % of those flights
    (``predictor.calibration.live_evaluation.fit_live_sigma``); linear in height between checkpoints
    and held beyond them. X (km·h) is the distance between the predicted path below the report and
    where its altitudes' winds were measured (``WeatherCube.measured_along``), integrated over the fall
    (``ascent_distance_km_h``); X̄(h) the evaluation flights' RMS X at that height, which weather that
    does not say where it was measured (a forecast) flies. Squared-error fits of σ0 + drift forms were
    tried and dominated by a few large misses high up, which left 3 km of σ at the ground; a table per
    height keeps each height honest. A table without β (a file written before the widened ellipse) is σ(h) alone.
    """

    heights_km: tuple[float, ...]
    sigma_parallel_km: tuple[float, ...]
    sigma_perpendicular_km: tuple[float, ...]
    growth_exponent: float = 0.0
    """β: σ grows as (X / X̄(h))^β (0: not with the distance)."""
    typical_km_h: tuple[float, ...] = ()
    """X̄(h), the evaluation flights' RMS X per height (empty: not measured)."""
    time_log_sigma: tuple[float, ...] = ()
    """Per height, the σ of ln(remaining time) the law's error adds to λ's own (empty: not measured):
    the smallest that, added in quadrature, puts 68.3 % of the evaluation flights' remaining time within
    1σ at that height (a quantile, not a normal's σ: the errors have heavy tails)."""

    def at(self, height_km: float, distance_km_h: float | None = None) -> ErrorModel:
        """The ``ErrorModel`` that ``predict`` uses for a report at this height (no drift or lead term),
        with X = ``distance_km_h`` (None: X̄ at this height)."""
        factor = 1.0
        if distance_km_h is not None and self.typical_km_h and self.growth_exponent:
            typical = by_height(height_km, self.heights_km, self.typical_km_h)
            low, high = DISTANCE_RATIO_LIMITS
            factor = min(max(distance_km_h / max(typical, 1e-9), low), high) ** self.growth_exponent
        parallel = factor * by_height(height_km, self.heights_km, self.sigma_parallel_km)
        perpendicular = factor * by_height(height_km, self.heights_km, self.sigma_perpendicular_km)
        return ErrorModel(
            sigma0_km=parallel, h=0.0, k_km2_per_h2=0.0, q=parallel / perpendicular, name="live"
        )

    def time_sigma_at(self, height_km: float) -> float | None:
        """The law's own σ of ln(remaining time) at this height (None: not measured)."""
        if not self.time_log_sigma:
            return None
        return by_height(height_km, self.heights_km, self.time_log_sigma)


def ascent_distance_km_h(track: Track, measured_along: np.ndarray) -> float:
    """X: the horizontal distance (km) between the predicted path and where the winds at each of its
    altitudes were measured, integrated over the fall (km·h). Sampled evenly in time, so X is the mean
    distance times the hours of the fall; altitudes beyond the measured track take its nearest end (the
    cube repeats the nearest measured layer there)."""
    if track.t_s.size < 2 or track.t_s[-1] <= track.t_s[0]:
        return 0.0
    t = np.linspace(float(track.t_s[0]), float(track.t_s[-1]), 24)
    z = np.interp(t, track.t_s, track.alt_m)
    lat = np.interp(t, track.t_s, track.lat)
    lon = np.interp(t, track.t_s, np.unwrap(track.lon, period=360.0))
    alt_m, lat_m = measured_along[:, 0], measured_along[:, 1]
    lon_m = np.unwrap(measured_along[:, 2], period=360.0)  # an ascent across ±180° interpolates across it
    _, _, distance_m = GEOD.inv(lon, lat, np.interp(z, alt_m, lon_m), np.interp(z, alt_m, lat_m))
    return float(np.mean(distance_m) / 1000.0 * (t[-1] - t[0]) / 3600.0)


LIVE_ERROR_MODEL = LiveErrorModel(
    heights_km=(25.0, 20.0, 15.0, 10.0, 5.0, 2.0),
    sigma_parallel_km=(4.569, 3.697, 3.259, 3.607, 2.01, 1.429),
    sigma_perpendicular_km=(3.711, 3.878, 3.779, 2.759, 1.429, 1.197),
    growth_exponent=0.525,
    typical_km_h=(50.6, 51.42, 49.02, 41.94, 27.03, 10.74),
    time_log_sigma=(0.1, 0.01, 0.0575, 0.05, 0.055, 0.0975),
)
"""The default live ellipse, for a law without live settings of its own (said in every prediction,
``DEFAULT_ELLIPSE_NOTE``): measured by ``drs live evaluate`` on the 30 SuperBIT test flights with the
2018–2019 model, of what ships (docs/planning/live-reprediction.md); the committed model file carries
the same."""


class Report(Protocol):
    """A position report (a calibration ``Fix``, an Iridium position, a GNSS sample); read-only, so
    frozen dataclasses qualify."""

    @property
    def time(self) -> datetime: ...
    @property
    def lat(self) -> float: ...
    @property
    def lon(self) -> float: ...
    @property
    def alt_m(self) -> float: ...


@dataclass(frozen=True)
class RateDiscrepancy:
    """What a descent record down to a height says about the λ of the descent still to come, measured
    by height across the model's evaluation flights.

    * ``log_bias``/``log_sigma``: median and spread (1.4826 × MAD) of ln(record λ / remaining λ). A
      law's shape is never exact, and a record falls a little faster or slower than the rest of the
      descent in much the same way on most flights; that shared departure is taken off the
      measurement, and its flight-to-flight spread widens the measurement's variance. Median and MAD,
      not mean and standard deviation: the few flights whose canopy misbehaves would otherwise make
      every record look untrustworthy, and the update would cling to the prior exactly when a flight
      is unlike the others.
    * ``remaining_log_mean``/``remaining_log_sigma``/``remaining_flights``: the prior for the rest of
      the descent at this height (mean and standard deviation of the remaining λ across the flights).
      Empty in a model evaluated before they were measured: the model's whole-descent prior stands in.

    Measured by ``drs live evaluate`` with the model's own law; linear in height between the table's
    heights, held beyond them.
    """

    heights_km: tuple[float, ...]
    log_bias: tuple[float, ...]
    log_sigma: tuple[float, ...]
    remaining_log_mean: tuple[float, ...] = ()
    remaining_log_sigma: tuple[float, ...] = ()
    remaining_flights: tuple[int, ...] = ()

    def at(self, height_km: float) -> tuple[float, float]:
        """(median, spread) of ln(record λ / remaining λ) at this height above the ground."""
        return by_height(height_km, self.heights_km, self.log_bias), by_height(
            height_km, self.heights_km, self.log_sigma
        )

    def remaining_prior(self, height_km: float) -> RatePrior | None:
        """The prior of the remaining descent's λ at this height (None: not measured): centred on the
        law (λ = 1), as wide as the evaluation flights' remaining λ was from it (root mean square of
        ln λ: their mean departure counted as spread, not taken off).

        Why centred on the law: the mean is the one thing that did not carry from one season or payload
        to another, while its size did (docs/planning/rate_estimators.py: 2018 → 2019 from 20 km 0.99×
        the plain restart's remaining-time error with the 2018 mean as the prior, 0.89× centred on the
        law); the plain restart (λ = 1) is then what the update starts from, and it leaves it only as
        far as the record says (docs/planning.md, issue #30)."""
        if not self.remaining_log_mean:
            return None
        mean = by_height(height_km, self.heights_km, self.remaining_log_mean)
        sigma = by_height(height_km, self.heights_km, self.remaining_log_sigma)
        return RatePrior(1.0, math.hypot(mean, sigma), min(self.remaining_flights))


NO_DISCREPANCY = RateDiscrepancy((0.0,), (0.0,), (0.0,))
"""A record taken at its word: no departure. Only for tests and the evaluation's own laws before they
are measured; a model without live settings flies ``DEFAULT_DISCREPANCY``, never this."""

DEFAULT_DISCREPANCY = RateDiscrepancy(
    heights_km=(1.0, 3.5, 6.0, 8.5, 11.0, 13.5, 16.0, 18.5, 21.0, 23.5, 26.0, 28.5),
    log_bias=(0.0,) * 12,
    log_sigma=(0.125, 0.1, 0.115, 0.105, 0.1, 0.113, 0.153, 0.176, 0.217, 0.217, 0.217, 0.198),
    remaining_log_mean=(0.0,) * 12,
    remaining_log_sigma=(0.282, 0.256, 0.235, 0.218, 0.191, 0.183, 0.176, 0.174, 0.176, 0.177, 0.188, 0.207),
    remaining_flights=(7,) * 12,
)
"""How far a record's λ may be from the remaining descent's, and the remaining λ's prior, for a model
without live settings of its own: conservative, so that neither a dense record (a 1 Hz record's fit σ
is a fraction of a percent) nor a pooled λ decides alone. Measured on two payloads' real flights (the
30 SuperBIT flights and the 10 EOSS flights with a landing, tests/data/eoss), on the model and textbook
laws (``measured_discrepancies``): at each height the largest root-mean-square log departure of a
record from the remaining descent (√(median² + spread²): a law's median departure is its shape error,
unknown for a law not evaluated live, so it is counted as spread, not taken off), and as the prior the
law itself (λ = 1) with the largest root-mean-square remaining ln λ as its width
(``conservative_discrepancy``; command in docs/planning.md). On SuperBIT alone the spread was 7–15 %,
EOSS's payload on the SuperBIT law widens it to 10–22 % and the prior to 17–28 %."""


@dataclass(frozen=True)
class Band:
    """What to correct while the capsule is between two heights above the ground (m)."""

    lower_m: float
    upper_m: float
    use_rate: bool
    decay_m: float | None
    """Decay length L of the wind correction (None: no wind correction in this band)."""

    def describe(self) -> str:
        """The band for a person: heights, the rate update, the wind correction."""
        lower = "ground" if not math.isfinite(self.lower_m) else f"{self.lower_m / 1000:g} km"
        upper = "top" if not math.isfinite(self.upper_m) else f"{self.upper_m / 1000:g} km"
        rate = "own λ updated" if self.use_rate else "rate off"
        if self.decay_m is None:
            wind = "off"
        else:
            wind = (
                "L = ∞ (constant)" if self.decay_m >= CONSTANT_WIND_M else f"L = {self.decay_m / 1000:g} km"
            )
        return f"{lower}–{upper}: {rate}, wind {wind}"


@dataclass(frozen=True)
class WindGain:
    """How much of the measured wind error is carried below the capsule, by its height above the ground.

    The training flights' own answer, not a constant: per report height, the least-squares slope of
    their landing miss without the wind correction on the displacement the whole correction adds,
    shrunk toward 0 by its uncertainty over the flights and held within 0–1
    (``predictor.calibration.wind_gain``). Where the wind error measured above carried on down on those
    flights it is near 1; where it did not (a forecast error that changes within a few km of height) near
    0. Linear in height between the table's heights, held beyond them.
    """

    heights_km: tuple[float, ...]
    gains: tuple[float, ...]

    def at(self, height_km: float) -> float:
        """The gain for a report at this height above the ground."""
        return by_height(height_km, self.heights_km, self.gains)


@dataclass(frozen=True)
class LiveCorrection:
    """How the measured descent corrects the rest of it, by the capsule's height above the ground.

    Outside every band nothing is corrected (a plain re-prediction from the report).
    """

    bands: tuple[Band, ...] = ()
    wind_window_m: float = 2000.0
    wind_gain: WindGain | None = None
    """The share of the measured wind error a band's wind correction carries down (None: all of it, as
    every correction flew before the gain was learned, and as a model file without one still flies)."""

    @classmethod
    def everywhere(cls, use_rate: bool, decay_m: float | None) -> LiveCorrection:
        return cls(bands=(Band(-math.inf, math.inf, use_rate, decay_m),))

    def band_at(self, height_m: float) -> Band | None:
        for band in self.bands:
            if band.lower_m <= height_m < band.upper_m:
                return band
        return None


NO_CORRECTION = LiveCorrection()
OWN_RATE = LiveCorrection.everywhere(True, None)
"""A model without live settings of its own: its shape with this flight's own λ update at every height,
no wind correction (nothing measured says where one would help)."""


@dataclass(frozen=True)
class LiveSettings:
    """How live re-prediction corrects one model's law, and how sure it then is: what the evaluation kept.

    All belong to the law they were measured with, so a model file carries its own (``drs live
    evaluate --model M --save-model``); a model without them flies ``OWN_RATE`` and says so.
    """

    correction: LiveCorrection
    error_model: LiveErrorModel
    discrepancy: RateDiscrepancy = NO_DISCREPANCY
    prior: RatePrior | None = None
    """The λ prior the evaluation measured (the flights' whole-descent λ on this law), flown when the
    model's calibration gave it none of its own."""
    law: str = "model"
    """The law the bands correct (``LIVE_LAWS``): ``model``, the model's own terms, or ``payload``, the
    payload's drag law with no calibrated term (the plain restart from the nominal payload), which this
    flight's own λ then corrects. ``discrepancy`` and ``prior`` were measured on that law. ``drs live
    evaluate`` ships the model's law only where, on its flights, it beat the payload's with the same λ
    beyond its 95 % interval (docs/planning.md, issue #30: on the real flights it never did)."""
    restart: str = "model"
    """The law flown outside every band (``LIVE_LAWS``): ``payload``, the plain restart from the nominal
    payload (what ``drs live evaluate`` writes since schema 5: never a stale pooled λ), or ``model``,
    the model's terms (a file written before schema 5, as it flew)."""


LIVE_LAWS = ("model", "payload")
"""What ``LiveSettings.law`` may name."""

DEFAULT_ELLIPSE_NOTE = "live ellipse: the default (measured with the SuperBIT model, not this one; drs live evaluate --save-model)"


@dataclass(frozen=True)
class Leg:
    """What one pair of consecutive reports measured, against the model over the same altitudes."""

    top_m: float
    bottom_m: float
    observed_s: float
    model_s: float
    observed_east_ms: float
    observed_north_ms: float
    forecast_east_ms: float
    forecast_north_ms: float

    @property
    def rate_factor(self) -> float:
        return self.model_s / self.observed_s

    @property
    def wind_error(self) -> tuple[float, float]:
        return self.observed_east_ms - self.forecast_east_ms, self.observed_north_ms - self.forecast_north_ms


@dataclass(frozen=True)
class RateFit:
    """The descent so far against the flown law: seconds since the record's top = model seconds / λ + offset.

    The offset absorbs what happened once near the top (a canopy that opened late, a first fix taken
    mid-swing), so that only the steady rate sets λ.
    """

    factor: float
    """λ, the factor on the law's descent rate (> 1: falling faster than the model)."""
    offset_s: float
    fixes: int
    """How many fixes the fit used."""
    scale_s: float
    """Robust spread of the time residuals (1.4826 × MAD), s."""
    log_sigma: float
    """Standard error of ln λ, widened for residuals correlated from fix to fix (a swing, a slow drift)."""


def fit_rate(
    observed_s: np.ndarray, model_s: np.ndarray, weights: np.ndarray | None = None
) -> RateFit | None:
    """Huber fit of observed = model / λ + offset by iteratively reweighted least squares.

    ``weights``: each fix's share of the record (default: one each), scaled so that they sum to the
    number of independent fixes the record holds (``DescentRecord.rate_fit`` gives height spans).

    Why Huber and not least squares: a 1 Hz record swings under its canopy and a tracker logs the odd
    wild fix; squared errors let a few of those set λ, a bounded weight does not. Every fix is used,
    vectorised (a 10,000-fix record costs well under a millisecond per iteration). None when the
    record is too short in model time to say anything (less than two fixes or a degenerate span).
    """
    if observed_s.size < 2 or float(np.ptp(model_s)) <= 0.0:
        return None
    design = np.column_stack((model_s, np.ones_like(model_s)))
    prior_weights = np.ones_like(model_s) if weights is None else np.asarray(weights, dtype=float)
    weights = prior_weights
    coef = np.zeros(2)
    scale = 1.0
    for _ in range(FIT_ITERATIONS):
        coef = _weighted_line(model_s, observed_s, weights)
        residual = observed_s - design @ coef
        # A floor of 1 s, the resolution of a fix's time stamp: a near-perfect fit must not make
        # every fix an outlier.
        scale = max(1.4826 * _median(np.abs(residual - _median(residual))), 1.0)
        u = np.abs(residual) / (HUBER_K * scale)
        weights = prior_weights * np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-12))
    if coef[0] <= 0.0:
        return None
    count = float(prior_weights.sum())
    return RateFit(float(1.0 / coef[0]), float(coef[1]), int(observed_s.size), scale,
                   _log_sigma(design, weights, residual, scale, float(coef[0]), count))  # fmt: skip


def _median(values: np.ndarray) -> float:
    """``np.median`` of a 1-D array, the same number, without its wrapper: the evaluations fit tens of
    thousands of short records, and ``np.median``'s generic path cost ten times its partition there."""
    n = values.size
    mid = n // 2
    if n % 2:
        middle = np.partition(values, mid)[mid]
    else:
        pair = np.partition(values, (mid - 1, mid))[mid - 1 : mid + 1]
        middle = (pair[0] + pair[1]) / 2.0
    return float(middle) if not np.isnan(values).any() else math.nan


def _weighted_line(x: np.ndarray, y: np.ndarray, w: np.ndarray) -> np.ndarray:
    """(slope, intercept) of the weighted least-squares line, in closed form (the 2×2 normal equations
    on centred sums: as exact as a QR solve here, and a fraction of its cost on a 10,000-fix record)."""
    total = float(w.sum())
    x_mean, y_mean = float(w @ x) / total, float(w @ y) / total
    dx = x - x_mean
    sxx = float(w @ (dx * dx))
    slope = float(w @ (dx * (y - y_mean))) / sxx if sxx > 0.0 else 0.0
    return np.array([slope, y_mean - slope * x_mean])


def _log_sigma(
    design: np.ndarray, weights: np.ndarray, residual: np.ndarray, scale: float, slope: float, count: float
) -> float:
    """σ of ln λ = σ(slope) / slope, with the weighted least-squares variance of the slope times
    (1 + ρ) / (1 − ρ), ρ the correlation of consecutive residuals.

    Why the factor: the fixes of a 1 Hz record are not independent (the capsule swings under its
    canopy for tens of seconds, GNSS errors drift), and counted as independent they would make the
    record look hundreds of times surer than it is; an AR(1) inflation is the textbook correction.
    """
    weighted = design * weights[:, None]
    try:
        # scale² × n / (n − 2): two parameters were fitted on these residuals. A line through two fixes
        # leaves none, and its scale is the 1 s floor: the spread the evaluation measured across
        # flights for records as short (``RateDiscrepancy``) is then what says how far off it can be.
        covariance = np.linalg.inv(design.T @ weighted) * scale**2 * count / max(count - 2.0, 1.0)
    except np.linalg.LinAlgError:
        return math.inf
    rho = 0.0
    if residual.size > 2:
        centred = residual - residual.mean()
        denominator = float(centred @ centred)
        if denominator > 0.0:
            rho = min(max(float(centred[1:] @ centred[:-1]) / denominator, 0.0), MAX_LAG1_CORRELATION)
    variance = float(covariance[0, 0]) * (1.0 + rho) / (1.0 - rho)
    return math.sqrt(max(variance, 0.0)) / slope


@dataclass(frozen=True)
class RateEstimate:
    """This flight's λ after the update, and how sure of it the update is."""

    factor: float
    """The λ flown below the capsule (the posterior median, held within ``RATE_FACTOR_LIMITS``)."""
    log_sigma: float
    """Posterior standard deviation of ln λ (∞: no prior and no usable record)."""
    measured: float | None
    """λ the record alone says, before the discrepancy and the prior (None: too little record)."""
    fixes: int
    prior: RatePrior | None

    def describe(self) -> str:
        """λ for a person: the posterior, what the record and the prior said."""
        sigma = "" if math.isinf(self.log_sigma) else f" ± {100 * self.log_sigma:.1f} %"
        record = f"record {self.measured:.3f} on {self.fixes} fixes" if self.measured else "no record yet"
        prior = (
            f"prior {self.prior.median:.3f} ± {100 * self.prior.log_sigma:.1f} % ({self.prior.flights} flights)"
            if self.prior
            else "no prior: from this descent alone"
        )
        return f"λ {self.factor:.3f}{sigma} ({record}; {prior})"


def update_rate(
    prior: RatePrior | None, fit: RateFit | None, log_bias: float, log_spread: float
) -> RateEstimate:
    """The posterior of ln λ: the prior's normal times the record's, in closed form (both are normal in ln λ).

    The record measures ln λ + ``log_bias`` with variance σ_fit² + ``log_spread``²; without a prior
    the record alone decides, without a record the prior does, and with neither λ is 1 (the law).
    """
    mean, variance = (math.log(prior.median), prior.log_sigma**2) if prior is not None else (0.0, math.inf)
    measured = None
    if fit is not None and math.isfinite(fit.log_sigma):
        measured = fit.factor
        observed = math.log(fit.factor) - log_bias
        noise = fit.log_sigma**2 + log_spread**2
        if math.isinf(variance):
            mean, variance = observed, noise
        elif variance > 0.0:
            precision = 1.0 / variance + 1.0 / max(noise, 1e-12)
            mean = (mean / variance + observed / max(noise, 1e-12)) / precision
            variance = 1.0 / precision
    factor = min(max(math.exp(mean), RATE_FACTOR_LIMITS[0]), RATE_FACTOR_LIMITS[1])
    return RateEstimate(factor, math.sqrt(variance), measured, fit.fixes if fit is not None else 0, prior)


class DescentRecord:
    """The descent so far as seconds since its top against altitude, and the rate factor on a law.

    ``law`` gives the track the flown model predicts from a report; it is asked once per record, from
    the record's top (the highest report), for the model's seconds from there to every altitude.
    """

    def __init__(self, law: Callable[[Report], Track]) -> None:
        self.law = law
        self.top: Report | None = None
        self._t: list[float] = []
        self._z: list[float] = []
        self._model: tuple[np.ndarray, np.ndarray] | None = None
        """(altitudes rising, the model's seconds from the top to each), once per record."""
        self._earlier: dict[tuple[Report | None, float], RateFit | None] = {}

    def add(self, report: Report) -> None:
        if self.top is None or report.alt_m > self.top.alt_m:
            # Still climbing (or the first report): the descent record starts again here.
            self.top, self._model = report, None
            self._t, self._z = [], []
        self._t.append((report.time - self.top.time).total_seconds())
        self._z.append(report.alt_m)

    def remaining_model_s(self, alt_m: float) -> float | None:
        """The law's seconds from ``alt_m`` to the ground, as flown from the record's top (None: no record yet)."""
        if self.top is None:
            return None
        z_up, model_up = self._law_up()
        return float(model_up[0] - np.interp(alt_m, z_up, model_up))

    def _law_up(self) -> tuple[np.ndarray, np.ndarray]:
        """(altitudes rising, the law's seconds from the record's top to each), asked once per top."""
        if self._model is None:
            assert self.top is not None
            track = self.law(self.top)
            self._model = track.alt_m[::-1].copy(), track.t_s[::-1] - track.t_s[0]
        return self._model

    def earlier_fit(self, alt_m: float) -> RateFit | None:
        """``rate_fit(alt_m, earlier=True)``, kept once the record is below ``alt_m`` (it cannot change)."""
        key = (self.top, alt_m)
        if key not in self._earlier:
            fit = self.rate_fit(alt_m, earlier=True)
            if self._z and self._z[-1] > alt_m:
                return fit
            self._earlier[key] = fit
        return self._earlier[key]

    def elapsed_s(self, alt_m: float) -> float | None:
        """Seconds from the record's top to where it first reached ``alt_m`` (None: not yet)."""
        z = np.asarray(self._z)
        below = np.flatnonzero(z <= alt_m)
        if below.size == 0 or below[0] == 0:
            return None
        i = int(below[0])
        z0, z1, t0, t1 = self._z[i - 1], self._z[i], self._t[i - 1], self._t[i]
        return t1 if z0 == z1 else t0 + (t1 - t0) * (z0 - alt_m) / (z0 - z1)

    def law_s(self, top_m: float, bottom_m: float) -> float | None:
        """The law's seconds from ``top_m`` down to ``bottom_m``, as flown from the record's top."""
        high, low = self.remaining_model_s(top_m), self.remaining_model_s(bottom_m)
        return None if high is None or low is None else high - low

    def since_top_s(self, report: Report) -> float:
        """Seconds from the record's top (the release, as far as the reports know) to ``report``."""
        return 0.0 if self.top is None else max((report.time - self.top.time).total_seconds(), 0.0)

    def rate_fit(
        self, alt_m: float, window_m: float = RECORD_WINDOW_M, earlier: bool = False
    ) -> RateFit | None:
        """λ on the law from the record's fixes down to ``alt_m``, those within ``window_m`` above it
        (at least the last two; None: too little), each fix weighted by the height it spans. ``earlier``: only the fixes up to the first one at
        or below ``alt_m``, what the record said when the capsule was there (``self_check``)."""
        if self.top is None or self.top.alt_m - alt_m < MIN_PAIR_DROP_M:
            return None
        z_up, model_up = self._law_up()
        z = np.asarray(self._z)
        flown = z >= z_up[0]
        if earlier:
            reached = np.flatnonzero(z <= alt_m)
            flown &= np.arange(z.size) <= (int(reached[0]) if reached.size else z.size - 1)
        keep = flown & (z <= alt_m + window_m)
        if keep.sum() < 2:
            keep[np.flatnonzero(flown)[-2:]] = True
        if keep.sum() < 2 or float(np.ptp(z[keep])) < MIN_PAIR_DROP_M:
            return None
        zk = z[keep]
        # Each fix weighs the height it spans (half the fall to each neighbour), so that the fit is
        # an integral over height whatever the cadence; the weights sum to the independent fixes the
        # height holds (INDEPENDENT_DROP_M), never more than the fixes themselves.
        padded = np.concatenate(([zk[0]], zk, [zk[-1]]))
        spans = np.maximum(0.5 * (padded[:-2] - padded[2:]), 0.0) + 1e-3
        count = min(float(zk.size), float(np.ptp(zk)) / INDEPENDENT_DROP_M + 2.0)
        weights = spans * (count / float(spans.sum()))
        return fit_rate(np.asarray(self._t)[keep], np.interp(zk, z_up, model_up), weights)


@dataclass(frozen=True)
class LivePrediction:
    prediction: Prediction
    """The prediction from the latest report, with the correction applied and the live ellipse."""
    report: Report
    rate: RateEstimate | None
    """This flight's λ update (None: the rate is not corrected at this height)."""
    wind_error_ms: tuple[float, float]
    """The wind error measured over the recent legs (below the capsule it is carried times ``wind_gain``)."""
    decay_m: float | None
    legs: tuple[Leg, ...] = field(repr=False)
    notes: tuple[str, ...] = ()
    """What this prediction flies that is not the model's own measured live settings (said, not silent)."""
    ascent_distance_km_h: float | None = None
    """X of the ellipse (``ascent_distance_km_h``; None: the weather does not say where it was measured,
    the typical X at this height was flown)."""
    time_log_sigma: float | None = None
    """The law's own σ of ln(remaining time) at this height (``LiveErrorModel.time_log_sigma``)."""
    wind_gain: float | None = None
    """The share of the measured wind error carried (``WindGain``; None: all of it, or no wind flown)."""

    @property
    def rate_factor(self) -> float:
        """The λ flown below the capsule (1: the law as it stands)."""
        return self.rate.factor if self.rate is not None else 1.0

    @property
    def remaining_sigma_s(self) -> float | None:
        """1σ of the remaining descent time, s: λ's own uncertainty (time ∝ 1/λ) and the law's error
        below the capsule that the evaluation measured at this height (``time_log_sigma``), added in
        quadrature. None when neither is known."""
        rate = None if self.rate is None or math.isinf(self.rate.log_sigma) else self.rate.log_sigma
        if rate is None and self.time_log_sigma is None:
            return None
        return self.prediction.descent_s * math.hypot(rate or 0.0, self.time_log_sigma or 0.0)

    def to_dict(self) -> dict[str, Any]:
        p = self.prediction
        rate = self.rate
        return {
            "report": {
                "time": iso_z(self.report.time),
                "lat": self.report.lat,
                "lon": self.report.lon,
                "alt_m": self.report.alt_m,
            },
            "landing": p.landing.to_dict(),
            "remaining_drift_km": p.drift_km,
            "remaining_s": p.descent_s,
            "remaining_sigma_s": self.remaining_sigma_s,
            "ellipse": p.ellipse.to_dict(),
            "ellipse_meaning": ELLIPSE_MEANING,
            "ascent_distance_km_h": self.ascent_distance_km_h,
            "rate_factor": self.rate_factor,
            "rate_log_sigma": None if rate is None or math.isinf(rate.log_sigma) else rate.log_sigma,
            "rate_measured": None if rate is None else rate.measured,
            "rate_fixes_used": 0 if rate is None else rate.fixes,
            "rate_prior": None if rate is None or rate.prior is None else rate.prior.to_dict(),
            "wind_error_ms": {"east": self.wind_error_ms[0], "north": self.wind_error_ms[1]},
            "wind_decay_m": self.decay_m,
            "wind_gain": self.wind_gain,
            "legs_used": len(self.legs),
            "notes": list(self.notes),
            "warnings": list(p.warnings),
        }


TYPICAL_DISTANCE_NOTE = (
    "live ellipse: the weather does not say where its winds were measured; widened by the evaluation "
    "flights' typical distance between the ascent and the descent at this height"
)
ELLIPSE_MEANING = (
    "the live 1σ and 2σ are the contours of probability 0.6827 and 0.9545 (68 % and 95 % of landings); "
    "the n_sigma 1 contour holds 39 %"
)
"""What a live prediction's file says its ellipse means (``LIVE_PROBABILITIES``)."""


def _velocity(a: Report, b: Report, seconds: float) -> tuple[float, float]:
    azimuth, _, distance = GEOD.inv(a.lon, a.lat, b.lon, b.lat)
    speed = distance / seconds
    return speed * math.sin(math.radians(azimuth)), speed * math.cos(math.radians(azimuth))


class LivePredictor:
    """Feeds on position reports of one descent; ``update`` returns the new prediction for each.

    The model's view of each leg (fall time and mean wind between two reports) comes from a prediction
    started at the leg's first report and read off its track where it crosses the leg's lower altitude,
    so the comparison uses exactly the physics and weather the prediction will use below. The law the
    rate factor is fitted against is one such prediction from the top of the record (the highest
    report): the model's seconds from there to every altitude. Every prediction from a report starts
    the time-since-release terms at the seconds since that top, not at zero.
    """

    def __init__(
        self,
        cube: WeatherCube,
        payload: Payload | None = None,
        terrain: Terrain | None = None,
        correction: LiveCorrection = OWN_RATE,
        error_model: LiveErrorModel = LIVE_ERROR_MODEL,
        step_m: float = 100.0,
        effects: Sequence[Term] = (),
        prior: RatePrior | None = None,
        discrepancy: RateDiscrepancy = NO_DISCREPANCY,
        notes: Sequence[str] = (),
        restart_effects: Sequence[Term] | None = None,
    ) -> None:
        self.cube = cube
        self.payload = payload or PROFILES["drs"]
        self.terrain = terrain or Terrain.sea_level()
        self.correction = correction
        self.error_model = error_model
        self.step_m = step_m
        self.effects = tuple(effects)
        self.restart_effects = self.effects if restart_effects is None else tuple(restart_effects)
        """The terms flown outside every band of the correction (default: ``effects``)."""
        self.prior = prior
        self.discrepancy = discrepancy
        self.notes = tuple(notes)
        self.reports: list[Report] = []
        self.legs: list[Leg] = []
        self._leg_start: Report | None = None
        self.record = DescentRecord(self.law)

    def _predict(self, report: Report, terms: Sequence[Term], error_model: ErrorModel = LAUNCH) -> Prediction:
        start = Release(report.time, report.lat, report.lon, report.alt_m,
                        since_release_s=self.record.since_top_s(report))  # fmt: skip
        setup = FlightSetup(self.payload, tuple(terms), terrain=self.terrain, step_m=self.step_m,
                            error_model=error_model, probabilities=LIVE_PROBABILITIES)  # fmt: skip
        return predict(self.cube, start, setup)

    def law(self, report: Report) -> Track:
        """The flown model's track from ``report``, with no live correction: the law a rate is fitted on."""
        return self._predict(report, self.effects).track

    def _leg(self, a: Report, b: Report) -> Leg | None:
        seconds = (b.time - a.time).total_seconds()
        if seconds <= 0.0 or a.alt_m - b.alt_m < MIN_PAIR_DROP_M:
            return None
        track = self._predict(a, self.effects).track
        if track.alt_m[-1] > b.alt_m:
            return None
        # The track's altitudes fall, so flip them for np.interp.
        z, t = track.alt_m[::-1], track.t_s[::-1]
        model_s = float(np.interp(b.alt_m, z, t))
        lat_b = float(np.interp(b.alt_m, z, track.lat[::-1]))
        lon_b = float(np.interp(b.alt_m, z, np.unwrap(track.lon, period=360.0)[::-1]))
        if model_s <= 0.0:
            return None
        end = _Point(b.time, lat_b, lon_b, b.alt_m)
        f_east, f_north = _velocity(a, end, model_s)
        o_east, o_north = _velocity(a, b, seconds)
        return Leg(a.alt_m, b.alt_m, seconds, model_s, o_east, o_north, f_east, f_north)

    def update(self, report: Report) -> LivePrediction:
        """A new report: measure the leg since the last usable one, then predict from the report."""
        self.observe(report)
        return self.predict_from(report)

    def observe(self, report: Report) -> None:
        """Record the report and measure the leg that ends at it (no prediction)."""
        if self.reports and report.time <= self.reports[-1].time:
            raise PredictorError(
                f"report at {iso_z(report.time)} is not after the previous one "
                f"({iso_z(self.reports[-1].time)})"
            )
        if self._leg_start is not None:
            leg = self._leg(self._leg_start, report)
            if leg is not None:
                self.legs.append(leg)
                self._leg_start = report
            elif report.alt_m > self._leg_start.alt_m:
                self._leg_start = report
        else:
            self._leg_start = report
        self.record.add(report)
        self.reports.append(report)

    def rate(self, report: Report) -> RateEstimate:
        """This flight's λ from the prior and the record down to ``report`` (the update, not flown)."""
        height_km = (report.alt_m - float(self.terrain.elevation(report.lat, report.lon))) / 1000.0
        bias, spread = self.discrepancy.at(height_km)
        prior = self.discrepancy.remaining_prior(height_km) or self.prior
        return update_rate(prior, self.record.rate_fit(report.alt_m), bias, spread)

    def self_check(self, report: Report) -> dict[str, float] | None:
        """This flight's own evidence for its λ: how well each candidate, asked when the capsule was
        ``CHECK_DROPS_M`` higher, would have predicted the time it then took to fall to ``report``.

        Mean of the squared log ratio of predicted to measured fall time over those checks, for
        ``plain`` (the law as it stands) and ``λ`` (the update the record then allowed). None: the
        record does not reach the lowest check yet. (Requiring every check was tried: 2019 → 2018 from
        20 km 1.05× the plain restart's time against 0.97×; dropped.) Cheap: one fit per check on the record already kept.
        """
        now_s = self.record.since_top_s(report)
        ground_m = float(self.terrain.elevation(report.lat, report.lon))
        errors: dict[str, list[float]] = {"plain": [], "λ": []}
        for drop in CHECK_DROPS_M:
            # On a grid of CHECK_GRID_M, so that a 1 Hz record asks each height's fit once (cached).
            top_m = math.ceil((report.alt_m + drop) / CHECK_GRID_M) * CHECK_GRID_M
            fit = self.record.earlier_fit(top_m)
            then_s, law_s = self.record.elapsed_s(top_m), self.record.law_s(top_m, report.alt_m)
            if then_s is None or law_s is None or law_s <= 0.0 or now_s - then_s <= 0.0:
                continue
            height_km = (top_m - ground_m) / 1000.0
            bias, spread = self.discrepancy.at(height_km)
            prior = self.discrepancy.remaining_prior(height_km) or self.prior
            then = update_rate(prior, fit, bias, spread)
            errors["plain"].append(math.log(law_s / (now_s - then_s)) ** 2)
            errors["λ"].append(math.log(law_s / then.factor / (now_s - then_s)) ** 2)
        if not errors["plain"]:
            return None
        return {name: float(np.mean(values)) for name, values in errors.items()}

    def _wind_error(self, alt_m: float, c: LiveCorrection) -> tuple[tuple[float, float], float]:
        """The wind error of recent legs: those whose lower end is within the window above ``alt_m``
        (the last leg always is, it ends at the latest report), weighted by their duration."""
        wind_legs = [g for g in self.legs if g.bottom_m - alt_m < c.wind_window_m] or self.legs[-1:]
        if not wind_legs:
            return (0.0, 0.0), alt_m
        weights = np.array([g.observed_s for g in wind_legs])
        errors = np.array([g.wind_error for g in wind_legs])
        east, north = (weights[:, None] * errors).sum(axis=0) / weights.sum()
        middle = np.array([0.5 * (g.top_m + g.bottom_m) for g in wind_legs])
        return (float(east), float(north)), float((weights * middle).sum() / weights.sum())

    def predict_from(self, report: Report, correction: LiveCorrection | None = None) -> LivePrediction:
        """The prediction from one report with the descent measured so far (``correction`` overrides)."""
        correction = correction or self.correction
        height = report.alt_m - float(self.terrain.elevation(report.lat, report.lon))
        band = correction.band_at(height)
        decay = band.decay_m if band is not None else None
        rate = self.rate(report) if band is not None and band.use_rate else None
        (east, north), measured_at = self._wind_error(report.alt_m, correction)
        gain = (
            None
            if decay is None or correction.wind_gain is None
            else correction.wind_gain.at(height / 1000.0)
        )
        share = 1.0 if gain is None else gain
        terms: list[Term] = list(self.effects if band is not None else self.restart_effects)
        if rate is not None and rate.factor != 1.0:
            terms.append(DescentRateScale(scale=rate.factor))
        if decay is not None and self.legs and report.alt_m > -500.0 + WIND_BIN_M:
            edges = np.arange(report.alt_m, -500.0, -WIND_BIN_M)[::-1]
            edges = np.concatenate(([-500.0], edges)) if edges[0] > -500.0 else edges
            centers = 0.5 * (edges[:-1] + edges[1:])
            weight = np.exp(-(max(measured_at, report.alt_m) - centers) / decay)
            terms.append(
                BinnedWind(
                    edges_m=tuple(float(e) for e in edges),
                    east_ms=tuple(float(share * east * w) for w in weight),
                    north_ms=tuple(float(share * north * w) for w in weight),
                )
            )
        prediction = self._predict(report, terms, error_model=self.error_model.at(height / 1000.0))
        distance = None
        if self.cube.measured_along is not None:
            distance = ascent_distance_km_h(prediction.track, self.cube.measured_along)
            grown = self.error_model.at(height / 1000.0, distance)
            p = prediction
            ellipse = parametric_ellipse(grown, p.drift_km, p.t_future_mean_h, p.bearing_deg,
                                         p.landing.lat, p.landing.lon, LIVE_PROBABILITIES)  # fmt: skip
            prediction = dataclasses.replace(prediction, ellipse=ellipse, error_model=grown)
        return LivePrediction(
            prediction=prediction,
            report=report,
            rate=rate,
            wind_error_ms=(east, north) if decay is not None else (0.0, 0.0),
            decay_m=decay,
            wind_gain=gain,
            legs=tuple(self.legs),
            notes=self.notes
            if distance is not None or not self.error_model.growth_exponent
            else (*self.notes, TYPICAL_DISTANCE_NOTE),
            ascent_distance_km_h=distance,
            time_log_sigma=self.error_model.time_sigma_at(height / 1000.0),
        )


@dataclass(frozen=True)
class _Point:
    time: datetime
    lat: float
    lon: float
    alt_m: float

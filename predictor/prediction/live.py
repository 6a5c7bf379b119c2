"""Live re-prediction during a descent: restart from each position report, and learn from the fall so far.

Why: during descent the capsule reports its position (every ~2 minutes over Iridium, every second from
a logger). Each report is the best possible release point for a new prediction (measured position,
altitude and time), and the reports so far measure two things the forecast got wrong:

* the **descent rate**: one factor λ on the flown model's descent law (its drag law with the density
  exponent and binned factors a calibrated model carries) is fitted to the whole altitude–time record
  of the descent so far, and then multiplies that same law below the capsule (``DescentRateScale``).
  Fitting the rate with the law that will carry it to the ground is the point: a rate measured at
  20 km and carried down with the textbook ρ^-½ is wrong by the law's error at every height below,
  and a law changed without refitting the rate is wrong by the rate. The fit is robust (Huber) on
  every fix, with a free time offset, so the swinging of a 1 Hz record, a late canopy and a single
  bad fix do not set the factor. A band's ``rate_window_m`` can restrict it to the recent descent
  (where the held-out flights said the law's shape is not good enough to carry the whole record), and
  its ``typical_rate`` divides the factor by the one the calibration flights typically showed at that
  height (``TypicalRate``), so a departure from the law that most flights share is not mistaken for
  this flight's own;
* the **wind**: the measured mean velocity between two reports minus the forecast's mean velocity
  over the same altitudes. An error at altitude does not simply continue to the ground (the jet and
  the stratosphere are different air), so the recent error is applied below the capsule with a weight
  exp(−Δz / L) that decays with the altitude distance Δz from the capsule (``BinnedWind`` in 250 m
  bins). L is chosen on real flights, leave-one-flight-out (``predictor.calibration.live_evaluation``),
  and the correction is switched on only in the altitude bands where it helped held-out flights.

The ellipse shrinks with what is left: σ∥ and σ⊥ are the errors the evaluation measured at the
report's height above the ground (``LiveErrorModel``).
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import datetime
from typing import Any, Protocol

import numpy as np

from predictor.descent import PROFILES, BinnedWind, DescentRateScale, Payload, Term
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError
from predictor.prediction.landings import Prediction, Track, iso_z, predict
from predictor.prediction.uncertainty import GEOD, ErrorModel

WIND_BIN_M = 250.0
RATE_FACTOR_LIMITS = (0.5, 2.0)
"""A measured rate factor outside this is a bad fix or a failed canopy, not a calibration."""
MIN_PAIR_DROP_M = 200.0
"""Report pairs closer in altitude than this say too little about rate or wind (GNSS noise)."""
HUBER_K = 1.345
"""Huber's constant: 95 % efficiency on Gaussian residuals, bounded influence of a swing or a bad fix."""
FIT_ITERATIONS = 8


@dataclass(frozen=True)
class LiveErrorModel:
    """σ∥ and σ⊥ (km, along and across the report→landing bearing) against height above the ground.

    Measured, not modelled: the RMS along- and cross-track errors of the live re-prediction at each
    checkpoint of the real-flight evaluation, linear in height between checkpoints and held beyond
    them. Squared-error fits of σ0 + drift forms were tried and dominated by a few large misses high
    up, which left 3 km of σ at the ground; a table per height keeps each height honest.
    """

    heights_km: tuple[float, ...]
    sigma_parallel_km: tuple[float, ...]
    sigma_perpendicular_km: tuple[float, ...]

    def at(self, height_km: float) -> ErrorModel:
        """The ``ErrorModel`` that ``predict`` uses for a report at this height (no drift or lead term)."""
        order = np.argsort(self.heights_km)
        heights = np.asarray(self.heights_km)[order]
        parallel = float(np.interp(height_km, heights, np.asarray(self.sigma_parallel_km)[order]))
        perpendicular = float(np.interp(height_km, heights, np.asarray(self.sigma_perpendicular_km)[order]))
        return ErrorModel(
            sigma0_km=parallel, h=0.0, k_km2_per_h2=0.0, q=parallel / perpendicular, name="live"
        )


LIVE_ERROR_MODEL = LiveErrorModel(
    heights_km=(25.0, 20.0, 15.0, 10.0, 5.0, 2.0),
    sigma_parallel_km=(4.139, 3.638, 3.321, 3.464, 2.107, 1.602),
    sigma_perpendicular_km=(3.581, 3.803, 3.857, 3.321, 1.529, 0.789),
)
"""Measured by ``drs live evaluate`` on the 30 test flights, each flown with the law refitted without
it; see docs/planning/live-reprediction.md."""


class Report(Protocol):
    """A position report (a calibration ``Fix``, an Iridium position, a GNSS sample)."""

    time: datetime
    lat: float
    lon: float
    alt_m: float


@dataclass(frozen=True)
class TypicalRate:
    """The rate factor the calibration flights' own whole-descent fits gave, by height above the ground.

    Why: a calibrated law is fitted to whole descents, and real descents depart from it in much the
    same way on most flights (on the SuperBIT flights, faster than the law high up). A factor fitted
    on the top of one record carries that shared departure as well as the flight's own, and carried
    to the ground it makes the fall too short on average. Divided by the typical factor at the same
    height, only what is particular to this flight is carried down.
    """

    heights_km: tuple[float, ...]
    factors: tuple[float, ...]

    def at(self, height_km: float) -> float:
        """Linear in height between the measured heights, held beyond them."""
        order = np.argsort(self.heights_km)
        return float(np.interp(height_km, np.asarray(self.heights_km)[order], np.asarray(self.factors)[order]))


@dataclass(frozen=True)
class Band:
    """What to correct while the capsule is between two heights above the ground (m)."""

    lower_m: float
    upper_m: float
    use_rate: bool
    decay_m: float | None
    """Decay length L of the wind correction (None: no wind correction in this band)."""
    rate_window_m: float = math.inf
    """The rate factor is fitted on fixes at most this far above the report (∞: the whole descent)."""
    typical_rate: TypicalRate | None = None
    """When set, the fitted factor is divided by the calibration flights' typical one at this height."""

    def describe(self) -> str:
        """The band for a person: heights, the rate estimator, the wind correction."""
        lower = "ground" if not math.isfinite(self.lower_m) else f"{self.lower_m / 1000:g} km"
        upper = "top" if not math.isfinite(self.upper_m) else f"{self.upper_m / 1000:g} km"
        window = "the whole descent" if math.isinf(self.rate_window_m) else f"the last {self.rate_window_m / 1000:g} km"
        if not self.use_rate:
            rate = "rate off"
        elif self.typical_rate is not None:
            rate = f"rate on {window} relative to the typical factor"
        else:
            rate = f"rate on {window}"
        wind = "off" if self.decay_m is None else f"L = {self.decay_m / 1000:g} km"
        return f"{lower}–{upper}: {rate}, wind {wind}"


@dataclass(frozen=True)
class LiveCorrection:
    """How the measured descent corrects the rest of it, by the capsule's height above the ground.

    Outside every band nothing is corrected (a plain re-prediction from the report).
    """

    bands: tuple[Band, ...] = ()
    wind_window_m: float = 2000.0

    @classmethod
    def everywhere(
        cls,
        use_rate: bool,
        decay_m: float | None,
        rate_window_m: float = math.inf,
        typical_rate: TypicalRate | None = None,
    ) -> LiveCorrection:
        return cls(bands=(Band(-math.inf, math.inf, use_rate, decay_m, rate_window_m, typical_rate),))

    def band_at(self, height_m: float) -> Band | None:
        for band in self.bands:
            if band.lower_m <= height_m < band.upper_m:
                return band
        return None


NO_CORRECTION = LiveCorrection()
TYPICAL_RATE = TypicalRate(
    heights_km=(25.0, 20.0, 15.0, 10.0, 5.0, 2.0), factors=(0.995, 1.0384, 1.0329, 1.0215, 1.0049, 1.005)
)
"""The 30 SuperBIT flights' typical whole-descent factor on the calibrated model's law (``drs live evaluate``)."""
DEFAULT_CORRECTION = LiveCorrection(
    bands=(
        Band(lower_m=-math.inf, upper_m=3500.0, use_rate=True, decay_m=None, rate_window_m=3000.0),
        Band(lower_m=3500.0, upper_m=7500.0, use_rate=True, decay_m=4000.0, rate_window_m=3000.0),
        Band(lower_m=7500.0, upper_m=12500.0, use_rate=True, decay_m=None, rate_window_m=3000.0),
        Band(lower_m=12500.0, upper_m=17500.0, use_rate=True, decay_m=None, typical_rate=TYPICAL_RATE),
        Band(lower_m=17500.0, upper_m=22500.0, use_rate=True, decay_m=None, typical_rate=TYPICAL_RATE),
    )
)
"""What the leave-one-flight-out evaluation kept with the calibrated model of the 30 SuperBIT flights
(``drs live evaluate``; docs/planning/live-reprediction.md): the rate fitted on the whole descent and
taken relative to the typical factor 12.5–22.5 km above the ground, on the last 3 km below (where the
law's shape no longer carries the whole record as well), and the decaying wind correction only
3.5–7.5 km; above 22.5 km a plain re-prediction did as well."""


@dataclass(frozen=True)
class LiveSettings:
    """How live re-prediction corrects one model's law, and how sure it then is: what the evaluation kept.

    Both belong to the law they were measured with: the bands and typical factors measured with one
    calibrated model are the wrong ones for another, so a model file carries its own (``drs live
    evaluate --model M --save-model``), and ``DEFAULT_LIVE`` is only for a flight without one.
    """

    correction: LiveCorrection
    error_model: LiveErrorModel


DEFAULT_LIVE = LiveSettings(DEFAULT_CORRECTION, LIVE_ERROR_MODEL)
"""What the evaluation of the committed SuperBIT model kept (its model file carries the same; a test pins it)."""


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


def fit_rate(observed_s: np.ndarray, model_s: np.ndarray) -> RateFit | None:
    """Huber fit of observed = model / λ + offset by iteratively reweighted least squares.

    Why Huber and not least squares: a 1 Hz record swings under its canopy and a tracker logs the odd
    wild fix; squared errors let a few of those set λ, a bounded weight does not. Every fix is used,
    vectorised (a 10,000-fix record costs well under a millisecond per iteration). None when the
    record is too short in model time to say anything (less than two fixes or a degenerate span).
    """
    if observed_s.size < 2 or float(np.ptp(model_s)) <= 0.0:
        return None
    design = np.column_stack((model_s, np.ones_like(model_s)))
    weights = np.ones_like(model_s)
    coef = np.zeros(2)
    scale = 1.0
    for _ in range(FIT_ITERATIONS):
        root = np.sqrt(weights)
        coef, *_ = np.linalg.lstsq(design * root[:, None], observed_s * root, rcond=None)
        residual = observed_s - design @ coef
        # A floor of 1 s, the resolution of a fix's time stamp: a near-perfect fit must not make
        # every fix an outlier.
        scale = max(1.4826 * float(np.median(np.abs(residual - np.median(residual)))), 1.0)
        u = np.abs(residual) / (HUBER_K * scale)
        weights = np.where(u <= 1.0, 1.0, 1.0 / np.maximum(u, 1e-12))
    if coef[0] <= 0.0:
        return None
    return RateFit(factor=float(1.0 / coef[0]), offset_s=float(coef[1]), fixes=int(observed_s.size), scale_s=scale)


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

    def add(self, report: Report) -> None:
        if self.top is None or report.alt_m > self.top.alt_m:
            # Still climbing (or the first report): the descent record starts again here.
            self.top, self._model = report, None
            self._t, self._z = [], []
        self._t.append((report.time - self.top.time).total_seconds())
        self._z.append(report.alt_m)

    def rate_fit(self, alt_m: float, window_m: float = math.inf) -> RateFit | None:
        """λ on the law from the record's fixes at most ``window_m`` above ``alt_m`` (None: too little)."""
        if self.top is None or self.top.alt_m - alt_m < MIN_PAIR_DROP_M:
            return None
        if self._model is None:
            track = self.law(self.top)
            self._model = track.alt_m[::-1].copy(), track.t_s[::-1] - track.t_s[0]
        z_up, model_up = self._model
        z = np.asarray(self._z)
        keep = (z - alt_m < window_m) & (z >= z_up[0])
        if not keep.any() or float(np.ptp(z[keep])) < MIN_PAIR_DROP_M:
            return None
        return fit_rate(np.asarray(self._t)[keep], np.interp(z[keep], z_up, model_up))


@dataclass(frozen=True)
class LivePrediction:
    prediction: Prediction
    """The prediction from the latest report, with the correction applied and the live ellipse."""
    report: Report
    rate_factor: float
    rate_fixes: int
    """How many fixes the rate factor was fitted on (0: no rate correction)."""
    wind_error_ms: tuple[float, float]
    decay_m: float | None
    legs: tuple[Leg, ...] = field(repr=False)

    def to_dict(self) -> dict[str, Any]:
        p = self.prediction
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
            "ellipse": p.ellipse.to_dict(),
            "rate_factor": self.rate_factor,
            "rate_fixes_used": self.rate_fixes,
            "wind_error_ms": {"east": self.wind_error_ms[0], "north": self.wind_error_ms[1]},
            "wind_decay_m": self.decay_m,
            "legs_used": len(self.legs),
            "warnings": list(p.warnings),
        }


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
    report): the model's seconds from there to every altitude.
    """

    def __init__(
        self,
        cube: WeatherCube,
        payload: Payload | None = None,
        terrain: Terrain | None = None,
        correction: LiveCorrection = DEFAULT_CORRECTION,
        error_model: LiveErrorModel = LIVE_ERROR_MODEL,
        step_m: float = 100.0,
        effects: Sequence[Term] = (),
    ) -> None:
        self.cube = cube
        self.payload = payload or PROFILES["drs"]
        self.terrain = terrain or Terrain.sea_level()
        self.correction = correction
        self.error_model = error_model
        self.step_m = step_m
        self.effects = tuple(effects)
        self.reports: list[Report] = []
        self.legs: list[Leg] = []
        self._leg_start: Report | None = None
        self.record = DescentRecord(self.law)

    def _predict(self, report: Report, terms: Sequence[Term], **kwargs: Any) -> Prediction:
        return predict(
            self.cube, report.time, report.lat, report.lon, report.alt_m, self.payload, self.terrain,
            self.step_m, effects=tuple(terms), **kwargs,
        )  # fmt: skip

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

    def rate_fit(self, alt_m: float, window_m: float = math.inf) -> RateFit | None:
        """λ on the flown law from the record's fixes at most ``window_m`` above ``alt_m`` (None: too little)."""
        return self.record.rate_fit(alt_m, window_m)

    def measured(
        self, alt_m: float, rate_window_m: float = math.inf
    ) -> tuple[float, tuple[float, float], float]:
        """(rate factor, wind error east/north, the altitude the wind was measured at)."""
        wind, measured_at = self._wind_error(alt_m, self.correction)
        return _clamped(self.rate_fit(alt_m, rate_window_m)), wind, measured_at

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
        fit = self.rate_fit(report.alt_m, band.rate_window_m) if band is not None and band.use_rate else None
        typical = band.typical_rate.at(height / 1000.0) if band is not None and band.typical_rate else 1.0
        rate = _clamped(fit, typical)
        (east, north), measured_at = self._wind_error(report.alt_m, correction)
        terms: list[Term] = list(self.effects)
        if rate != 1.0:
            terms.append(DescentRateScale(scale=rate))
        if decay is not None and self.legs and report.alt_m > -500.0 + WIND_BIN_M:
            edges = np.arange(report.alt_m, -500.0, -WIND_BIN_M)[::-1]
            edges = np.concatenate(([-500.0], edges)) if edges[0] > -500.0 else edges
            centers = 0.5 * (edges[:-1] + edges[1:])
            weight = np.exp(-(max(measured_at, report.alt_m) - centers) / decay)
            terms.append(
                BinnedWind(
                    edges_m=tuple(float(e) for e in edges),
                    east_ms=tuple(float(east * w) for w in weight),
                    north_ms=tuple(float(north * w) for w in weight),
                )
            )
        prediction = self._predict(report, terms, error_model=self.error_model.at(height / 1000.0))
        return LivePrediction(
            prediction=prediction,
            report=report,
            rate_factor=rate,
            rate_fixes=fit.fixes if fit is not None else 0,
            wind_error_ms=(east, north) if decay is not None else (0.0, 0.0),
            decay_m=decay,
            legs=tuple(self.legs),
        )


def _clamped(fit: RateFit | None, typical: float = 1.0) -> float:
    """The rate factor to fly: 1 without a fit, else λ / ``typical`` held within ``RATE_FACTOR_LIMITS``."""
    if fit is None:
        return 1.0
    return min(max(fit.factor / typical, RATE_FACTOR_LIMITS[0]), RATE_FACTOR_LIMITS[1])


@dataclass(frozen=True)
class _Point:
    time: datetime
    lat: float
    lon: float
    alt_m: float

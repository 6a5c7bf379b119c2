"""Does live re-prediction help on real descents? Measured on flight tracks, leave-one-flight-out.

For each flight the weather is its own ascent's winds (``ascent_weather_cube``), which is what a
forecast is to a descent: right in general, wrong in detail (an hour or two and tens of km away). The
ground is a level plane at the flight's measured landing altitude (a DEM stands in for it in
operations). At each checkpoint (the first report at or below 25, 20, 15, 10, 5 and 2 km above the
ground) the landing and the remaining descent time are predicted from that report, with two laws:

* ``profile``: the payload profile's drag law (the textbook v ∝ ρ^-½);
* ``model``: the calibrated model (``--model``: its payload and terms, e.g. a density exponent). On a
  flight the model was calibrated on, its terms are refitted without that flight
  (``held_out_laws``), so that the law is held out too, not only the live choices;

and with these live corrections on top of each law:

* ``plain``: restarted from the report, nothing learned;
* ``rate``: plus the descent-rate factor fitted on the whole descent so far with the same law (on the
  profile this is the ρ^-½ extrapolation of the measured rate); ``recent rate``: fitted on the last
  3 km only (the previous estimator, a baseline);
* ``wind L`` / ``rate + wind L``: plus the measured wind error, decaying below the capsule with L.

Each correction is chosen leave-one-flight-out on the metric it acts on: the rate (a vertical effect)
on the remaining-time error, the wind (horizontal) on the landing error, each held-out flight getting
what the OTHER flights preferred. A correction ships (``predictor.prediction.live.DEFAULT_CORRECTION``) only in
the bands where it helped held-out flights. The same held-out errors fit the live ellipse.

Every fix of the track is used: each one enters the rate fit and the wind legs (a 1 Hz track of
10,000 fixes is a few hundred leg probes and six checkpoints), and predictions are made only at the
checkpoints.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, date, datetime
from pathlib import Path

import numpy as np

from predictor.calibration.model_file import CalibratedModel
from predictor.calibration.residuals import FlightCase, flight_case
from predictor.calibration.selection import refit_without_each
from predictor.descent import PROFILES, Payload, Term
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError
from predictor.prediction import (
    GEOD,
    NO_CORRECTION,
    Band,
    DescentRecord,
    LiveCorrection,
    LiveErrorModel,
    LivePredictor,
    LiveSettings,
    TypicalRate,
)
from predictor.tracks import Fix, ascent_weather_cube, clean, read_track

CHECKPOINTS_KM = (25.0, 20.0, 15.0, 10.0, 5.0, 2.0)
LOWEST_SHARE = 0.6
"""A checkpoint's report must be at least this share of its height (a data gap skips the checkpoint)."""
DECAYS_M = (1000.0, 2000.0, 4000.0, 8000.0, 16000.0, math.inf)
RECENT_RATE_WINDOW_M = 3000.0
PLAIN = "model · plain"
RATE = "model · rate"
RELATIVE = "model · relative rate"
HELD_OUT_LIVE = "model + held-out live"


def _wind_label(decay: float) -> str:
    return "const" if math.isinf(decay) else f"{decay / 1000:g} km"


RATE_WINDOWS_M = {"rate": math.inf, "recent rate": RECENT_RATE_WINDOW_M}
"""The two rate estimators: fitted on the whole descent so far, or on its last 3 km."""
RELATIVE_RATE = "relative rate"
"""The third: the whole-descent factor divided by the typical one of the other flights at that height."""


def _rate_estimators(typical: TypicalRate | None) -> dict[str, tuple[float, TypicalRate | None]]:
    """Rate estimator name → (fit window, typical factor it is divided by)."""
    estimators: dict[str, tuple[float, TypicalRate | None]] = {n: (w, None) for n, w in RATE_WINDOWS_M.items()}
    if typical is not None:
        estimators[RELATIVE_RATE] = (math.inf, typical)
    return estimators


def corrections(typical: TypicalRate | None = None) -> dict[str, LiveCorrection]:
    """Every live correction tried on the calibrated model, by name (the relative rate with ``typical``)."""
    estimators = _rate_estimators(typical)
    configs = {"plain": NO_CORRECTION}
    configs.update({n: LiveCorrection.everywhere(True, None, w, t) for n, (w, t) in estimators.items()})
    for decay in DECAYS_M:
        stored = 1e12 if math.isinf(decay) else decay
        configs[f"wind {_wind_label(decay)}"] = LiveCorrection.everywhere(False, stored)
        for rate, (window, factor) in estimators.items():
            configs[f"{rate} + wind {_wind_label(decay)}"] = LiveCorrection.everywhere(True, stored, window, factor)
    return configs


PROFILE_CORRECTIONS = {
    "plain": NO_CORRECTION,
    "rate": LiveCorrection.everywhere(True, None),
    "recent rate": LiveCorrection.everywhere(True, None, rate_window_m=RECENT_RATE_WINDOW_M),
}
"""On the profile's law only the baselines: nothing learned, and the measured rate carried down with ρ^-½."""


def configurations(typical: TypicalRate) -> dict[str, tuple[str, LiveCorrection]]:
    """'law · correction' → (law, correction): the profile baselines, then every model correction."""
    configs = {f"profile · {n}": ("profile", c) for n, c in PROFILE_CORRECTIONS.items()}
    configs.update({f"model · {n}": ("model", c) for n, c in corrections(typical).items()})
    return configs


def _combined(rate: str | None, wind: str | None) -> str:
    """The model configuration named by a rate choice ('rate', 'recent rate' or None) and a wind
    choice ('wind 2 km' or None)."""
    if wind is None:
        return f"model · {rate}" if rate else PLAIN
    return f"model · {f'{rate} + ' if rate else ''}{wind}"


RATE_CHOICES: tuple[str | None, ...] = (None, *RATE_WINDOWS_M, RELATIVE_RATE)
WIND_CHOICES: tuple[str | None, ...] = (None, *(f"wind {_wind_label(d)}" for d in DECAYS_M))


class LevelGround(Terrain):
    """Flat ground at one height: the measured landing altitude of a test flight."""

    def __init__(self, height_m: float) -> None:
        super().__init__()
        self.height_m = float(height_m)

    def elevation(self, lat: float | np.ndarray, lon: float | np.ndarray) -> np.ndarray:
        shape = np.broadcast_shapes(np.shape(lat), np.shape(lon))
        return np.full(shape, self.height_m)

    def source_at(self, lat: float, lon: float) -> str:
        return f"level ground at the measured landing altitude {self.height_m:.0f} m"


@dataclass
class Case:
    """One checkpoint of one flight: the errors of every configuration there."""

    flight: str
    checkpoint_km: float
    height_m: float
    errors_km: dict[str, float]
    along_km: dict[str, float]
    across_km: dict[str, float]
    remaining_drift_km: dict[str, float]
    time_error_s: dict[str, float] = field(default_factory=dict)
    """Predicted minus measured remaining descent time, s."""


@dataclass
class Evaluation:
    flights: list[str]
    skipped: list[str]
    cases: list[Case]
    start_errors_km: dict[str, float]
    """Error of the model's prediction from the descent start (no live updates), per flight."""
    model_label: str = ""
    profile_label: str = ""
    fixes_used: int = 0
    """Fixes of the descents fed to the live predictors (every one of them)."""
    rate_choice: dict[float, dict[str, str | None]] = field(default_factory=dict)
    """Per checkpoint and held-out flight: the rate estimator the other flights' remaining time gained most from."""
    wind_choice: dict[float, dict[str, str | None]] = field(default_factory=dict)
    """Per checkpoint and held-out flight: the wind correction the other flights' landings gained most from."""
    all_flights_choice: dict[float, tuple[str | None, str | None]] = field(default_factory=dict)
    typical_rate: TypicalRate = TypicalRate((), ())
    """The typical whole-descent rate factor of all the flights by checkpoint (what ships)."""
    held_out_laws: dict[str, tuple[Term, ...]] = field(default_factory=dict)
    """Flight → the model's terms refitted without it, for the flights the model was calibrated on
    (each flies its own fold's law); empty when the model's law never saw these flights."""

    def held_out_name(self, case: Case) -> str:
        """The configuration this case gets from its held-out choices, rate and wind alike."""
        km = case.checkpoint_km
        return _combined(self.rate_choice[km][case.flight], self.wind_choice[km][case.flight])

    def shipped_name(self, case: Case) -> str:
        """What ships for this case: each held-out choice only where it helped held-out flights."""
        km = case.checkpoint_km
        if km not in self.rate_choice:
            return PLAIN
        rate = self.rate_choice[km][case.flight] if rate_helps(self, km) else None
        wind = self.wind_choice[km][case.flight] if wind_helps(self, km) else None
        return _combined(rate, wind)


def _describe(model: CalibratedModel) -> str:
    """The model as the report names it: where it came from and the terms it flies."""
    terms = ", ".join(
        f"`{t.name}` ({', '.join(f'{k} {v:.4g}' for k, v in t.parameters().items() if isinstance(v, float))})"
        for t in model.terms
    )
    return f"{model.label()}: payload `{model.payload.name}`" + (
        f", {terms}" if terms else ", no calibrated terms"
    )


def _touchdown_s(descent: Sequence[Fix], ground_m: float) -> float:
    """Measured seconds from the descent's first fix to touchdown.

    The landing fix is the first one on the ground, up to one interval after touchdown (3 min for the
    SuperBIT trackers: 90 s of bias on average, more than the errors being measured), so the last
    airborne fix is carried down to the ground at the rate of its own interval, never past the landing fix.
    """
    landing = descent[-1]
    end = (landing.time - descent[0].time).total_seconds()
    if len(descent) < 3:
        return end
    a, b = descent[-3], descent[-2]
    seconds = (b.time - a.time).total_seconds()
    rate = (a.alt_m - b.alt_m) / seconds if seconds > 0.0 else 0.0
    if rate <= 0.0:
        return end
    return min(end, (b.time - descent[0].time).total_seconds() + max(b.alt_m - ground_m, 0.0) / rate)


def _checkpoint_fix(descent: Sequence[Fix], ground_m: float, checkpoint_km: float) -> Fix | None:
    target = checkpoint_km * 1000.0
    for fix in descent[:-1]:
        height = fix.alt_m - ground_m
        if height <= target:
            return fix if height >= LOWEST_SHARE * target else None
    return None


def _errors(pred_lat: float, pred_lon: float, origin: Fix, truth: Fix) -> tuple[float, float, float]:
    """(distance, along-track, cross-track) km of the truth from the prediction, along origin→prediction."""
    azimuth_pred, _, _ = GEOD.inv(origin.lon, origin.lat, pred_lon, pred_lat)
    azimuth, _, distance = GEOD.inv(pred_lon, pred_lat, truth.lon, truth.lat)
    angle = math.radians(azimuth - azimuth_pred)
    d = distance / 1000.0
    return d, d * math.cos(angle), d * math.sin(angle)


@dataclass(frozen=True)
class _Flight:
    """A usable test flight, ready to be replayed: its descent, weather, ground and checkpoints, and
    the same as the calibration scores it (to refit the model's law without it)."""

    name: str
    descent: list[Fix]
    landing: Fix
    cube: WeatherCube
    ground: LevelGround
    checkpoints: dict[float, Fix | None]
    case: FlightCase


def _usable(paths: Sequence[str | Path], day: date | None, skipped: list[str]) -> list[_Flight]:
    flights = []
    for path in paths:
        flight = clean(read_track(path, day=day))
        if not flight.usable or flight.landing is None or flight.descent_start is None:
            skipped.append(f"{flight.name}: {'; '.join(flight.exclusions) or 'no landing'}")
            continue
        try:
            cube = ascent_weather_cube(flight)
        except PredictorError as exc:
            skipped.append(f"{flight.name}: {exc}")
            continue
        descent = list(flight.descent)
        checkpoints = {k: _checkpoint_fix(descent, flight.landing.alt_m, k) for k in CHECKPOINTS_KM}
        flights.append(
            _Flight(
                flight.name, descent, flight.landing, cube, LevelGround(flight.landing.alt_m), checkpoints,
                flight_case(flight, cube),
            )
        )  # fmt: skip
    return flights


def refit_agreement(model: CalibratedModel, refit: Sequence[Term]) -> str | None:
    """Why the refit on all the flights is not the model's law (None when it is, within 1e-6 relative).

    A fold's law is the model's law without one flight only if, with every flight, the refit gives the
    model back: same terms, same parameters. Otherwise the model was calibrated on other flights,
    weather, payload or step than this evaluation has, and its held-out laws cannot be rebuilt here.
    """
    if [t.name for t in refit] != [t.name for t in model.terms]:
        return f"terms {[t.name for t in refit]} against the model's {[t.name for t in model.terms]}"
    for ours, theirs in zip(refit, model.terms, strict=True):
        for key, value in theirs.parameters().items():
            again = np.asarray(ours.parameters()[key], dtype=float)
            if again.shape != np.shape(value) or not np.allclose(again, value, rtol=1e-6, atol=1e-9):
                return f"{ours.name} {key} {again.tolist()} against the model's {value}"
    return None


def held_out_laws(model: CalibratedModel, flights: Sequence[_Flight]) -> dict[str, CalibratedModel]:
    """Flight name → the model with its law refitted without that flight (leave-one-flight-out).

    Only for the flights the model was calibrated on (its provenance); a flight it never saw flies the
    model itself, whose law is then independent of it. Refused when the model's calibration flights
    are not all here, or when refitting on them does not give the model's own parameters back.
    """
    calibrated = model.provenance.get("flights")
    names = [f.name for f in flights]
    if not model.terms or not isinstance(calibrated, list) or not set(calibrated) & set(names):
        return {}
    where = model.source_path or "the model"
    missing = sorted(set(calibrated) - set(names))
    if missing:
        raise PredictorError(
            f"{where}: its law cannot be held out: it was calibrated on flights not given ({', '.join(missing)})"
        )
    seen = [f for f in flights if f.name in calibrated]
    refit, folds = refit_without_each([f.case for f in seen], model.payload, model.terms)
    disagreement = refit_agreement(model, refit)
    if disagreement is not None:
        raise PredictorError(
            f"{where}: its law cannot be held out: refitted on its {len(seen)} flights it gives {disagreement}"
        )
    return {f.name: dataclasses.replace(model, terms=terms) for f, terms in zip(seen, folds, strict=True)}


def _rate_survey(flights: Sequence[_Flight], model: CalibratedModel) -> dict[tuple[str, float], float]:
    """(flight, checkpoint km) → the whole-descent rate factor on the model's law at that checkpoint."""
    survey = {}
    for flight in flights:
        record = DescentRecord(LivePredictor(flight.cube, model.payload, flight.ground, effects=model.terms).law)
        for fix in flight.descent[:-1]:
            record.add(fix)
            for km, at in flight.checkpoints.items():
                fit = record.rate_fit(fix.alt_m) if at is fix else None
                if fit is not None:
                    survey[(flight.name, km)] = fit.factor
    return survey


def _typical(survey: dict[tuple[str, float], float], leave_out: str | None = None) -> TypicalRate:
    """The geometric mean factor per checkpoint over the surveyed flights (without ``leave_out``)."""
    heights, factors = [], []
    for km in CHECKPOINTS_KM:
        values = [f for (name, k), f in survey.items() if k == km and name != leave_out]
        if values:
            heights.append(km)
            factors.append(round(float(np.exp(np.mean(np.log(values)))), 4))
    return TypicalRate(tuple(heights), tuple(factors))


def evaluate(
    paths: Sequence[str | Path],
    model: CalibratedModel | None = None,
    profile: Payload | None = None,
    day: date | None = None,
) -> Evaluation:
    """Every checkpoint of every usable flight under every configuration.

    ``profile`` is the payload of the textbook law (default: the 2018–2019 test payload the SuperBIT
    flights were predicted with); ``model`` the calibrated model (default: that profile, uncalibrated);
    ``day`` the UTC date of logs that store times of day only. Each flight the model was calibrated
    on flies the model's law refitted without it, and its relative rate is divided by the typical
    factor of the OTHER flights under that law, so that both are held out.
    """
    profile = profile or PROFILES["superbit-test"]
    model = model or CalibratedModel(profile, (), None)
    result = Evaluation(
        flights=[],
        skipped=[],
        cases=[],
        start_errors_km={},
        model_label=_describe(model),
        profile_label=profile.name,
    )
    flights = _usable(paths, day, result.skipped)
    laws = held_out_laws(model, flights)
    result.held_out_laws = {name: law.terms for name, law in laws.items()}
    model_survey = _rate_survey(flights, model)
    result.typical_rate = _typical(model_survey)
    for flight in flights:
        law = laws.get(flight.name, model)
        # The typical factor this flight is divided by: the other flights' fits with its own fold's law
        # (a flight the model never saw flies the model's own law, whose survey is already made).
        survey = model_survey if law is model else _rate_survey(flights, law)
        configs = configurations(_typical(survey, leave_out=flight.name))
        landing, descent = flight.landing, flight.descent
        live = {
            "profile": LivePredictor(flight.cube, profile, flight.ground, NO_CORRECTION),
            "model": LivePredictor(flight.cube, law.payload, flight.ground, NO_CORRECTION, effects=law.terms),
        }
        touchdown_s = _touchdown_s(descent, landing.alt_m)
        start = live["model"].predict_from(descent[0]).prediction.landing
        result.start_errors_km[flight.name] = _errors(start.lat, start.lon, descent[0], landing)[0]
        result.flights.append(flight.name)
        result.fixes_used += len(descent) - 1
        for fix in descent[:-1]:
            for predictor in live.values():
                predictor.observe(fix)
            for km, at in flight.checkpoints.items():
                if at is not fix:
                    continue
                remaining_s = touchdown_s - (fix.time - descent[0].time).total_seconds()
                case = Case(flight.name, km, fix.alt_m - landing.alt_m, {}, {}, {}, {})
                for name, (law, correction) in configs.items():
                    p = live[law].predict_from(fix, correction).prediction
                    d, along, across = _errors(p.landing.lat, p.landing.lon, fix, landing)
                    case.errors_km[name] = d
                    case.along_km[name] = along
                    case.across_km[name] = across
                    case.remaining_drift_km[name] = p.drift_km
                    case.time_error_s[name] = p.descent_s - remaining_s
                result.cases.append(case)
    _leave_one_out(result)
    return result


def _choose(cases: Sequence[Case]) -> tuple[str | None, str | None]:
    """The rate by the mean |remaining-time error|, then the wind by the mean landing error given that rate."""
    timing = [np.mean([abs(c.time_error_s[_combined(r, None)]) for c in cases]) for r in RATE_CHOICES]
    rate = RATE_CHOICES[int(np.argmin(timing))]
    landing = [np.mean([c.errors_km[_combined(rate, w)] for c in cases]) for w in WIND_CHOICES]
    return rate, WIND_CHOICES[int(np.argmin(landing))]


def _leave_one_out(result: Evaluation) -> None:
    for km in CHECKPOINTS_KM:
        cases = [c for c in result.cases if c.checkpoint_km == km]
        if len(cases) < 3:
            continue
        rates: dict[str, str | None] = {}
        winds: dict[str, str | None] = {}
        for i, case in enumerate(cases):
            rates[case.flight], winds[case.flight] = _choose(cases[:i] + cases[i + 1 :])
        result.rate_choice[km] = rates
        result.wind_choice[km] = winds
        result.all_flights_choice[km] = _choose(cases)


def _cases(result: Evaluation, km: float) -> list[Case]:
    return [c for c in result.cases if c.checkpoint_km == km]


def held_out(result: Evaluation, km: float) -> dict[str, tuple[list[float], list[float]]]:
    """Per checkpoint, (landing errors km, remaining-time errors s) of: the profile's plain and rate
    (ρ^-½) predictions, the model's plain and rate predictions, and the model with its held-out
    live corrections."""
    cases = _cases(result, km)
    rows = {
        name: ([c.errors_km[name] for c in cases], [c.time_error_s[name] for c in cases])
        for name in (
            "profile · plain",
            "profile · rate",
            "profile · recent rate",
            PLAIN,
            RATE,
            "model · recent rate",
            RELATIVE,
        )
    }
    names = [result.held_out_name(c) for c in cases]
    rows[HELD_OUT_LIVE] = (
        [c.errors_km[n] for c, n in zip(cases, names, strict=True)],
        [c.time_error_s[n] for c, n in zip(cases, names, strict=True)],
    )
    return rows


def rate_helps(result: Evaluation, km: float) -> bool:
    """The held-out rate choice cut the mean |remaining-time error|: the metric of a vertical correction,
    which the wind does not touch (the landing error it causes is reported beside it)."""
    if km not in result.rate_choice:
        return False
    cases = _cases(result, km)
    chosen = [_combined(result.rate_choice[km][c.flight], None) for c in cases]
    held = np.mean([abs(c.time_error_s[n]) for c, n in zip(cases, chosen, strict=True)])
    return bool(held < np.mean([abs(c.time_error_s[PLAIN]) for c in cases]))


def wind_helps(result: Evaluation, km: float) -> bool:
    """The held-out wind choice cut the mean landing error below the rate choice alone."""
    if km not in result.wind_choice:
        return False
    cases = _cases(result, km)
    with_wind = np.mean([c.errors_km[result.held_out_name(c)] for c in cases])
    without = np.mean([c.errors_km[_combined(result.rate_choice[km][c.flight], None)] for c in cases])
    return bool(with_wind < without)


def fit_live_sigma(result: Evaluation, leave_out: str | None = None) -> LiveErrorModel:
    """RMS along- and cross-track error per checkpoint of what ships (optionally without one flight)."""
    heights, parallel, perpendicular = [], [], []
    for km in CHECKPOINTS_KM:
        cases = [c for c in result.cases if c.checkpoint_km == km and c.flight != leave_out]
        if len(cases) < 3:
            continue
        along = np.array([c.along_km[result.shipped_name(c)] for c in cases])
        across = np.array([c.across_km[result.shipped_name(c)] for c in cases])
        heights.append(km)
        parallel.append(round(float(np.sqrt(np.mean(along**2))), 3))
        perpendicular.append(round(float(np.sqrt(np.mean(across**2))), 3))
    return LiveErrorModel(tuple(heights), tuple(parallel), tuple(perpendicular))


def held_out_coverage(result: Evaluation) -> dict[float, tuple[float, float, int]]:
    """Per checkpoint: the fraction of flights inside the 1σ and 2σ live ellipses fitted WITHOUT them.

    A 2-D Gaussian puts 39.3 % inside 1σ and 86.5 % inside 2σ.
    """
    out = {}
    for km in CHECKPOINTS_KM:
        cases = [c for c in result.cases if c.checkpoint_km == km]
        if len(cases) < 4:
            continue
        m2 = []
        for c in cases:
            model = fit_live_sigma(result, leave_out=c.flight).at(km)
            s_par, s_perp = model.sigmas_km(0.0, 0.0)
            name = result.shipped_name(c)
            m2.append((c.along_km[name] / s_par) ** 2 + (c.across_km[name] / s_perp) ** 2)
        m2a = np.array(m2)
        out[km] = (float(np.mean(m2a <= 1.0)), float(np.mean(m2a <= 4.0)), len(cases))
    return out


def shipped_correction(result: Evaluation) -> LiveCorrection:
    """The all-flights choice in each checkpoint's band, each part only where it helped held-out flights.

    A checkpoint's band reaches half-way to its neighbours (10 km: 7.5–12.5 km above the ground).
    """
    kms = sorted(CHECKPOINTS_KM)
    bands = []
    configs = corrections(result.typical_rate)
    estimators = _rate_estimators(result.typical_rate)
    for i, km in enumerate(kms):
        if km not in result.all_flights_choice:
            continue
        rate, wind = result.all_flights_choice[km]
        use_rate = rate is not None and rate_helps(result, km)
        decay = configs[wind].bands[0].decay_m if wind is not None and wind_helps(result, km) else None
        if not use_rate and decay is None:
            continue
        lower = -math.inf if i == 0 else 500.0 * (kms[i - 1] + km)
        upper = math.inf if i == len(kms) - 1 else 500.0 * (km + kms[i + 1])
        window, typical = estimators[rate] if use_rate and rate is not None else (math.inf, None)
        bands.append(Band(lower, upper, use_rate, decay, window, typical))
    return LiveCorrection(bands=tuple(bands))


SERIES = (
    ("profile · plain", "profile, plain"),
    ("profile · rate", "profile + rate (ρ^-½)"),
    ("profile · recent rate", "profile + last-3-km rate (ρ^-½)"),
    (PLAIN, "model, plain"),
    (RATE, "model + rate"),
    ("model · recent rate", "model + last-3-km rate"),
    (RELATIVE, "model + relative rate"),
    (HELD_OUT_LIVE, "model + held-out live"),
)
"""The rows of the report: label in ``held_out`` → what the report calls it."""


def live_settings(model: CalibratedModel, result: Evaluation, command: str) -> CalibratedModel:
    """The model with what its evaluation kept: the shipped correction bands and the live ellipse."""
    model_s, textbook_s = remaining_time_ratio(result, 20.0) if 20.0 in result.rate_choice else (math.nan, math.nan)
    provenance = {
        **model.provenance,
        "live": {
            "flights": list(result.flights),
            "command": command,
            "evaluated_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
            "remaining_time_error_20km_s": None if math.isnan(model_s) else round(model_s, 1),
            "rho_half_remaining_time_error_20km_s": None if math.isnan(textbook_s) else round(textbook_s, 1),
        },
    }
    settings = LiveSettings(shipped_correction(result), fit_live_sigma(result))
    return dataclasses.replace(model, live=settings, provenance=provenance)


def remaining_time_ratio(result: Evaluation, km: float) -> tuple[float, float]:
    """Mean |remaining-time error| (s) at a checkpoint: the model with its held-out live corrections,
    and the ρ^-½ extrapolation (the profile with its fitted rate)."""
    rows = held_out(result, km)
    return float(np.mean(np.abs(rows[HELD_OUT_LIVE][1]))), float(np.mean(np.abs(rows["profile · rate"][1])))


BOOTSTRAP_RESAMPLES = 2000


def remaining_time_ratio_interval(result: Evaluation, km: float, seed: int = 0) -> tuple[float, float]:
    """95 % interval of that ratio with the flights resampled (paired: both errors of a flight together).

    Why: 28 flights are few, and one flight with a large miss moves a mean; the interval says how much
    of the ratio is the flights that happened to be flown.
    """
    rows = held_out(result, km)
    model = np.abs(np.asarray(rows[HELD_OUT_LIVE][1]))
    textbook = np.abs(np.asarray(rows["profile · rate"][1]))
    picks = np.random.default_rng(seed).integers(0, model.size, size=(BOOTSTRAP_RESAMPLES, model.size))
    ratios = model[picks].mean(axis=1) / textbook[picks].mean(axis=1)
    low, high = np.quantile(ratios, (0.025, 0.975))
    return float(low), float(high)


def _plot(result: Evaluation, kms: list[float], png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2))
    styles = ("o:", "s--", "x:", "o-", "s-", "x-", "d-", "^-")
    for (name, label), style in zip(SERIES, styles, strict=True):
        left.plot(kms, [np.mean(held_out(result, k)[name][0]) for k in kms], style, label=label)
        right.plot(kms, [np.mean(np.abs(held_out(result, k)[name][1])) for k in kms], style, label=label)
    left.axhline(float(np.mean(list(result.start_errors_km.values()))), color="grey", ls=":",
                 label="model from descent start, no updates")  # fmt: skip
    left.set_ylabel("landing error, km (mean)")
    right.set_ylabel("|remaining-time error|, s (mean)")
    for ax in (left, right):
        ax.set_xlabel("height above the ground at the report, km")
        ax.invert_xaxis()
        ax.grid(alpha=0.3)
    left.legend(fontsize=7)
    fig.suptitle(f"Live re-prediction on {len(result.flights)} SuperBIT test flights (ascent winds)")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def _held_out_text(result: Evaluation) -> str:
    """What is held out in the numbers above, and how far the refitted laws spread."""
    if not result.held_out_laws:
        return (
            "The model's law was not calibrated on these flights, so it is held out as it stands; the "
            "live choices and the typical factors are held out per flight."
        )
    spread = []
    for k, term in enumerate(next(iter(result.held_out_laws.values()))):
        for key, value in term.parameters().items():
            values = [terms[k].parameters()[key] for terms in result.held_out_laws.values()]
            if isinstance(value, float) and len(set(values)) > 1:
                spread.append(f"`{term.name}` {key} {min(values):.4g}–{max(values):.4g}")
    return (
        f"Everything is held out: each of the {len(result.held_out_laws)} flights the model was calibrated "
        "on flies the model's law refitted without it (leave-one-flight-out, the calibration's own fit; "
        f"across the folds {', '.join(spread) or 'the parameters do not change'}), the typical factor it "
        "is divided by comes from the other flights' fits with that law, and its live choices from the "
        "other flights' held-out predictions."
    )


def _bands_text(shipped: LiveCorrection) -> str:
    return "; ".join(b.describe() for b in shipped.bands) or "nothing (plain re-prediction everywhere)"


def write_report(result: Evaluation, out_dir: str | Path, command: str) -> Path:
    """docs/planning/live-reprediction.md and its PNG plot."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    kms = [km for km in CHECKPOINTS_KM if km in result.rate_choice]
    _plot(result, kms, out / "live-reprediction.png")
    sigma = fit_live_sigma(result)
    coverage = held_out_coverage(result)
    header = "| height km | flights | " + " | ".join(label for _, label in SERIES) + " |"
    rule = "|---|---|" + "---|" * len(SERIES)
    lines = [
        "# Live re-prediction on the real test flights",
        "",
        f"Generated by `{command}` (do not edit by hand; rerun it).",
        "",
        f"Flights: {len(result.flights)} used"
        + (f", skipped: {'; '.join(result.skipped)}" if result.skipped else "")
        + f"; {result.fixes_used} descent fixes, every one fed to the live predictors (rate fit and wind "
        "legs); predictions only at the checkpoints. Weather: each flight's own ascent winds "
        "(`ascent_weather_cube`); ground: level at the measured landing altitude. Checkpoint = the first "
        "report at or below that height above the ground (skipped for a flight whose next report is "
        f"below {LOWEST_SHARE:.0%} of it, a data gap).",
        "",
        f"Two laws: **profile** = payload `{result.profile_label}` and its drag law (v ∝ ρ^-½); **model** = "
        f"{result.model_label}. Live corrections: **rate** = one factor on the law's descent rate, "
        "fitted (Huber, with a free time offset) on every fix of the descent so far with the same law "
        "that carries it to the ground, so *profile + rate* is the ρ^-½ extrapolation of the measured "
        f"rate; *last-3-km rate* fits only the fixes within {RECENT_RATE_WINDOW_M / 1000:g} km above the "
        "report (the previous estimator); *relative rate* divides the whole-descent factor by the typical "
        "factor (geometric mean) the OTHER flights' own fits gave at that checkpoint, so that the law's "
        "departure shared by most flights (faster than the law high up) is not carried to the ground as "
        "if it were this flight's; **wind L** = the measured wind error, decaying below the capsule "
        f"with L in {', '.join('∞' if math.isinf(d) else f'{d / 1000:g} km' for d in DECAYS_M)}. "
        "**model + held-out live**: for each flight the rate (off, whole descent, last 3 km or relative, by the "
        "mean |remaining-time error| of the OTHER flights) and then the wind (by their mean landing error) that the other "
        "flights preferred at that checkpoint.",
        "",
        "Landing error = distance from the predicted to the measured landing. Remaining-time error = "
        "predicted minus measured time from the report to touchdown; the measured touchdown is the last "
        "airborne fix carried to the ground at the rate of its own interval (the first fix on the ground "
        "is up to one interval late: 3 min on these trackers).",
        "",
    ]

    def table(title: str, cell: Callable[[np.ndarray, np.ndarray], str]) -> None:
        """One row per checkpoint, one ``cell(landing errors, time errors)`` per configuration."""
        lines.extend([f"## {title}", "", header, rule])
        for km in kms:
            rows = held_out(result, km)
            cells = [cell(*rows[n]) for n, _ in SERIES]
            lines.append(f"| {km:g} | {len(rows[PLAIN][0])} | {' | '.join(cells)} |")
        lines.append("")

    table(
        "Landing error, km (mean / median)",
        lambda landing, seconds: f"{np.mean(landing):.2f} / {np.median(landing):.2f}",
    )
    table(
        "Remaining-time error, s (mean |error| / mean signed error)",
        lambda landing, seconds: f"{np.mean(np.abs(seconds)):.0f} / {np.mean(seconds):+.0f}",
    )
    if 20.0 in kms:
        model_s, textbook_s = remaining_time_ratio(result, 20.0)
        low, high = remaining_time_ratio_interval(result, 20.0)
        lines += [
            f"From 20 km the remaining-time error with the model and its held-out live corrections is "
            f"{model_s:.0f} s (mean |error|) against {textbook_s:.0f} s for the ρ^-½ extrapolation of the "
            f"measured rate: {100 * model_s / textbook_s:.0f} % (95 % interval {100 * low:.0f}–{100 * high:.0f} % "
            f"with the flights resampled, {BOOTSTRAP_RESAMPLES} paired bootstrap draws). {_held_out_text(result)} "
            "Typical whole-descent rate factor of all the flights by checkpoint, with the model's own law "
            "(what ships, `predictor.prediction.live.TYPICAL_RATE`): "
            + ", ".join(
                f"{h:g} km {f:.4f}"
                for h, f in zip(result.typical_rate.heights_km, result.typical_rate.factors, strict=True)
            )
            + ".",
            "",
        ]
    lines += [
        "![landing and remaining-time error against height](live-reprediction.png)",
        "",
        "## What ships",
        "",
        "A correction ships in a checkpoint's band only where its held-out choice beat the model's plain "
        "re-prediction on its own metric: the rate on the mean |remaining-time error|, the wind on the "
        "mean landing error (beyond the rate choice).",
        "",
        "| height km | rate: held-out / plain mean |Δt| s | ships | wind: held-out / rate-only mean km | ships "
        "| choice on all flights |",
        "|---|---|---|---|---|---|",
    ]
    for km in kms:
        cases = _cases(result, km)
        rate_names = [_combined(result.rate_choice[km][c.flight], None) for c in cases]
        rate_held = np.mean([abs(c.time_error_s[n]) for c, n in zip(cases, rate_names, strict=True)])
        plain = np.mean([abs(c.time_error_s[PLAIN]) for c in cases])
        wind_held = np.mean([c.errors_km[result.held_out_name(c)] for c in cases])
        rate_only = np.mean([c.errors_km[n] for c, n in zip(cases, rate_names, strict=True)])
        rate, wind = result.all_flights_choice[km]
        lines.append(
            f"| {km:g} | {rate_held:.0f} / {plain:.0f} | {'yes' if rate_helps(result, km) else 'no'} | "
            f"{wind_held:.2f} / {rate_only:.2f} | {'yes' if wind_helps(result, km) else 'no'} | "
            f"{rate or 'no rate'}, {wind or 'no wind'} |"
        )
    shown = ("plain", "rate", "recent rate", "wind 2 km", "wind 8 km", "wind const", "rate + wind 2 km")
    lines += [
        "",
        "Mean landing error (km) of fixed model configurations on all flights (not held out; shows the shape):",
        "",
        "| height km | " + " | ".join(shown) + " |",
        "|---|" + "---|" * len(shown),
    ]
    for km in kms:
        cases = _cases(result, km)
        lines.append(
            f"| {km:g} | "
            + " | ".join(f"{np.mean([c.errors_km[f'model · {n}'] for c in cases]):.2f}" for n in shown)
            + " |"
        )
    starts = list(result.start_errors_km.values())
    lines += [
        "",
        f"The model from the descent start with no live update: median {np.median(starts):.2f} km, "
        f"mean {np.mean(starts):.2f} km over {len(starts)} flights.",
        "",
        "Live ellipse (`predictor.prediction.live.LIVE_ERROR_MODEL`): RMS along/across-track error of what ships, "
        "per height, and the held-out coverage (each flight against σ fitted without it; a 2-D Gaussian "
        "gives 39.3 % in 1σ, 86.5 % in 2σ):",
        "",
        "| height km | σ∥ km | σ⊥ km | in 1σ | in 2σ |",
        "|---|---|---|---|---|",
        *[
            f"| {h:g} | {sp:.2f} | {sc:.2f} | {100 * coverage[h][0]:.0f} % | {100 * coverage[h][1]:.0f} % |"
            for h, sp, sc in zip(
                sigma.heights_km, sigma.sigma_parallel_km, sigma.sigma_perpendicular_km, strict=True
            )
            if h in coverage
        ],
        "",
        "What ships (`predictor.prediction.live.DEFAULT_CORRECTION`, bands of height above the ground): "
        + _bands_text(shipped_correction(result))
        + "; elsewhere a plain re-prediction from the report.",
        "",
        "Choices per flight (held-out):",
        "",
    ]
    for km in kms:
        counts: dict[str, int] = {}
        for flight in result.rate_choice[km]:
            name = _combined(result.rate_choice[km][flight], result.wind_choice[km][flight])
            counts[name] = counts.get(name, 0) + 1
        lines.append(f"* {km:g} km: " + ", ".join(f"{n} ×{c}" for n, c in sorted(counts.items())))
    md = out / "live-reprediction.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return md

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

* ``plain``: restarted from the report, nothing learned (``drs live --no-correction``);
* ``λ``: this flight's own rate factor on the law, the Bayesian update of a prior with the descent so
  far (``predictor.prediction.live.update_rate``). The same estimator on both laws: the prior is the
  spread of the OTHER flights' remaining-descent λ at that height on that law, and the discrepancy
  (how a record's λ departs from the remaining descent's) is measured on the OTHER flights with that
  law, so the textbook law with λ is the fair baseline of the model with λ;
* ``wind L`` / ``λ + wind L``: plus the measured wind error, decaying below the capsule with L.

Each correction is chosen leave-one-flight-out on the metric it acts on: the rate (a vertical effect)
on the remaining-time error, the wind (horizontal) on the landing error, each held-out flight getting
what the OTHER flights preferred. A correction ships (in the model file's live settings, ``--save-model``) only
in the bands where it helped held-out flights. The same held-out errors fit the live ellipse.

The weather is each flight's own ascent winds unless GRIB files are given (``--weather``, as ``drs
calibrate`` takes them), and the ground is level at the measured landing unless a DEM is given.

Every fix of the track is used: each one enters the rate fit and the wind legs (a 1 Hz track of
10,000 fixes is a few hundred leg probes and six checkpoints), and predictions are made only at the
checkpoints.
"""

from __future__ import annotations

import dataclasses
import functools
import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass, field
from datetime import UTC, date, datetime
from pathlib import Path

import numpy as np

from predictor.calibration.residuals import FlightCase, flight_case
from predictor.calibration.selection import refit_without_each
from predictor.calibration.wind_gain import GainFit, fit_gain, gain_sample, gained
from predictor.descent import PROFILES, Payload, RatePrior, Term
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError, WeatherError
from predictor.prediction import (
    CONSTANT_WIND_M,
    DISTANCE_RATIO_LIMITS,
    GEOD,
    LIVE_PROBABILITIES,
    NO_CORRECTION,
    NO_DISCREPANCY,
    OWN_RATE,
    Band,
    CalibratedModel,
    DescentRecord,
    LiveCorrection,
    LiveErrorModel,
    LivePredictor,
    LiveSettings,
    RateDiscrepancy,
    WindGain,
    n_sigma_for,
)
from predictor.tracks import Fix, ascent_weather_cube, clean, read_track

CHECKPOINTS_KM = (25.0, 20.0, 15.0, 10.0, 5.0, 2.0)
LOWEST_SHARE = 0.6
"""A checkpoint's report must be at least this share of its height (a data gap skips the checkpoint)."""
DECAYS_M = (1000.0, 2000.0, 4000.0, 8000.0, 16000.0, math.inf)
OWN = "λ"
"""The rate correction: this flight's own λ, updated from the prior with the descent so far."""
PLAIN = "model · plain"
RATE = "model · λ"
PLAIN_RESTART = "profile · plain"
TEXTBOOK_RATE = "profile · λ"
SHIPPED = "what ships"
WHOLE_WIND = "what ships, all of the wind"
BAND_SWITCH = "training band switch"
PLAIN_ABOVE_M = 22500.0
WIND_BELOW_M = 12500.0
SHIPPED_DECAY_M = 4000.0
"""What ships (issue #30), by height above the ground: above ``PLAIN_ABOVE_M`` the plain restart from
the nominal payload; below it the same law with this flight's own λ update; below ``WIND_BELOW_M`` also
the measured wind error, decaying below the capsule with L = ``SHIPPED_DECAY_M``, times the share of it
the training flights' landings wanted (``wind_gains``: a gain, shrunk toward none by its uncertainty, not
a switch). The bands are one rule, learned from no training set, so a training set's luck cannot switch
them.

Why these heights, both found on SuperBIT leave-one-out before any split across seasons or payloads
existed and then checked on every split (docs/planning.md): at the 25 km checkpoint a SuperBIT record is
the burst's 3-minute interval and at most one more fix, and λ from it made the remaining time worse
(1.04× the plain restart leave-one-out, 1.02–1.10× on three of four splits), while from 20 km down it
beat the plain restart everywhere; a decaying wind correction helped held-out landings only from about
10 km down, with L = 4 km (issue #21), and carried higher it lost across seasons (2018 → 2019 from
20 km 1.11×). Measured beside it on every split: the training flights' band switch (what shipped
before), textbook + λ everywhere, the flight's own evidence with the training flights as a prior, and
the band choice shrunk toward the plain restart by its held-out interval."""


def _wind_label(decay: float) -> str:
    return "const" if math.isinf(decay) else f"{decay / 1000:g} km"


def corrections() -> dict[str, LiveCorrection]:
    """Every live correction tried on the calibrated model, by name."""
    configs = {"plain": NO_CORRECTION, OWN: OWN_RATE}
    for decay in DECAYS_M:
        stored = 10 * CONSTANT_WIND_M if math.isinf(decay) else decay
        configs[f"wind {_wind_label(decay)}"] = LiveCorrection.everywhere(False, stored)
        configs[f"{OWN} + wind {_wind_label(decay)}"] = LiveCorrection.everywhere(True, stored)
    return configs


PROFILE_CORRECTIONS = {
    "plain": NO_CORRECTION,
    OWN: OWN_RATE,
    f"{OWN} + wind {_wind_label(SHIPPED_DECAY_M)}": LiveCorrection.everywhere(True, SHIPPED_DECAY_M),
}
"""On the textbook law the baselines (the plain restart, and the same λ estimator as the model's) and
what ships below ``WIND_BELOW_M``."""
TEXTBOOK_RATE_WIND = f"profile · {OWN} + wind {_wind_label(SHIPPED_DECAY_M)}"
MODEL_RATE_WIND = f"model · {OWN} + wind {_wind_label(SHIPPED_DECAY_M)}"
TEXTBOOK_RATE_GAIN = f"{TEXTBOOK_RATE_WIND} × g"
MODEL_RATE_GAIN = f"{MODEL_RATE_WIND} × g"
GAINED = {TEXTBOOK_RATE_GAIN: (TEXTBOOK_RATE, TEXTBOOK_RATE_WIND), MODEL_RATE_GAIN: (RATE, MODEL_RATE_WIND)}
"""What ships below ``WIND_BELOW_M``, on each law → (that law with λ, the same with all of the measured
wind error): the wind flown times the gain the other (training) flights' landings learned
(``wind_gains``). Not replayed: its landing is ``gain`` of the way from the first's to the second's
(``wind_gain.gained``; exact in the horizontally uniform cube of each flight's ascent winds), its
remaining time the first's (the wind does not move the vertical)."""
GAIN_KMS = tuple(km for km in CHECKPOINTS_KM if 1000.0 * km < WIND_BELOW_M)
"""The report heights the wind gain is learned at (where what ships flies the wind)."""


def live_law(result: Evaluation, leave_out: str | None = None) -> str:
    """The law live re-prediction flies below ``PLAIN_ABOVE_M``: ``model`` only where the model's law with
    this flight's own λ beat the payload's law with the same λ estimator on these flights (without
    ``leave_out``) beyond its 95 % interval, each flight's mean |remaining-time error| over its reports
    below that height (the upper end of the ratio's paired-bootstrap interval below 1); else ``payload``.

    Why an interval and not the point estimate: the calibrated law also flies its pooled λ, which did
    not carry from one season or payload to another, and on 15–30 real flights it was within a few
    percent of the payload's law (0.98–0.99, the interval's upper end 1.007–1.08, on every training set
    of docs/planning.md), so it must be clearly better on the flights at hand to be flown; a law whose
    shape is right (an independent world with the library's own two-regime form) is, by a factor of
    several."""
    key = leave_out or ""
    if key not in result.law_choice:
        ratio = law_ratio(result, leave_out)
        result.law_choice[key] = "model" if ratio is not None and ratio[2] < 1.0 else "payload"
    return result.law_choice[key]


def law_ratio(result: Evaluation, leave_out: str | None = None) -> tuple[float, float, float] | None:
    """The model's law + λ ÷ the payload's law + λ, each flight's mean |remaining-time error| over its
    reports below ``PLAIN_ABOVE_M`` (without ``leave_out``), with its 95 % paired-bootstrap interval over
    the flights (None: the model has no terms, or fewer than 3 flights)."""
    below = [c for c in result.cases if 1000.0 * c.checkpoint_km < PLAIN_ABOVE_M and c.flight != leave_out]
    flights = sorted({c.flight for c in below})
    if not result.model_terms or len(flights) < 3:
        return None

    def mean_error(name: str, flight: str) -> float:
        return float(np.mean([abs(c.time_error_s[name]) for c in below if c.flight == flight]))

    return ratio_interval(
        [mean_error(RATE, f) for f in flights], [mean_error(TEXTBOOK_RATE, f) for f in flights]
    )


def configurations() -> dict[str, tuple[str, LiveCorrection]]:
    """'law · correction' → (law, correction): the profile baselines, then every model correction."""
    configs = {f"profile · {n}": ("profile", c) for n, c in PROFILE_CORRECTIONS.items()}
    configs.update({f"model · {n}": ("model", c) for n, c in corrections().items()})
    return configs


def _combined(rate: str | None, wind: str | None) -> str:
    """The model configuration named by a rate choice (λ or None) and a wind choice ('wind 2 km' or None)."""
    if wind is None:
        return f"model · {rate}" if rate else PLAIN
    return f"model · {f'{rate} + ' if rate else ''}{wind}"


RATE_CHOICES: tuple[str | None, ...] = (None, OWN)
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
    time_sigma_s: dict[str, float] = field(default_factory=dict)
    """The 1σ of the remaining time the λ update stated, s (configurations that update λ)."""
    remaining_s: float = 0.0
    """The measured remaining descent time, s."""
    evidence: dict[str, float] = field(default_factory=dict)
    """This flight's own evidence at the report (``LivePredictor.self_check``), by vertical candidate."""
    distance_km_h: dict[str, float] = field(default_factory=dict)
    """X of the live ellipse (``ascent_distance_km_h``), by configuration; empty when the weather does
    not say where it was measured."""
    landings: dict[str, tuple[float, float]] = field(default_factory=dict)
    """The predicted landing (lat, lon), by configuration: where the wind gain's least squares and the
    landing it flies are measured (``wind_gain``)."""
    report: Fix | None = None
    """The report predicted from."""
    truth: Fix | None = None
    """The measured landing."""


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
    rate_laws: dict[str, tuple[RatePrior | None, RateDiscrepancy]] = field(default_factory=dict)
    """Law ('model', 'profile') → the λ prior and discrepancy of ALL the flights with it (what ships)."""
    weather_label: str = "each flight's own ascent winds (`ascent_weather_cube`)"
    ground_label: str = "level at the measured landing altitude"
    model_terms: tuple[Term, ...] = ()
    """The model's own terms (none: its law is the payload's drag law)."""
    held_out_laws: dict[str, tuple[Term, ...]] = field(default_factory=dict)
    """Flight → the model's terms refitted without it, for the flights the model was calibrated on
    (each flies its own fold's law); empty when the model's law never saw these flights."""
    training: Evaluation | None = None
    """Train → score: the training flights' own (leave-one-out) evaluation, which made every choice
    for the scored flights here and decides what ships (None: leave-one-out on these flights)."""
    law_choice: dict[str, str] = field(default_factory=dict, repr=False, compare=False)
    """``live_law`` of these flights, by the flight left out ('' for none), once computed."""
    gain_fits: dict[tuple[str, str], tuple[GainFit, ...]] = field(
        default_factory=dict, repr=False, compare=False
    )
    """``wind_gain_fits`` of these flights, by (configuration, the flight left out or ''), once computed."""

    def band_switch_name(self, case: Case) -> str:
        """The configuration the training flights' band switch (what shipped before issue #30) gives
        this case: its held-out choices, rate and wind alike. Measured, not shipped."""
        km = case.checkpoint_km
        return _combined(self.rate_choice[km][case.flight], self.wind_choice[km][case.flight])

    def shipped_name(self, case: Case) -> str:
        """What ships for this case (``PLAIN_ABOVE_M``): the plain restart in the top band, the live law
        (``live_law``, chosen without this flight) with this flight's own λ below it, and the wind
        below ``WIND_BELOW_M``."""
        height_m = 1000.0 * case.checkpoint_km
        if height_m >= PLAIN_ABOVE_M:
            return PLAIN_RESTART
        law = live_law(self.training or self, leave_out=case.flight)
        if law == "model":
            return RATE if height_m >= WIND_BELOW_M else MODEL_RATE_GAIN
        return TEXTBOOK_RATE if height_m >= WIND_BELOW_M else TEXTBOOK_RATE_GAIN

    def whole_wind_name(self, case: Case) -> str:
        """What shipped before the wind gain: the same, with all of the measured wind error."""
        name = self.shipped_name(case)
        return GAINED[name][1] if name in GAINED else name


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
    ground: Terrain
    checkpoints: dict[float, Fix | None]
    case: FlightCase


def _usable(
    paths: Sequence[str | Path],
    day: date | None,
    skipped: list[str],
    weather: WeatherCube | None,
    terrain: Terrain | None,
    law_terrain: Terrain | None,
) -> list[_Flight]:
    """The flights that can be replayed; every other one goes to ``skipped`` with the reason.

    Each flight's ``case`` (what the law is refitted on) is cleaned and scored on ``law_terrain``, the
    ground the model was calibrated on, which need not be this evaluation's."""
    flights = []
    for path in paths:
        flight = clean(read_track(path, day=day), terrain)
        if not flight.usable or flight.landing is None or flight.descent_start is None:
            skipped.append(f"{flight.name}: {'; '.join(flight.exclusions) or 'no landing found'}")
            continue
        try:
            cube = weather if weather is not None else ascent_weather_cube(flight)
        except PredictorError as exc:
            hint = " (a descent-only track needs --weather)" if isinstance(exc, WeatherError) else ""
            skipped.append(f"{flight.name}: no ascent winds: {exc}{hint}")
            continue
        descent = list(flight.descent)
        if len(descent) < 3:
            skipped.append(f"{flight.name}: {len(descent)} descent fixes, too few to replay")
            continue
        checkpoints = {k: _checkpoint_fix(descent, flight.landing.alt_m, k) for k in CHECKPOINTS_KM}
        if not any(checkpoints.values()):
            skipped.append(f"{flight.name}: no report within {LOWEST_SHARE:.0%} of any checkpoint height")
            continue
        ground = terrain if terrain is not None else LevelGround(flight.landing.alt_m)
        flights.append(
            _Flight(
                flight.name,
                descent,
                flight.landing,
                cube,
                ground,
                checkpoints,
                flight_case(
                    flight if law_terrain is terrain else clean(read_track(path, day=day), law_terrain),
                    cube,
                    law_terrain,
                ),
            )
        )
    return flights


MIN_EVALUATED_FLIGHTS = 3
"""The live error model (``fit_live_sigma``) needs three flights at a checkpoint height; with fewer an
evaluation has nothing to say how sure a live prediction is."""
REFIT_RTOL = 1e-4
"""A refit within this of the model's parameters is the model's law. Why not tighter: the optimiser
stops a few 1e-6 apart on the same data when the flights come in another order or another machine
sums them differently (a 1.6e-6 refusal was seen), while a different weather, ground or step moves the
parameters by percent (the exponent's fold-to-fold spread on SuperBIT is 15 %)."""
ASCENT_WEATHER = "each flight's own ascent winds"


def refit_agreement(model: CalibratedModel, refit: Sequence[Term]) -> str | None:
    """Why the refit on all the flights is not the model's law (None when it is, within ``REFIT_RTOL``).

    A fold's law is the model's law without one flight only if, with every flight, the refit gives the
    model back: same terms, same parameters. Otherwise the model was calibrated on other flights,
    weather, payload or step than this evaluation has, and its held-out laws cannot be rebuilt here.
    """
    if [t.name for t in refit] != [t.name for t in model.terms]:
        return f"terms {[t.name for t in refit]} against the model's {[t.name for t in model.terms]}"
    for ours, theirs in zip(refit, model.terms, strict=True):
        for key, value in theirs.parameters().items():
            again = np.asarray(ours.parameters()[key], dtype=float)
            if again.shape != np.shape(value):
                return f"{ours.name} {key} of shape {again.shape} against the model's {np.shape(value)}"
            if not np.allclose(again, value, rtol=REFIT_RTOL, atol=1e-9):
                gap = float(np.max(np.abs(again - value) / np.maximum(np.abs(value), 1e-9)))
                return (
                    f"{ours.name} {key} {np.round(again, 6).tolist()} against the model's "
                    f"{np.round(np.asarray(value, dtype=float), 6).tolist()} ({gap:.2g} relative, "
                    f"tolerance {REFIT_RTOL:g})"
                )
    return None


def refit_causes(model: CalibratedModel, weather_label: str, step_m: float) -> str:
    """What differs between the model's calibration and this evaluation that would move a refit: the
    weather, the ground, the step, the version (from the model's provenance); said when nothing does."""
    provenance = model.provenance
    causes = []
    theirs = str(provenance.get("weather", ""))
    if theirs and theirs.startswith(ASCENT_WEATHER) != weather_label.startswith(ASCENT_WEATHER):
        causes.append(f"it was calibrated on {theirs}, this evaluation flies {weather_label}")
    elif theirs and not theirs.startswith(ASCENT_WEATHER) and theirs != weather_label:
        causes.append(f"its weather was {theirs}, here {weather_label}")
    if "dem" not in provenance:
        causes.append(
            "it does not record the DEM it was calibrated with (saved before models did; recalibrate)"
        )
    if "step_m" not in provenance:
        causes.append(f"it does not record its calibration step (refitted at {step_m:g} m)")
    from_version = provenance.get("project_version")
    if from_version is not None and from_version != _project_version():
        causes.append(f"it was calibrated by version {from_version}, this is {_project_version()}")
    return "; ".join(causes) or (
        "the weather, ground, step and flights are the calibration's own: the refit's optimiser "
        "stopped elsewhere (report this)"
    )


def _project_version() -> str:
    from importlib import metadata

    try:
        return metadata.version("drs-console")
    except metadata.PackageNotFoundError:
        return "unknown"


def held_out_laws(
    model: CalibratedModel, flights: Sequence[_Flight], weather_label: str = ASCENT_WEATHER
) -> dict[str, CalibratedModel]:
    """Flight name → the model with its law refitted without that flight (leave-one-flight-out).

    Only for the flights the model was calibrated on (its provenance); a flight it never saw flies the
    model itself, whose law is then independent of it. Refitted at the calibration's own step and on
    its own ground (``_usable``'s ``law_terrain``). Refused when the model's calibration flights are not
    all here, or when refitting on them does not give the model's own parameters back, with the
    differences between the calibration and this evaluation that could cause it.
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
    step_m = float(model.provenance.get("step_m", DEFAULT_CALIBRATION_STEP_M))
    refit, folds = refit_without_each([f.case for f in seen], model.payload, model.terms, step_m)
    disagreement = refit_agreement(model, refit)
    if disagreement is not None:
        raise PredictorError(
            f"{where}: its law cannot be held out: refitted on its {len(seen)} flights it gives {disagreement}; "
            f"possible cause: {refit_causes(model, weather_label, step_m)}"
        )
    return {f.name: dataclasses.replace(model, terms=terms) for f, terms in zip(seen, folds, strict=True)}


DEFAULT_CALIBRATION_STEP_M = 200.0
"""``drs calibrate``'s default step, for a model saved before its step was recorded."""


SURVEY_HEIGHTS_KM = tuple(1.0 + 2.5 * k for k in range(12))
"""Heights (km above the ground) at which a law's λ prior and discrepancy are tabulated: 1 to 28.5 km."""
SURVEY_BAND_M = 3000.0
"""A flight counts at a table height through its fix nearest to it, if within this far."""


@dataclass(frozen=True)
class _Sample:
    """One fix of one flight: what its record said there, and what the rest of its descent did."""

    flight: str
    height_m: float
    record_log: float | None
    """ln λ the record measured down to this fix (``DescentRecord.rate_fit``; None: too little record)."""
    remaining_log: float
    """ln(law's seconds from here to the ground / measured seconds): the λ the next prediction needed."""


@dataclass(frozen=True)
class _Survey:
    """Every flight's λ on one law: of its whole descent, and at each fix of its record."""

    whole: dict[str, float]
    """Flight → ln λ of the whole descent (the record from its top down to the last airborne fix)."""
    samples: list[_Sample]


def _rate_survey(flights: Sequence[_Flight], payload: Payload, terms: Sequence[Term]) -> _Survey:
    """At each flight's fix nearest each of ``SURVEY_HEIGHTS_KM`` (what ``rate_law`` uses), the λ of the
    descent that was still to come (the law's remaining seconds against the measured ones, to the
    touchdown the evaluation scores against), and the record's λ as live re-prediction measures it at
    that fix or, where the record says nothing yet (just below the top), at the first fix below it that
    has one, within ``SURVEY_BAND_M``.

    Only those fixes are fitted, not every one: a 1 Hz record has thousands, and each fit is a pass over
    its window."""
    whole, samples = {}, []
    for flight in flights:
        record = DescentRecord(LivePredictor(flight.cube, payload, flight.ground, effects=terms).law)
        touchdown_s = _touchdown_s(flight.descent, flight.landing.alt_m)
        heights = np.array([fix.alt_m - flight.landing.alt_m for fix in flight.descent[:-1]])
        wanted = {int(np.argmin(np.abs(heights - 1000.0 * km))): km for km in SURVEY_HEIGHTS_KM}
        pending: list[float] = []
        for i, fix in enumerate(flight.descent[:-1]):
            record.add(fix)
            law_s = record.remaining_model_s(fix.alt_m) or 0.0
            measured_s = touchdown_s - (fix.time - flight.descent[0].time).total_seconds()
            if law_s <= 0.0 or measured_s <= 0.0:
                continue
            remaining = math.log(law_s / measured_s)
            if i in wanted:
                samples.append(_Sample(flight.name, float(heights[i]), None, remaining))
                pending.append(wanted[i])
            pending = [km for km in pending if heights[i] > 1000.0 * km - SURVEY_BAND_M]
            fit = record.rate_fit(fix.alt_m) if pending else None
            if fit is not None:
                # The record's λ here against the remaining descent's λ at this same fix.
                samples.append(_Sample(flight.name, float(heights[i]), math.log(fit.factor), remaining))
                pending = []
        fit = record.rate_fit(flight.descent[-2].alt_m, window_m=math.inf)
        if fit is not None:
            whole[flight.name] = math.log(fit.factor)
    return _Survey(whole, samples)


def rate_law(survey: _Survey, leave_out: str | None = None) -> tuple[RatePrior | None, RateDiscrepancy]:
    """The λ prior and discrepancy of the surveyed flights (without ``leave_out``).

    Prior: the median and spread of their whole-descent ln λ (what a pre-flight prediction and a model
    without a table fly). Table, at each of ``SURVEY_HEIGHTS_KM`` with at least three flights there (each
    through its fix nearest the height): the remaining descent's ln λ (mean, standard deviation), and
    ln(record λ / remaining λ) (median, 1.4826 × MAD: robust to the flight whose canopy misbehaves),
    each flight through its nearest fix with a record λ; where fewer than three flights have one (high
    up, just below the top), the departure of the nearest height that has them.
    """
    logs = np.array([v for name, v in survey.whole.items() if name != leave_out])
    prior = None
    if logs.size >= 3:
        prior = RatePrior(float(np.exp(logs.mean())), min(float(logs.std(ddof=1)), 1.0), int(logs.size))
    columns: list[tuple[float, float | None, float | None, float, float, int]] = []
    for km in SURVEY_HEIGHTS_KM:
        remaining = _nearest(survey, km, leave_out, with_record=False)
        if len(remaining) < 3:
            continue
        measured = _nearest(survey, km, leave_out, with_record=True)
        bias = spread = None
        if len(measured) >= 3:
            departure = np.array(
                [s.record_log - s.remaining_log for s in measured if s.record_log is not None]
            )
            bias = float(np.median(departure))
            spread = round(1.4826 * float(np.median(np.abs(departure - bias))), 5)
            bias = round(bias, 5)
        logs_ = np.array([s.remaining_log for s in remaining])
        columns.append((km, bias, spread, round(float(logs_.mean()), 5),
                        round(min(float(logs_.std(ddof=1)), 1.0), 5), len(remaining)))  # fmt: skip
    known = [c for c in columns if c[1] is not None]
    if not known:
        return prior, NO_DISCREPANCY
    filled = []
    for km, bias, spread, mean, sigma, count in columns:
        if bias is None:
            nearest = min(known, key=lambda c: abs(c[0] - km))
            bias, spread = nearest[1], nearest[2]
        filled.append((km, bias, spread, mean, sigma, count))
    heights, bias_, spread_, mean_, sigma_, count_ = zip(*filled, strict=True)
    return prior, RateDiscrepancy(heights, bias_, spread_, mean_, sigma_, count_)


def _nearest(survey: _Survey, km: float, leave_out: str | None, with_record: bool) -> list[_Sample]:
    """Each flight's sample nearest ``km`` (within ``SURVEY_BAND_M``), among those with a record λ if
    ``with_record``, else among those without (one per flight at its fix nearest the height)."""
    nearest: dict[str, _Sample] = {}
    for sample in survey.samples:
        distance = abs(sample.height_m - 1000.0 * km)
        if (
            sample.flight == leave_out
            or distance >= SURVEY_BAND_M
            or (sample.record_log is not None) != with_record
        ):
            continue
        if sample.flight not in nearest or distance < abs(nearest[sample.flight].height_m - 1000.0 * km):
            nearest[sample.flight] = sample
    return list(nearest.values())


def conservative_discrepancy(laws: Sequence[RateDiscrepancy]) -> RateDiscrepancy:
    """The record-to-remaining departure to fly with a law nobody evaluated live: at each height every
    law here measured (laws of several payloads' flights), no median taken off and the largest
    root-mean-square log departure (√(median² + spread²)) as the spread, and as the prior of the
    remaining λ the law itself with the largest root-mean-square remaining ln λ as its width
    (``live.DEFAULT_DISCREPANCY``)."""
    heights = sorted(set.intersection(*(set(d.heights_km) for d in laws)))
    spread, remaining = [], []
    for km in heights:
        spread.append(round(max(math.hypot(*d.at(km)) for d in laws), 3))
        priors = [d.remaining_prior(km) for d in laws]
        remaining.append(round(max((p.log_sigma for p in priors if p is not None), default=0.0), 3))
    flights = min((min(d.remaining_flights) for d in laws if d.remaining_flights), default=0)
    if not flights:
        return RateDiscrepancy(tuple(heights), (0.0,) * len(heights), tuple(spread))
    return RateDiscrepancy(tuple(heights), (0.0,) * len(heights), tuple(spread),
                           (0.0,) * len(heights), tuple(remaining), (flights,) * len(heights))  # fmt: skip


def measured_discrepancies(
    track_sets: Sequence[Sequence[str | Path]],
    model: CalibratedModel,
    profile: Payload | None = None,
    day: date | None = None,
) -> list[RateDiscrepancy]:
    """The record-to-remaining departure of every set of flights (a payload, a team) on the model's law
    and on the profile's, each flight with its own ascent winds and level ground at its landing: what
    ``conservative_discrepancy`` pools into the default of a model without live settings."""
    profile = profile or PROFILES["superbit-test"]
    laws = []
    for paths in track_sets:
        flights = _usable(paths, day, [], None, None, None)
        for payload, terms in ((model.payload, model.terms), (profile, ())):
            laws.append(rate_law(_rate_survey(flights, payload, terms))[1])
    return laws


def _refuse_none(flights: Sequence[_Flight], skipped: Sequence[str]) -> None:
    if not flights:
        raise PredictorError(f"no usable flight among the tracks given: {'; '.join(skipped)}")


def _refuse_too_few(flights: Sequence[_Flight], skipped: Sequence[str], needs: str) -> None:
    """Flights each held out among the others: the live error model needs ``MIN_EVALUATED_FLIGHTS``."""
    if len(flights) < MIN_EVALUATED_FLIGHTS:
        raise PredictorError(
            f"{needs} needs at least {MIN_EVALUATED_FLIGHTS} usable flights, got {len(flights)}"
            + (f" (skipped: {'; '.join(skipped)})" if skipped else "")
        )


def _each_held_out(
    result: Evaluation,
    flights: list[_Flight],
    model: CalibratedModel,
    profile: Payload,
    progress: Callable[[str, int, int | None], None] | None,
) -> Evaluation:
    """Leave-one-flight-out on ``flights``: each flown with what the others measured and chose."""
    _replay(result, flights, flights, model, profile, progress)
    _leave_one_out(result)
    _add_gained(result)
    return result


def evaluate_live(
    paths: Sequence[str | Path],
    model: CalibratedModel | None = None,
    profile: Payload | None = None,
    day: date | None = None,
    weather: WeatherCube | None = None,
    terrain: Terrain | None = None,
    train: Sequence[str | Path] | None = None,
    progress: Callable[[str, int, int | None], None] | None = None,
) -> Evaluation:
    """Every checkpoint of every usable flight under every configuration.

    ``profile`` is the payload of the textbook law (default: the 2018–2019 test payload the SuperBIT
    flights were predicted with); ``model`` the calibrated model (default: that profile, uncalibrated);
    ``day`` the UTC date of logs that store times of day only; ``weather`` GRIB weather for every
    flight (default: each flight's ascent winds); ``terrain`` a DEM (default: level ground at each
    measured landing).

    Without ``train``, leave-one-flight-out on ``paths``: each flight the model was calibrated on flies
    the model's law refitted without it, and on both laws its λ prior and discrepancy and its live
    choices come from the OTHER flights. With ``train``, ``paths`` are scored with what the training
    flights alone measured and chose (their own evaluation, leave-one-out among themselves, is
    ``Evaluation.training``): a season, a payload or a team held out whole. The model must then not
    have been calibrated on a scored flight.
    ``progress(stage, done, total)`` is told once per scored flight (a run takes minutes).
    """
    profile = profile or PROFILES["superbit-test"]
    model = model or CalibratedModel(profile, (), None)
    if train is None:
        result = _evaluation(model, profile, weather, terrain)
        flights = _usable(paths, day, result.skipped, weather, terrain, _law_terrain(model, terrain))
        _refuse_none(flights, result.skipped)
        _refuse_too_few(flights, result.skipped, "a live evaluation")
        return _each_held_out(result, flights, model, profile, progress)
    result = _evaluation(model, profile, weather, terrain)
    scored = _usable(paths, day, result.skipped, weather, terrain, terrain)
    _refuse_none(scored, result.skipped)
    both = sorted({f.name for f in scored} & {read_track(path, day=day).name for path in train})
    if both:
        raise PredictorError(f"flights both trained and scored on: {', '.join(both)}")
    seen = model.provenance.get("flights")
    if model.terms and isinstance(seen, list) and set(seen) & {f.name for f in scored}:
        raise PredictorError(
            f"{model.source_path or 'the model'} was calibrated on scored flights "
            f"({', '.join(sorted(set(seen) & {f.name for f in scored}))}): calibrate it on the training "
            "flights alone (drs calibrate --tracks TRAIN... --save-model PATH)"
        )
    training = _evaluation(model, profile, weather, terrain)
    trained = _usable(train, day, training.skipped, weather, terrain, _law_terrain(model, terrain))
    _refuse_too_few(trained, training.skipped, "--train")
    result.training = _each_held_out(training, trained, model, profile, progress)
    kept = [f for f in _usable(train, day, [], weather, terrain, terrain) if f.name in training.flights]
    _replay(result, kept, scored, model, profile, progress)
    for km, choice in training.all_flights_choice.items():
        result.rate_choice[km] = {f: choice[0] for f in result.flights}
        result.wind_choice[km] = {f: choice[1] for f in result.flights}
        result.all_flights_choice[km] = choice
    _add_gained(result)
    return result


def _evaluation(
    model: CalibratedModel, profile: Payload, weather: WeatherCube | None, terrain: Terrain | None
) -> Evaluation:
    result = Evaluation(
        flights=[],
        skipped=[],
        cases=[],
        start_errors_km={},
        model_label=_describe(model),
        profile_label=profile.name,
        model_terms=model.terms,
    )
    if weather is not None:
        result.weather_label = weather.source
    if terrain is not None:
        result.ground_label = "the DEM given (--dem)"
    return result


def _law_terrain(model: CalibratedModel, terrain: Terrain | None) -> Terrain | None:
    """The ground the model's calibration scored its flights on, so that its law is refitted exactly as
    it was fitted whatever ``--dem`` this evaluation has (a model saved before its DEM was recorded:
    this evaluation's ground)."""
    if "dem" not in model.provenance:
        return terrain
    dem = model.provenance["dem"]
    if dem is None:
        return None
    try:
        return Terrain.from_dir(str(dem))
    except (OSError, PredictorError) as exc:
        raise PredictorError(
            f"{model.source_path or 'the model'}: its law cannot be held out: the DEM it was calibrated "
            f"with ({dem}) cannot be read here: {exc}"
        ) from None


def _replay(
    result: Evaluation,
    surveyed: Sequence[_Flight],
    scored: Sequence[_Flight],
    model: CalibratedModel,
    profile: Payload,
    progress: Callable[[str, int, int | None], None] | None = None,
) -> None:
    """Replay each of ``scored`` under every configuration, with the λ prior and discrepancy of the
    ``surveyed`` flights other than itself (the same list: leave-one-out; disjoint: train → score)."""
    laws = held_out_laws(model, surveyed, result.weather_label) if surveyed is scored else {}
    result.held_out_laws = {name: law.terms for name, law in laws.items()}
    model_survey = _rate_survey(surveyed, model.payload, model.terms)
    profile_survey = _rate_survey(surveyed, profile, ())
    result.rate_laws = {"model": rate_law(model_survey), "profile": rate_law(profile_survey)}
    configs = configurations()
    for done, flight in enumerate(scored):
        if progress is not None:
            progress("live re-prediction of every checkpoint (flights)", done, len(scored))
        law = laws.get(flight.name, model)
        # The other flights' λ on this flight's own fold's law (a flight the model never saw flies the
        # model's own law, whose survey is already made).
        survey = model_survey if law is model else _rate_survey(surveyed, law.payload, law.terms)
        model_prior, model_discrepancy = rate_law(survey, leave_out=flight.name)
        profile_prior, profile_discrepancy = rate_law(profile_survey, leave_out=flight.name)
        landing, descent = flight.landing, flight.descent
        live = {
            "profile": LivePredictor(flight.cube, profile, flight.ground, NO_CORRECTION,
                                     prior=profile_prior, discrepancy=profile_discrepancy),
            "model": LivePredictor(flight.cube, law.payload, flight.ground, NO_CORRECTION, effects=law.terms,
                                   prior=model_prior, discrepancy=model_discrepancy),
        }  # fmt: skip
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
                case = Case(flight.name, km, fix.alt_m - landing.alt_m, {}, {}, {}, {},
                            remaining_s=remaining_s, report=fix, truth=landing)  # fmt: skip
                for law_name, predictor in live.items():
                    checked = predictor.self_check(fix)
                    for name, value in (checked or {}).items():
                        case.evidence[f"{law_name} · {name}"] = value
                for name, (law_name, correction) in configs.items():
                    live_prediction = live[law_name].predict_from(fix, correction)
                    p = live_prediction.prediction
                    d, along, across = _errors(p.landing.lat, p.landing.lon, fix, landing)
                    case.errors_km[name] = d
                    case.landings[name] = (p.landing.lat, p.landing.lon)
                    case.along_km[name] = along
                    case.across_km[name] = across
                    case.remaining_drift_km[name] = p.drift_km
                    case.time_error_s[name] = p.descent_s - remaining_s
                    rate = live_prediction.rate
                    if rate is not None and math.isfinite(rate.log_sigma):
                        case.time_sigma_s[name] = p.descent_s * rate.log_sigma
                    if live_prediction.ascent_distance_km_h is not None:
                        case.distance_km_h[name] = live_prediction.ascent_distance_km_h
                result.cases.append(case)


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


def wind_gain_fits(result: Evaluation, name: str, leave_out: str | None = None) -> tuple[GainFit, ...]:
    """The wind gain of ``name`` (``GAINED``) at each of ``GAIN_KMS``, fitted on these flights' landings
    (without ``leave_out``): the least-squares share of the measured wind error that their landings
    wanted, shrunk toward 0 by its uncertainty (``wind_gain.fit_gain``)."""
    key = (name, leave_out or "")
    if key not in result.gain_fits:
        without, with_wind = GAINED[name]
        fits = []
        for km in GAIN_KMS:
            samples = []
            for c in _cases(result, km):
                if c.flight != leave_out and c.truth is not None:
                    truth = (c.truth.lat, c.truth.lon)
                    samples.append(gain_sample(c.landings[without], c.landings[with_wind], truth))
            fits.append(fit_gain(samples))
        result.gain_fits[key] = tuple(fits)
    return result.gain_fits[key]


def wind_gains(result: Evaluation, name: str, leave_out: str | None = None) -> WindGain:
    """``wind_gain_fits`` as the table a model file flies."""
    fits = wind_gain_fits(result, name, leave_out)
    return WindGain(GAIN_KMS, tuple(round(f.gain, 3) for f in fits))


def _add_gained(result: Evaluation) -> None:
    """Every case below ``WIND_BELOW_M`` gets the configurations of ``GAINED``, each with the gain of the
    OTHER flights (train → score: of the training flights), as ``GAINED`` says."""
    source = result.training or result
    for case in result.cases:
        if 1000.0 * case.checkpoint_km >= WIND_BELOW_M or case.report is None or case.truth is None:
            continue
        leave = case.flight if result.training is None else None
        for name, (without, with_wind) in GAINED.items():
            gain = wind_gains(source, name, leave).at(case.checkpoint_km)
            lat, lon = gained(*case.landings[without], *case.landings[with_wind], gain)
            d, along, across = _errors(lat, lon, case.report, case.truth)
            case.errors_km[name], case.along_km[name], case.across_km[name] = d, along, across
            case.landings[name] = (lat, lon)
            case.remaining_drift_km[name] = (
                float(GEOD.inv(case.report.lon, case.report.lat, lon, lat)[2]) / 1000.0
            )
            case.time_error_s[name] = case.time_error_s[without]
            if without in case.time_sigma_s:
                case.time_sigma_s[name] = case.time_sigma_s[without]
            if without in case.distance_km_h and with_wind in case.distance_km_h:
                x0, x1 = case.distance_km_h[without], case.distance_km_h[with_wind]
                case.distance_km_h[name] = x0 + gain * (x1 - x0)


def _cases(result: Evaluation, km: float) -> list[Case]:
    return [c for c in result.cases if c.checkpoint_km == km]


def held_out(result: Evaluation, km: float) -> dict[str, tuple[list[float], list[float]]]:
    """Per checkpoint, (landing errors km, remaining-time errors s) of: the textbook law restarted plain
    and with λ, the model restarted plain and with λ, what ships, and the rules measured beside it (the
    training flights' band switch, the flight's own evidence, the band choice shrunk toward the plain
    restart)."""
    cases = _cases(result, km)
    rows = {
        name: ([c.errors_km[name] for c in cases], [c.time_error_s[name] for c in cases])
        for name in (PLAIN_RESTART, TEXTBOOK_RATE, PLAIN, RATE)
    }
    rules: dict[str, Callable[[Case], str]] = {
        SHIPPED: result.shipped_name,
        WHOLE_WIND: result.whole_wind_name,
        BAND_SWITCH: result.band_switch_name,
        EVIDENCE: lambda c: evidence_choice(result, c),
        SHRUNK: lambda c: shrunk_choice(result, c),
    }
    for rule, choose in rules.items():
        names = [choose(c) for c in cases]
        rows[rule] = (
            [c.errors_km[n] for c, n in zip(cases, names, strict=True)],
            [c.time_error_s[n] for c, n in zip(cases, names, strict=True)],
        )
    return rows


EVIDENCE = "per-flight evidence"
VERTICAL_CANDIDATES = (PLAIN_RESTART, TEXTBOOK_RATE, PLAIN, RATE)
"""What the flight's own evidence chooses among, the plain restart first (kept on a tie)."""


def _log_error(case: Case, name: str) -> float:
    """Squared log ratio of the predicted to the measured remaining time."""
    predicted = max(case.remaining_s + case.time_error_s[name], 1.0)
    return math.log(predicted / max(case.remaining_s, 1.0)) ** 2


def evidence_choice(result: Evaluation, case: Case) -> str:
    """The vertical candidate this flight's own evidence picks, with the training flights as a prior.

    Score = this flight's mean squared log error of the fall it has already made (``self_check``) +
    the other (training) flights' mean squared log error of the remaining time with that candidate at
    this height. No evidence of its own yet: the plain restart from the nominal payload.
    """
    if not all(name in case.evidence for name in VERTICAL_CANDIDATES):
        return PLAIN_RESTART
    source = result.training or result
    others = [c for c in _cases(source, case.checkpoint_km) if c.flight != case.flight]
    scores = [
        case.evidence[name] + (float(np.mean([_log_error(c, name) for c in others])) if others else 0.0)
        for name in VERTICAL_CANDIDATES
    ]
    return VERTICAL_CANDIDATES[int(np.argmin(scores))]


SHRUNK = "band choice shrunk"


def shrunk_choice(result: Evaluation, case: Case) -> str:
    """The band choice shrunk toward the plain restart by its held-out interval: of the vertical
    candidates, the one whose ratio to the plain restart's mean |remaining-time error| on the other
    (training) flights has the lowest upper 95 % bound, if that bound is below 1; else the plain
    restart. Measured, not shipped: on 13–15 training flights the bound rarely falls below 1, and the
    plain restart from 15 and 10 km misses the 0.85× floor."""
    source = result.training or result
    others = [c for c in _cases(source, case.checkpoint_km) if c.flight != case.flight]
    best, bound = PLAIN_RESTART, 1.0
    for name in VERTICAL_CANDIDATES[1:]:
        high = ratio_interval(
            [c.time_error_s[name] for c in others], [c.time_error_s[PLAIN_RESTART] for c in others]
        )[2]
        if high < bound:
            best, bound = name, high
    return best


def rate_helps(result: Evaluation, km: float) -> bool:
    """The held-out rate choice cut the mean |remaining-time error|: the metric of a vertical correction,
    which the wind does not touch (the landing error it causes is reported beside it). Train → score:
    decided on the training flights alone."""
    if result.training is not None:
        return rate_helps(result.training, km)
    if km not in result.rate_choice:
        return False
    cases = _cases(result, km)
    chosen = [_combined(result.rate_choice[km][c.flight], None) for c in cases]
    held = np.mean([abs(c.time_error_s[n]) for c, n in zip(cases, chosen, strict=True)])
    return bool(held < np.mean([abs(c.time_error_s[PLAIN]) for c in cases]))


def wind_helps(result: Evaluation, km: float) -> bool:
    """The held-out wind choice cut the mean landing error below the rate choice alone (train → score:
    on the training flights)."""
    if result.training is not None:
        return wind_helps(result.training, km)
    if km not in result.wind_choice:
        return False
    cases = _cases(result, km)
    with_wind = np.mean([c.errors_km[result.band_switch_name(c)] for c in cases])
    without = np.mean([c.errors_km[_combined(result.rate_choice[km][c.flight], None)] for c in cases])
    return bool(with_wind < without)


GROWTH_EXPONENTS = np.linspace(0.0, 1.5, 61)
"""The β (σ ∝ (X / X̄)^β) a maximum-likelihood fit of the live ellipse tries."""
TIME_SIGMA_GRID = np.linspace(0.0, 0.6, 241)
"""The law's σ of ln(remaining time) it tries."""
REGIONS = (LIVE_PROBABILITIES[0], LIVE_PROBABILITIES[1])
"""The live 1σ and 2σ regions (issue #30's floors: 60–75 % and 80–95 % of held-out flights)."""


def fit_live_sigma(result: Evaluation, leave_out: str | None = None, grow: bool = True) -> LiveErrorModel:
    """The live error model of what ships at each checkpoint (optionally without one flight), by
    maximum likelihood of zero-mean normal errors: along and across the track σ = a(h)·(X / X̄(h))^β,
    X̄(h) the RMS X of these flights at that height and one β over every height (``grow``; without it,
    or when the weather does not say where it was measured, β = 0 and a(h) is the RMS error: the
    ellipse before the distance was measured); and the law's σ of
    ln(remaining time) beyond λ's own, per height. Then the ellipse's one scale, all heights pooled, so
    that its 68.3 % region holds 68.3 % of these flights; the time's σlaw(h) is the smallest that puts
    68.3 % of them within 1σ at that height (a quantile: per height, as its coverage varied 56–81 %
    with one pooled scale).

    Why one β: a checkpoint has 10–30 flights, too few to say how the error grows with X at each
    height. Why a power and not a(h)² + (κX)²: that additive form, fitted so, put a(h) at its floor and
    the whole ellipse on κX, and lost held-out coverage across seasons (docs/planning.md). Why the
    scale and the quantile: the real errors have heavier tails than a normal (most flights near the
    centre, a few far out), so a normal's own σ holds 70–80 % in its 68 % region."""
    heights, rows = [], []
    for km in CHECKPOINTS_KM:
        cases = [c for c in result.cases if c.checkpoint_km == km and c.flight != leave_out]
        if len(cases) < MIN_EVALUATED_FLIGHTS:
            continue
        names = [result.shipped_name(c) for c in cases]
        along = np.array([c.along_km[n] for c, n in zip(cases, names, strict=True)])
        across = np.array([c.across_km[n] for c, n in zip(cases, names, strict=True)])
        distance = np.array([c.distance_km_h.get(n, math.nan) for c, n in zip(cases, names, strict=True)])
        predicted = np.array(
            [max(c.remaining_s + c.time_error_s[n], 1.0) for c, n in zip(cases, names, strict=True)]
        )
        log_error = np.log(predicted / np.array([max(c.remaining_s, 1.0) for c in cases]))
        rate_sigma = np.array([c.time_sigma_s.get(n, 0.0) for c, n in zip(cases, names, strict=True)])
        heights.append(km)
        rows.append((along, across, distance, log_error, rate_sigma / predicted))
    if not rows:
        raise PredictorError(
            f"the live error model needs {MIN_EVALUATED_FLIGHTS} flights with a report at one checkpoint height "
            f"({', '.join(f'{km:g}' for km in CHECKPOINTS_KM)} km), and these flights have fewer at every one"
        )
    grow = grow and all(np.isfinite(r[2]).all() for r in rows)
    typical = [float(np.sqrt(np.mean(r[2] ** 2))) if grow else 1.0 for r in rows]
    ratios = [
        np.clip(r[2] / max(x, 1e-9), *DISTANCE_RATIO_LIMITS) if grow else np.ones_like(r[0])
        for r, x in zip(rows, typical, strict=True)
    ]

    def fit(beta: float) -> tuple[float, list[float], list[float]]:
        """(−log-likelihood, a∥(h), a⊥(h)) for this β, each a(h) in closed form."""
        total = 0.0
        parallel: list[float] = []
        perpendicular: list[float] = []
        for r, ratio in zip(rows, ratios, strict=True):
            shape = ratio ** (2.0 * beta)
            for errors, into in ((r[0], parallel), (r[1], perpendicular)):
                variance = max(float(np.mean(errors**2 / shape)), 1e-6)
                into.append(math.sqrt(variance))
                total += float(np.sum(np.log(variance * shape) + errors**2 / (variance * shape)))
        return total, parallel, perpendicular

    beta = float(min(GROWTH_EXPONENTS, key=lambda b: fit(b)[0])) if grow else 0.0
    _, parallel, perpendicular = fit(beta)

    def law_sigma(log_error: np.ndarray, rate: np.ndarray) -> float:
        """The smallest σlaw on the grid that puts 68.3 % of these errors within √(σλ² + σlaw²)."""
        inside = np.abs(log_error)[None, :] <= np.hypot(rate[None, :], TIME_SIGMA_GRID[:, None])
        enough = np.flatnonzero(inside.mean(axis=1) >= REGIONS[0])
        return float(TIME_SIGMA_GRID[enough[0] if enough.size else -1])

    law = [law_sigma(r[3], r[4]) for r in rows]
    m2 = np.concatenate([((r[0] / a) ** 2 + (r[1] / b) ** 2) / ratio ** (2.0 * beta)
                         for r, ratio, a, b in zip(rows, ratios, parallel, perpendicular, strict=True)])  # fmt: skip
    scale = math.sqrt(float(np.quantile(m2, REGIONS[0]))) / n_sigma_for(REGIONS[0])
    return LiveErrorModel(
        tuple(heights),
        tuple(round(scale * a, 3) for a in parallel),
        tuple(round(scale * b, 3) for b in perpendicular),
        round(beta, 3),
        tuple(round(x, 2) for x in typical) if grow else (),
        tuple(round(s, 4) for s in law),
    )


@dataclass(frozen=True)
class Coverage:
    """At one checkpoint, the share of held-out flights inside the live 1σ and 2σ (``REGIONS``)."""

    flights: int
    table: tuple[float, float]
    """The ellipse of σ(h) alone (the RMS error per height, what shipped before the distance, with the
    same pooled scale to the 68 % region)."""
    grown: tuple[float, float]
    """The ellipse widened with X (what ships where ``distance_helps``)."""
    time: tuple[float, float]
    """The stated σ of the remaining time (λ's own and the law's, ``LivePrediction.remaining_sigma_s``)."""
    time_rate_only: tuple[float, float]
    """λ's own σ alone (what was stated before; 0 where λ is not flown)."""
    log_score: tuple[float, float]
    """Mean −log-likelihood of the landing errors under the ellipse of σ(h) alone and the widened one
    (lower is better: the proper score, which rewards a tight ellipse where it holds and a wide one
    where it is needed)."""


def held_out_coverage(result: Evaluation) -> dict[float, Coverage]:
    """Per checkpoint: the share of flights inside the live 1σ and 2σ regions fitted WITHOUT them (in
    train → score, by the training flights), the ellipse as the 68.3 % and 95.4 % contours of its
    Gaussian, the remaining time as ±1 and ±2 of its stated σ."""
    out = {}
    fitted_on = result.training or result
    radii = [n_sigma_for(p) ** 2 for p in REGIONS]
    fits: dict[str | None, tuple[LiveErrorModel, LiveErrorModel]] = {}

    def fitted(leave: str | None) -> tuple[LiveErrorModel, LiveErrorModel]:
        if leave not in fits:
            fits[leave] = (fit_live_sigma(fitted_on, leave, grow=False), fit_live_sigma(fitted_on, leave))
        return fits[leave]

    for km in CHECKPOINTS_KM:
        cases = [c for c in result.cases if c.checkpoint_km == km]
        if len(cases) < 4:
            continue
        table: list[float] = []
        grown: list[float] = []
        time: list[float] = []
        rate_only: list[float] = []
        score: tuple[list[float], list[float]] = ([], [])
        for c in cases:
            leave = None if result.training is not None else c.flight
            name = result.shipped_name(c)
            before, model = fitted(leave)
            for errors, into, scores in ((before, table, score[0]), (model, grown, score[1])):
                s_par, s_perp = errors.at(km, c.distance_km_h.get(name)).sigmas_km(0.0, 0.0)
                into.append((c.along_km[name] / s_par) ** 2 + (c.across_km[name] / s_perp) ** 2)
                scores.append(math.log(s_par * s_perp) + 0.5 * into[-1])
            predicted = max(c.remaining_s + c.time_error_s[name], 1.0)
            error = abs(math.log(predicted / max(c.remaining_s, 1.0)))
            rate = c.time_sigma_s.get(name, 0.0) / predicted
            law = model.time_sigma_at(km) or 0.0
            time.append(error / max(math.hypot(rate, law), 1e-9))
            rate_only.append(error / rate if rate > 0.0 else math.inf)
        out[km] = Coverage(
            len(cases),
            (float(np.mean(np.array(table) <= radii[0])), float(np.mean(np.array(table) <= radii[1]))),
            (float(np.mean(np.array(grown) <= radii[0])), float(np.mean(np.array(grown) <= radii[1]))),
            (float(np.mean(np.array(time) <= 1.0)), float(np.mean(np.array(time) <= 2.0))),
            (float(np.mean(np.array(rate_only) <= 1.0)), float(np.mean(np.array(rate_only) <= 2.0))),
            (float(np.mean(score[0])), float(np.mean(score[1]))),
        )
    return out


def distance_helps(result: Evaluation) -> bool:
    """Whether the live ellipse ships widened with the distance from the ascent (β of ``fit_live_sigma``)
    or as σ(h) alone: widened only if, on the training flights (these flights, without ``--train``),
    each held out of the fit, it scored better (lower mean −log-likelihood over every checkpoint).

    Why a test and not always: across seasons the widened ellipse held fewer flights in its 68 % and
    95 % regions than σ(h) alone (docs/planning.md); the distance is measured, the gain is not sure."""
    coverage = held_out_coverage(result.training or result).values()
    return bool(coverage) and sum(c.log_score[1] for c in coverage) < sum(c.log_score[0] for c in coverage)


def shipped_error_model(result: Evaluation) -> LiveErrorModel:
    """The live error model that ships: fitted on the training flights, widened with the distance only
    where ``distance_helps``."""
    source = result.training or result
    return fit_live_sigma(source, grow=distance_helps(source))


SHIPPED_CORRECTION = LiveCorrection(
    bands=(
        Band(-math.inf, WIND_BELOW_M, True, SHIPPED_DECAY_M),
        Band(WIND_BELOW_M, PLAIN_ABOVE_M, True, None),
    )
)
"""What ships on the payload's law (``LiveSettings.law`` ``payload``): this flight's own λ below
``PLAIN_ABOVE_M`` and the decaying wind correction below ``WIND_BELOW_M``; nothing above (the plain
restart). ``live_settings`` adds the wind gain its evaluation learned."""


def band_switch_correction(result: Evaluation) -> LiveCorrection:
    """What the training flights' band switch would ship (what shipped before issue #30; reported, not
    shipped): the all-flights choice in each checkpoint's band, each part only where it helped held-out
    flights. A checkpoint's band reaches half-way to its neighbours (10 km: 7.5–12.5 km above the ground).
    """
    kms = sorted(CHECKPOINTS_KM)
    bands = []
    configs = corrections()
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
        bands.append(Band(lower, upper, use_rate, decay))
    return LiveCorrection(bands=tuple(bands))


SERIES = (
    (PLAIN_RESTART, "plain restart (textbook law)"),
    (TEXTBOOK_RATE, "textbook law + λ"),
    (PLAIN, "model, plain"),
    (RATE, "model + λ"),
    (SHIPPED, "what ships"),
    (WHOLE_WIND, "what ships, all of the wind (before)"),
    (BAND_SWITCH, "training band switch"),
    (EVIDENCE, "per-flight evidence"),
    (SHRUNK, "band choice shrunk"),
)
"""The rows of the report: label in ``held_out`` → what the report calls it."""
BASELINES = ((PLAIN_RESTART, "plain restart"), (PLAIN, "model plain"), (TEXTBOOK_RATE, "textbook + λ"))
"""What the model's figure is divided by in the ratio tables: the plain restart with the nominal payload
(``drs live --no-correction``), the model's own law restarted plain, and the textbook law with the same
λ estimator."""
FLOOR_KMS = (20.0, 10.0)
"""The heights whose mean errors the model file's live provenance records."""
FLOOR_TIME_KMS = (25.0, 20.0, 15.0, 10.0, 5.0)
TIGHT_TIME_KMS = (15.0, 10.0)
TIGHT_TIME_RATIO = 0.85
"""Issue #30's floors, held out, against the plain restart from the nominal payload: time and landing
≤ 1.0× from 25, 20, 15, 10 and 5 km above the ground, and the time ≤ 0.85× from 15 and 10 km."""


def live_settings(model: CalibratedModel, result: Evaluation, command: str) -> CalibratedModel:
    """The model with what its evaluation kept: the rule that ships (``SHIPPED_CORRECTION`` on the
    payload's law), the λ discrepancy and prior these flights measured on that law, and the live
    ellipse."""
    law = live_law(result)
    prior, discrepancy = result.rate_laws["model" if law == "model" else "profile"]
    ratios = {}
    for km in FLOOR_KMS:
        if km in result.rate_choice:
            model_s = float(np.mean(np.abs(held_out(result, km)[SHIPPED][1])))
            ratios[f"remaining_time_error_{km:g}km_s"] = round(model_s, 1)
            for name, label in BASELINES:
                base = float(np.mean(np.abs(held_out(result, km)[name][1])))
                ratios[f"{label.replace(' ', '_').replace('+', 'with')}_{km:g}km_s"] = round(base, 1)
    provenance = {
        **model.provenance,
        "live": {
            "flights": list(result.flights),
            "command": command,
            "evaluated_utc": datetime.now(UTC).strftime("%Y-%m-%dT%H:%M:%SZ"),
            **ratios,
        },
    }
    source = result.training or result
    gains = wind_gains(source, MODEL_RATE_GAIN if law == "model" else TEXTBOOK_RATE_GAIN)
    correction = dataclasses.replace(SHIPPED_CORRECTION, wind_gain=gains)
    settings = LiveSettings(correction, shipped_error_model(result), discrepancy, prior, law, "payload")
    return dataclasses.replace(model, live=settings, provenance=provenance)


BOOTSTRAP_RESAMPLES = 2000


@functools.lru_cache(maxsize=64)
def _resamples(seed: int, flights: int) -> np.ndarray:
    """The bootstrap's draws of flights, the same for every ratio of one set: an evaluation asks for
    thousands of intervals, and drawing them anew took a third of its time."""
    picks = np.random.default_rng(seed).integers(0, flights, size=(BOOTSTRAP_RESAMPLES, flights))
    picks.flags.writeable = False
    return picks


def ratio_interval(
    model: Sequence[float], baseline: Sequence[float], seed: int = 0
) -> tuple[float, float, float]:
    """Mean |model| / mean |baseline| and its 95 % interval with the flights resampled (paired: both
    errors of a flight together).

    Why: 28 flights are few, and one flight with a large miss moves a mean; the interval says how much
    of the ratio is the flights that happened to be flown.
    """
    a, b = np.abs(np.asarray(model, dtype=float)), np.abs(np.asarray(baseline, dtype=float))
    picks = _resamples(seed, a.size)
    ratios = a[picks].mean(axis=1) / np.maximum(b[picks].mean(axis=1), 1e-12)
    low, high = np.quantile(ratios, (0.025, 0.975))
    return float(a.mean() / max(b.mean(), 1e-12)), float(low), float(high)


def floors(result: Evaluation) -> list[tuple[float, str, float, float, float, bool]]:
    """(km, what, ratio, low, high, met) of issue #30's floors against the plain restart: from each of
    ``FLOOR_TIME_KMS`` the remaining-time and the landing error of *what ships* at most the
    plain restart's (point estimate), and the time at most ``TIGHT_TIME_RATIO`` of it from 15 and 10 km."""
    out = []
    for km in FLOOR_TIME_KMS:
        if km not in result.rate_choice:
            continue
        rows = held_out(result, km)
        time_limit = TIGHT_TIME_RATIO if km in TIGHT_TIME_KMS else 1.0
        for metric, label, limit in ((1, "time", time_limit), (0, "landing", 1.0)):
            ratio, low, high = ratio_interval(rows[SHIPPED][metric], rows[PLAIN_RESTART][metric])
            out.append((km, f"{label} (≤ {limit:g}×)", ratio, low, high, ratio <= limit))
    return out


def _plot(result: Evaluation, kms: list[float], png: Path) -> None:
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    fig, (left, right) = plt.subplots(1, 2, figsize=(10, 4.2))
    styles = ("o:", "s--", "o-", "s-", "^-", "^:", "v-", "x--", "d:")
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
    fig.suptitle(f"Live re-prediction on {len(result.flights)} test flights, held out")
    fig.tight_layout()
    fig.savefig(png, dpi=110)
    plt.close(fig)


def _held_out_text(result: Evaluation) -> str:
    """What is held out in the numbers above, and how far the refitted laws spread."""
    if result.training is not None:
        return (
            f"Train → score: held out whole. The scored flights played no part in anything flown here: the "
            f"model's law, its λ prior and discrepancy (the {len(result.training.flights)} training flights' "
            f"fits: {', '.join(result.training.flights)}), the live choices at each checkpoint (what those "
            "flights preferred, each held out among themselves) and what ships."
        )
    if not result.held_out_laws:
        if not result.model_terms:
            return (
                "The model has no calibrated terms: its law is the payload's drag law, which no flight set, "
                "so there is no law to hold out; its λ prior and discrepancy and its live choices are held "
                "out per flight."
            )
        return (
            "The model's law was calibrated on other flights than these, so it is held out as it stands; its "
            "λ prior and discrepancy and its live choices are held out per flight."
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
        f"across the folds {', '.join(spread) or 'the parameters do not change'}), its λ prior and "
        "discrepancy come from the other flights' fits with that law, and its live choices from the "
        "other flights' held-out predictions."
    )


def _law_text(result: Evaluation) -> str:
    """The live law and why (``live_law``), for the report."""
    ratio = law_ratio(result)
    if ratio is None:
        return "the payload's drag law (the model has no calibrated terms)"
    which = "the model's law" if live_law(result) == "model" else "the payload's drag law"
    return (
        f"{which} (model + λ ÷ textbook + λ below {PLAIN_ABOVE_M / 1000:g} km on these flights "
        f"{ratio[0]:.2f}, 95 % {ratio[1]:.2f}–{ratio[2]:.2f}; the model's law only if the whole interval is below 1)"
    )


def _bands_text(shipped: LiveCorrection) -> str:
    return "; ".join(b.describe() for b in shipped.bands) or "nothing (plain re-prediction everywhere)"


def _gain_text(result: Evaluation) -> str:
    """The wind gain that ships, with what it was fitted from, for the report."""
    source = result.training or result
    name = MODEL_RATE_GAIN if live_law(source) == "model" else TEXTBOOK_RATE_GAIN
    fits = wind_gain_fits(source, name)
    return "by report height: " + ", ".join(
        f"{km:g} km {f.gain:.2f} (least squares {f.raw:.2f} ± {f.sigma:.2f}, {f.flights} flights)"
        for km, f in zip(GAIN_KMS, fits, strict=True)
    )


def _rate_law_text(name: str, law: tuple[RatePrior | None, RateDiscrepancy]) -> str:
    prior, discrepancy = law
    text = (
        f"median λ {prior.median:.4f}, σ(ln λ) {prior.log_sigma:.4f} over {prior.flights} flights"
        if prior is not None
        else "no prior (fewer than 3 whole-descent fits)"
    )
    d = discrepancy
    rows = ", ".join(
        f"{h:g} km {math.exp(m):.3f} ± {100 * sd:.1f} % / {100 * b:+.1f} % ± {100 * s:.1f} %"
        for h, m, sd, b, s in zip(d.heights_km, d.remaining_log_mean, d.remaining_log_sigma, d.log_bias,
                                  d.log_sigma, strict=True)
    )  # fmt: skip
    return (
        f"**{name}**: whole descent {text}; by height, the remaining descent's λ (mean ± σ of ln λ) / the "
        f"record's λ against it (median ± 1.4826 MAD of the log ratio): {rows}"
    )


def share_with_interval(inside: float, flights: int) -> str:
    """A share of flights with its 95 % (Wilson) interval, in per cent (here and in
    docs/calibration/preflight_held_out.py)."""
    z, n = 1.96, flights
    centre = (inside + z * z / (2 * n)) / (1 + z * z / n)
    half = z * math.sqrt(inside * (1 - inside) / n + z * z / (4 * n * n)) / (1 + z * z / n)
    return f"{100 * inside:.0f} % ({100 * max(centre - half, 0.0):.0f}–{100 * min(centre + half, 1.0):.0f})"


def _coverage_lines(sigma: LiveErrorModel, coverage: dict[float, Coverage], widened: bool) -> list[str]:
    """The live ellipse and the remaining time's σ against issue #30's floors, every height (``widened``:
    what ships is the ellipse widened with the distance)."""

    def cell(pair: tuple[float, float], flights: int) -> str:
        marks = (
            "" if 0.60 <= pair[0] <= 0.75 else " **miss**",
            "" if 0.80 <= pair[1] <= 0.95 else " **miss**",
        )
        return " | ".join(f"{share_with_interval(v, flights)}{m}" for v, m in zip(pair, marks, strict=True))

    rows = [
        f"| {h:g} | {c.flights} | {sp:.2f} / {sc:.2f} | {x:.0f} | {cell(c.grown, c.flights)} | "
        f"{cell(c.table, c.flights)} | {c.log_score[1]:.2f} / {c.log_score[0]:.2f} | {100 * t:.1f} % | {cell(c.time, c.flights)} | {cell(c.time_rate_only, c.flights)} |"
        for h, sp, sc, x, t in zip(sigma.heights_km, sigma.sigma_parallel_km, sigma.sigma_perpendicular_km,
                                   sigma.typical_km_h or (math.nan,) * len(sigma.heights_km),
                                   sigma.time_log_sigma, strict=True)
        if (c := coverage.get(h)) is not None
    ]  # fmt: skip
    return [
        "## The live ellipse and the remaining time's σ, held out (issue #30: 1σ 60–75 %, 2σ 80–95 %)",
        "",
        "What 1σ and 2σ mean here: the regions that hold 68.3 % and 95.4 % of a normal error, the 1-D "
        "meaning carried to two dimensions: for the ellipse the contours of probability 0.6827 and 0.9545 "
        "of its Gaussian (n = 1.515 and 2.486 times σ∥, σ⊥; the n = 1 ellipse holds 39.3 %), which every "
        "live prediction carries and names (`ellipse.contours[].probability`, `ellipse_meaning`); for the "
        "remaining time ±1 and ±2 of its stated σ (`remaining_sigma_s`). The model file's "
        f"`live.error_model`: σ = a(h)·(X / X̄(h))^β with β = {sigma.growth_exponent:g}, X the distance "
        "(km) between the predicted path below the report and where the winds at its altitudes were "
        "measured (the ascent), integrated over the fall (km·h), X̄(h) its RMS on these flights; a(h) "
        "and β by maximum likelihood, then one scale so that the 68.3 % region holds 68.3 % of the "
        "(training) flights. Remaining time: σ = T · √(σλ² + σlaw(h)²), σλ the λ update's own, "
        "σlaw(h) the law's error below: the smallest that puts 68.3 % of the (training) flights within 1σ "
        "at that height. Each flight is scored against what was fitted without it (train → score: on "
        "the training flights alone). Shares with their 95 % (Wilson) interval; **miss**: outside the "
        "floor. *σ(h) alone*: the same fit with β = 0 (the ellipse before the distance); *λ's σ alone*: "
        "what was stated before (none where λ is not flown). *Score*: mean −log-likelihood of the held-out "
        "landing errors, widened / σ(h) alone (lower is better). What ships: "
        + (
            "the widened ellipse (it scored better on the training flights, each held out)."
            if widened
            else "σ(h) alone (β = 0 in the model file): the widened ellipse did not score better on the "
            "training flights, each held out (`distance_helps`)."
        ),
        "",
        "| height km | flights | a∥ / a⊥ km (widened) | X̄ km·h | widened: in 1σ | in 2σ | σ(h) alone: in 1σ "
        "| in 2σ | score | σlaw | time in 1σ | in 2σ | λ's σ alone: in 1σ | in 2σ |",
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|---|",
        *rows,
    ]


def _sigma_coverage(result: Evaluation, km: float, name: str) -> str:
    """How often the stated 1σ of the remaining time held the measured error (normal: 68 %)."""
    cases = [c for c in _cases(result, km) if name in c.time_sigma_s]
    if not cases:
        return "–"
    inside = np.mean([abs(c.time_error_s[name]) <= c.time_sigma_s[name] for c in cases])
    return f"{np.median([c.time_sigma_s[name] for c in cases]):.0f} s / {100 * inside:.0f} %"


def write_live_report(
    result: Evaluation, out_dir: str | Path, command: str, report_name: str = "live-reprediction"
) -> Path:
    """docs/planning/NAME.md and its PNG plot NAME.png (``report_name``)."""
    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    kms = [km for km in CHECKPOINTS_KM if km in result.rate_choice]
    _plot(result, kms, out / f"{report_name}.png")
    sigma = fit_live_sigma(result.training or result)
    widened = distance_helps(result.training or result)
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
        + f"; {result.fixes_used} descent fixes, every one fed to the live predictors (λ update and wind "
        f"legs); predictions only at the checkpoints. Weather: {result.weather_label}; ground: "
        f"{result.ground_label}. Checkpoint = the first report at or below that height above the ground "
        f"(skipped for a flight whose next report is below {LOWEST_SHARE:.0%} of it, a data gap).",
        "",
        f"Two laws: **textbook** = payload `{result.profile_label}` and its drag law (v ∝ ρ^-½, no terms); "
        f"**model** = {result.model_label}. Live corrections: **plain** = restarted from the report, "
        "nothing learned (`drs live --no-correction`; on the textbook law this is *the plain restart*); "
        "**λ** = this flight's own factor on the law's descent rate for the descent still to come, a "
        "Bayesian update of a log-normal prior with the descent so far: the record's time-at-altitude "
        "against the law from its top over its last 6 km of fall (Huber fit with a free time offset, each "
        "fix weighted by the height it spans and the record counting at most one independent fix per "
        "250 m of fall, so that a record of any cadence gives the same λ; its variance widened by "
        "(1+ρ)/(1−ρ) for correlated residuals) less the median departure of such a record from the "
        "remaining descent's λ at that height, with that departure's spread (1.4826 MAD) added to its "
        "variance. The prior is the law itself (λ = 1), as wide as the OTHER flights' remaining-descent λ "
        "was from it at that height (root mean square of ln λ). On each law the prior and the departure "
        "(measured on the OTHER flights) are that law's own, so *textbook + λ* is the same estimator on "
        "the textbook law. **wind L** = the measured wind error, decaying below the capsule with L in "
        f"{', '.join('∞' if math.isinf(d) else f'{d / 1000:g} km' for d in DECAYS_M)}. "
        f"**what ships**: the plain restart above {PLAIN_ABOVE_M / 1000:g} km above the ground, textbook "
        f"+ λ below it (the model + λ only where it beat textbook + λ beyond its 95 % interval on the "
        f"other, training, flights), and the wind with L = {SHIPPED_DECAY_M / 1000:g} km below "
        f"{WIND_BELOW_M / 1000:g} km, times a gain per report height learned from the other (training) "
        "flights' landings: the least-squares share of the wind correction's displacement their landing "
        "miss without it wanted, shrunk toward 0 by its uncertainty over the flights, within 0–1 (its "
        "landing is that share of the way from the landing without the wind to the one with all of it); "
        "its bands learned from no training set (issue #30). *What ships, all of the wind (before)*: the "
        "same with all of the measured error (gain 1). Measured "
        "beside it: **training band switch** (what shipped before): for each flight λ on or off on the "
        "model's law (by the mean |remaining-time error| of the OTHER, training, flights) and then the "
        "wind (by their mean landing error) that those flights preferred at that checkpoint. "
        "Time-since-release terms count from the top of the record.",
        "",
        "Landing error = distance from the predicted to the measured landing. Remaining-time error = "
        "predicted minus measured time from the report to touchdown; the measured touchdown is the last "
        "airborne fix carried to the ground at the rate of its own interval (the first fix on the ground "
        "is up to one interval late: 3 min on the SuperBIT trackers).",
        "",
    ]

    def table(title: str, cell: Callable[[list[float], list[float]], str]) -> None:
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
    lines += [
        "## What ships against the baselines, same run",
        "",
        "Ratio of the mean error of *what ships* to each baseline's, with its 95 % interval "
        f"({BOOTSTRAP_RESAMPLES} paired bootstrap draws of the flights). Below 1: what ships does better.",
        "",
        "| height km | "
        + " | ".join(f"time ÷ {label}" for _, label in BASELINES)
        + " | "
        + " | ".join(f"landing ÷ {label}" for _, label in BASELINES)
        + " |",
        "|---|" + "---|" * (2 * len(BASELINES)),
    ]
    for km in kms:
        rows = held_out(result, km)
        cells = []
        for metric in (1, 0):
            for name, _ in BASELINES:
                ratio, low, high = ratio_interval(rows[SHIPPED][metric], rows[name][metric])
                cells.append(f"{ratio:.2f} ({low:.2f}–{high:.2f})")
        lines.append(f"| {km:g} | {' | '.join(cells)} |")
    checks = floors(result)
    lines += [
        "",
        "Every series ÷ the plain restart, remaining time / landing (95 % interval), same flights; *per-flight "
        "evidence* picks, per flight and report, among the plain restart, textbook + λ, model plain and "
        "model + λ the one with the least squared log error of the fall it has already made (asked 1.5 and "
        "3 km higher up, `LivePredictor.self_check`) plus the other (training) flights' mean squared log "
        "error of the remaining time at that height; no evidence yet: the plain restart. *Band choice "
        "shrunk*: among the same four, the one whose ratio to the plain restart's remaining-time error on "
        "the other (training) flights has the lowest upper 95 % bound, if below 1; else the plain "
        "restart. The band switch, the evidence and the shrunk choice are measured, not shipped:",
        "",
        "| height km | " + " | ".join(label for n, label in SERIES if n != PLAIN_RESTART) + " |",
        "|---|" + "---|" * (len(SERIES) - 1),
    ]
    for km in kms:
        rows = held_out(result, km)
        cells = []
        for n, _ in SERIES:
            if n == PLAIN_RESTART:
                continue
            t, t_low, t_high = ratio_interval(rows[n][1], rows[PLAIN_RESTART][1])
            d, d_low, d_high = ratio_interval(rows[n][0], rows[PLAIN_RESTART][0])
            cells.append(f"{t:.2f} ({t_low:.2f}–{t_high:.2f}) / {d:.2f} ({d_low:.2f}–{d_high:.2f})")
        lines.append(f"| {km:g} | {' | '.join(cells)} |")
    lines += [
        "",
        "Floors (issue #30: what ships ÷ the plain restart, point estimate, 95 % interval): "
        + "; ".join(
            f"{km:g} km {label}: {ratio:.2f} ({low:.2f}–{high:.2f}) {'met' if met else 'NOT met'}"
            for km, label, ratio, low, high, met in checks
        )
        + ".",
        "",
        _held_out_text(result),
        "",
        "λ on each law, all flights (the model's live settings ship the textbook one): "
        + _rate_law_text("model", result.rate_laws["model"])
        + "; "
        + _rate_law_text("textbook", result.rate_laws["profile"])
        + ".",
        "",
        "The 1σ of the remaining time that the λ update states (its posterior σ of ln λ times the "
        "remaining time; it leaves out the wind and the law's error below) against the measured error: "
        "median σ / share of flights within it (a normal error: 68 %):",
        "",
        "| height km | model + λ | textbook + λ |",
        "|---|---|---|",
        *[f"| {km:g} | {_sigma_coverage(result, km, RATE)} | {_sigma_coverage(result, km, TEXTBOOK_RATE)} |"
          for km in kms],
        "",
        f"![landing and remaining-time error against height]({report_name}.png)",
        "",
        "## The training band switch (what shipped before; measured, not shipped)",
        "",
        "It put a correction in a checkpoint's band only where its held-out choice beat the model's plain "
        "re-prediction on its own metric: λ on the mean |remaining-time error|, the wind on the "
        "mean landing error (beyond the λ choice).",
        "",
        "| height km | λ: held-out / plain mean |Δt| s | ships | wind: held-out / λ-only mean km | ships "
        "| choice on all flights |",
        "|---|---|---|---|---|---|",
    ]  # fmt: skip
    for km in kms:
        cases = _cases(result, km)
        rate_names = [_combined(result.rate_choice[km][c.flight], None) for c in cases]
        rate_held = np.mean([abs(c.time_error_s[n]) for c, n in zip(cases, rate_names, strict=True)])
        plain = np.mean([abs(c.time_error_s[PLAIN]) for c in cases])
        wind_held = np.mean([c.errors_km[result.band_switch_name(c)] for c in cases])
        rate_only = np.mean([c.errors_km[n] for c, n in zip(cases, rate_names, strict=True)])
        rate, wind = result.all_flights_choice[km]
        lines.append(
            f"| {km:g} | {rate_held:.0f} / {plain:.0f} | {'yes' if rate_helps(result, km) else 'no'} | "
            f"{wind_held:.2f} / {rate_only:.2f} | {'yes' if wind_helps(result, km) else 'no'} | "
            f"{rate or 'no λ'}, {wind or 'no wind'} |"
        )
    shown = ("plain", OWN, "wind 2 km", "wind 8 km", "wind const", f"{OWN} + wind 2 km")
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
        *_coverage_lines(sigma, coverage, widened),
        "",
        f"What ships (the model file's `live.law` `{live_law(result.training or result)}`, `live.restart` "
        "`payload` and `live.bands`, bands of height above the ground): "
        f"{_law_text(result.training or result)}, {_bands_text(SHIPPED_CORRECTION)}; elsewhere the plain "
        f"restart from the nominal payload. The wind's gain (`live.wind_gain`), {_gain_text(result)}. "
        "The band switch would have shipped, on the model's law: "
        f"{_bands_text(band_switch_correction(result))}.",
        "",
        "The band switch's choices per flight (held-out):",
        "",
    ]
    for km in kms:
        counts: dict[str, int] = {}
        for flight in result.rate_choice[km]:
            name = _combined(result.rate_choice[km][flight], result.wind_choice[km][flight])
            counts[name] = counts.get(name, 0) + 1
        lines.append(f"* {km:g} km: " + ", ".join(f"{n} ×{c}" for n, c in sorted(counts.items())))
    md = out / f"{report_name}.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return md

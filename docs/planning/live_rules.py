"""The rules tried for issue #30 (item 2), what live re-prediction flies at each report, side by side on
every held-out split: the table in docs/planning.md.

Run from the repository root: ``.venv/bin/python docs/planning/live_rules.py`` (about two minutes).

Why a script and not ``drs live evaluate``: each evaluation reports what ships and three alternatives
(the training band switch, per-flight evidence, the shrunk band choice); this one runs the six splits of
the committed reports (SuperBIT leave-one-out, 2018 → 2019, 2019 → 2018, SuperBIT → EOSS, EOSS →
SuperBIT, EOSS leave-one-out) in one process and scores every rule on the same held-out cases: at the
first report at or below 25, 20, 15, 10 and 5 km above the ground, the mean |remaining-time error| and
the mean landing error of the rule ÷ the plain restart's (textbook law, nominal payload, nothing
learned). A trailing * marks a ratio that misses issue #30's floor (≤ 1.0, the time ≤ 0.85 from 15
and 10 km).

Rules (each flight's choice made without it: by the OTHER flights in leave-one-out, by the training
flights alone in train → score):

* *band switch*: per checkpoint, λ on or off on the model's law and then the wind L, whichever the
  other flights' held-out errors preferred (what shipped before);
* *textbook + λ* / *model + λ*: the flight's own λ update at every height on that law, no wind;
* *evidence*: per flight and report, among the plain restart, textbook + λ, model plain and model + λ,
  the least squared log error of the fall already made (``LivePredictor.self_check``) plus the other
  flights' mean squared log error of the remaining time at that height; *evidence, 2*: the same among
  the plain restart and textbook + λ only; *evidence, no prior*: without the other flights' term;
* *shrunk*: among the same four, the lowest upper 95 % bound of the ratio to the plain restart's
  remaining-time error on the other flights, if below 1, else the plain restart; *shrunk + wind*: then
  the wind L with the lowest upper bound of the landing ratio, if below 1;
* *λ once the fit has 3 fixes*: textbook + λ where the record's window holds at least 3 fixes (the top
  and one interval below the burst are not evidence), else the plain restart;
* *restart above 22.5 km*: the plain restart at the 25 km checkpoint, textbook + λ below; *+ wind L
  below 12.5 km*: and the wind with L below 12.5 km (on the model's law + λ, the proxy the evaluation
  has for every L); *what shipped before (all of the wind)*: the same with L = 4 km on the live law
  (`live_law`: the textbook law on every split here); *what ships*: that wind times the gain the other
  (training) flights' landings learned at the checkpoint (`live_evaluation.wind_gains`, issue #30 item
  4); *before, wind only far from the ascent*: what shipped before, the wind only where the predicted
  path is farther from the ascent than the training flights' typical X at that height; *+ wind 4 km
  above 12.5 km when far*: what shipped before, and the wind from 22.5 km down where the path is that
  far;
* the wind gain's alternatives (``Gained``: the landing that share of the way from the landing without
  the wind to the one with all of it): *the least-squares slope (not shrunk)* held within 0–1, *its lower
  95 % bound*, *one gain pooled over 10, 5 and 2 km*, *also from 20 and 15 km* (where what ships flies
  no wind); *learned L*: the L (or none) with the least mean landing error of the other (training)
  flights at the checkpoint, on the model's law + λ; *learned L × its gain*: each L times its own gain;
* *before, wind only where its look-back helped* (never built in the product): what shipped before, but at a
  report where it flies the wind, this flight's own check decides it. From the last report at least D
  higher, the position at this report's altitude is predicted with λ as ships, with and without the
  wind error measured there (L = 4 km), and compared with where the capsule was: the wind is flown
  unless it made that position worse (no report D higher: what ships). D (1–4 km) is the one whose rule
  gave the least total landing error on the OTHER (training) flights' reports where what ships flies
  the wind (from 10, 5 and 2 km); *+ training prior*: the wind is flown where ln(with / without) of the
  check plus ln(the training flights' mean landing with the wind ÷ without it at that height) is ≤ 0.

``--hard-worlds`` (about two minutes; it also prints each world's own ``drs live evaluate`` report)
measures, in the five hard independent worlds of ``tests/predictor/calibration/test_live_hard_worlds.py``,
through the product's live predictor (``CalibratedModel.live_predictor``): what ships (the model file's
wind gain), what shipped before (the same file with all of the wind) and no wind; the look-back check
(D and the prior from the eight calibration flights); and the gain's shrunk, least-squares and lower-bound
forms fitted on the calibration flights replayed here, their landings interpolated (``wind_gain.gained``;
the product fits its own on ``drs live evaluate``'s cases). Scored on the ten unseen flights, landing ÷
the plain restart's with its 95 % interval.
"""

from __future__ import annotations

import math
import sys
import tempfile
from collections.abc import Callable, Hashable, Sequence
from dataclasses import replace
from pathlib import Path
from typing import NamedTuple, TypeVar

import numpy as np

from predictor.calibration.live_evaluation import (
    GAINED,
    MODEL_RATE_WIND,
    PLAIN,
    PLAIN_RESTART,
    RATE,
    SHIPPED_DECAY_M,
    TEXTBOOK_RATE,
    TEXTBOOK_RATE_WIND,
    VERTICAL_CANDIDATES,
    WIND_BELOW_M,
    Case,
    Evaluation,
    LevelGround,
    _cases,
    _errors,
    _log_error,
    _rate_survey,
    _usable,
    evaluate_live,
    fit_live_sigma,
    rate_law,
    ratio_interval,
    wind_gains,
)
from predictor.calibration.wind_gain import GainFit, GainSample, fit_gain, gain_sample, gained
from predictor.descent import PROFILES, Payload
from predictor.environment.weather import load_weather
from predictor.prediction import GEOD
from predictor.prediction.live import NO_CORRECTION, OWN_RATE, LiveCorrection, LivePredictor, by_height
from predictor.prediction.model_file import CalibratedModel, load_model
from predictor.tracks import Fix, clean, read_track

SUPERBIT = sorted(Path("../shared/data/tracks/pyballoon_superbit").glob("*-*.csv"))
EOSS = sorted(Path("tests/data/eoss").glob("*_descent.csv"))
KMS = (25.0, 20.0, 15.0, 10.0, 5.0)


class Gained(NamedTuple):
    """A wind correction flown times a gain: the landing ``gain`` of the way from ``without``'s to
    ``with_wind``'s (``wind_gain.gained``); the remaining time is ``without``'s (the wind does not move it)."""

    without: str
    with_wind: str
    gain: float


Choice = str | Gained
Rule = Callable[[Evaluation, Case], Choice]


def scored(case: Case, choice: Choice) -> tuple[float, float]:
    """(landing error km, remaining-time error s) of ``choice`` at ``case``."""
    if isinstance(choice, str):
        return case.errors_km[choice], case.time_error_s[choice]
    assert case.report is not None and case.truth is not None
    lat, lon = gained(*case.landings[choice.without], *case.landings[choice.with_wind], choice.gain)
    return _errors(lat, lon, case.report, case.truth)[0], case.time_error_s[choice.without]


def flown_gain(result: Evaluation, case: Case, choice: Choice) -> float | None:
    """The wind gain ``choice`` flies at ``case`` (None: no gained wind)."""
    if isinstance(choice, Gained):
        return choice.gain
    if choice not in GAINED:
        return None
    leave = case.flight if result.training is None else None
    return wind_gains(result.training or result, choice, leave).at(case.checkpoint_km)


def gain_samples(cases: Sequence[Case], without: str, with_wind: str) -> list[GainSample]:
    out = []
    for c in cases:
        assert c.truth is not None
        out.append(gain_sample(c.landings[without], c.landings[with_wind], (c.truth.lat, c.truth.lon)))
    return out


GAIN_FITS: dict[tuple[int, str, float, str, str], GainFit] = {}


def gain_at(result: Evaluation, case: Case, km: float, without: str, with_wind: str) -> GainFit:
    """The gain fitted on the other (training) flights' cases at checkpoint ``km``."""
    key = (id(result), case.flight if result.training is None else "", km, without, with_wind)
    if key not in GAIN_FITS:
        source = result.training or result
        pool = [c for c in _cases(source, km) if c.flight != case.flight]
        GAIN_FITS[key] = fit_gain(gain_samples(pool, without, with_wind))
    return GAIN_FITS[key]


def with_gain(result: Evaluation, case: Case, how: str = "shrunk", above: bool = False) -> Choice:
    """What ships, with its wind flown times the gain the other (training) flights' landings give at this
    checkpoint (``how``: ``shrunk`` as ``fit_gain``, ``raw`` the least-squares slope held within 0–1,
    ``bound`` its lower 95 % bound held within 0–1, ``pooled`` one shrunk gain over 10, 5 and 2 km);
    ``above``: also from 20 and 15 km, where what ships flies no wind."""
    shipped = result.whole_wind_name(case)
    if shipped in NO_WIND:
        without, with_wind = NO_WIND[shipped], shipped
    elif above and shipped in (TEXTBOOK_RATE, RATE):
        without, with_wind = shipped, {TEXTBOOK_RATE: TEXTBOOK_RATE_WIND, RATE: MODEL_RATE_WIND}[shipped]
    else:
        return shipped
    if how == "pooled":
        source = result.training or result
        pool = [c for km in (10.0, 5.0, 2.0) for c in _cases(source, km) if c.flight != case.flight]
        fit = fit_gain(gain_samples(pool, without, with_wind))
    else:
        fit = gain_at(result, case, case.checkpoint_km, without, with_wind)
    gain = {
        "shrunk": fit.gain,
        "pooled": fit.gain,
        "raw": min(max(fit.raw, 0.0), 1.0),
        "bound": min(max(fit.raw - 1.96 * fit.sigma, 0.0), 1.0) if math.isfinite(fit.sigma) else 0.0,
    }[how]
    return Gained(without, with_wind, gain)


def others(result: Evaluation, case: Case) -> list[Case]:
    source = result.training or result
    return [c for c in _cases(source, case.checkpoint_km) if c.flight != case.flight]


def upper(cases: list[Case], name: str, base: str, time: bool) -> float:
    def error(c: Case, n: str) -> float:
        return c.time_error_s[n] if time else c.errors_km[n]

    return ratio_interval([error(c, name) for c in cases], [error(c, base) for c in cases])[2]


def shrunk(result: Evaluation, case: Case, wind: bool = False) -> str:
    pool = others(result, case)
    best, bound = PLAIN_RESTART, 1.0
    for name in VERTICAL_CANDIDATES[1:]:
        if (high := upper(pool, name, PLAIN_RESTART, True)) < bound:
            best, bound = name, high
    if not wind or best not in (PLAIN, RATE):
        return best
    vertical, bound = best, 1.0
    for decay in ("1 km", "2 km", "4 km", "8 km", "16 km", "const"):
        name = f"model · {'λ + ' if vertical == RATE else ''}wind {decay}"
        if (high := upper(pool, name, vertical, False)) < bound:
            best, bound = name, high
    return best


def evidence(result: Evaluation, case: Case, candidates: tuple[str, ...], prior: bool = True) -> str:
    if not all(name in case.evidence for name in candidates):
        return PLAIN_RESTART
    pool = others(result, case) if prior else []
    scores = [
        case.evidence[n] + (float(np.mean([_log_error(c, n) for c in pool])) if pool else 0.0)
        for n in candidates
    ]
    return candidates[int(np.argmin(scores))]


def window_fixes() -> dict[tuple[str, float], int]:
    """(flight, checkpoint) → the fixes the record's 6 km window holds at that report."""
    counts = {}
    for flight in _usable(SUPERBIT + EOSS, None, [], None, None, None):
        top = max(range(len(flight.descent)), key=lambda i: flight.descent[i].alt_m)
        for km, at in flight.checkpoints.items():
            if at is not None:
                heights = [f.alt_m for f in flight.descent[top : flight.descent.index(at) + 1]]
                counts[(flight.name, km)] = max(
                    sum(h <= at.alt_m + 6000.0 for h in heights), min(2, len(heights))
                )
    return counts


def far(result: Evaluation, case: Case) -> bool:
    """The descent still to come is farther from its ascent than the training flights' typical X at this
    height (issue #30 item 4: the wind error carried down more on the legs far from the ascent,
    docs/planning/wind-errors.md)."""
    typical = fit_live_sigma(result.training or result, case.flight if result.training is None else None)
    x = case.distance_km_h.get(TEXTBOOK_RATE)
    return (
        x is not None
        and bool(typical.typical_km_h)
        and x > by_height(case.checkpoint_km, typical.heights_km, typical.typical_km_h)
    )


LOOKBACKS_M = (1000.0, 2000.0, 3000.0, 4000.0)
"""The look-back lengths D the wind check may use (chosen per split on the training flights)."""
WITH_WIND = LiveCorrection.everywhere(True, SHIPPED_DECAY_M)
NO_WIND = {TEXTBOOK_RATE_WIND: TEXTBOOK_RATE, MODEL_RATE_WIND: RATE}
Check = dict[float, tuple[float, float]]
"""Look-back D (m) → the distance (km) from where the capsule was at a report to the position at its
altitude predicted from D higher, with the measured wind and without it."""
Checks = dict[tuple[str, float], Check]
K = TypeVar("K", bound=Hashable)
Row = tuple[Hashable, Hashable, float, float, Check | None]
"""A training report where what ships flies the wind: flight, height, landing km with the wind, without
it, and its wind check."""


def position_at(
    live: LivePredictor, start: Fix, correction: LiveCorrection, alt_m: float
) -> tuple[float, float]:
    """(lat, lon) where the prediction from ``start`` crosses ``alt_m``."""
    track = live.predict_from(start, correction).prediction.track
    z = track.alt_m[::-1]
    return float(np.interp(alt_m, z, track.lat[::-1])), float(np.interp(alt_m, z, track.lon[::-1]))


def replay_checks(live: LivePredictor, descent: Sequence[Fix], reports: dict[K, Fix]) -> dict[K, Check]:
    """Feed ``descent`` to ``live`` and, for each report and look-back D, check the wind on the last D of
    fall: from the last fix at least D above the report, with the record as it then was, λ as ships
    and the wind error then measured (L = 4 km) or none."""
    index = {id(fix): i for i, fix in enumerate(descent)}
    starts: dict[int, list[tuple[K, float]]] = {}
    for key, at in reports.items():
        for drop in LOOKBACKS_M:
            higher = [j for j in range(index[id(at)]) if descent[j].alt_m >= at.alt_m + drop]
            if higher:
                starts.setdefault(higher[-1], []).append((key, drop))
    out: dict[K, Check] = {key: {} for key in reports}
    for j, fix in enumerate(descent[:-1]):
        live.observe(fix)
        for key, drop in starts.get(j, []):
            at = reports[key]
            errors = []
            for correction in (WITH_WIND, OWN_RATE):
                lat, lon = position_at(live, fix, correction, at.alt_m)
                errors.append(float(GEOD.inv(lon, lat, at.lon, at.lat)[2]) / 1000.0)
            out[key][drop] = (errors[0], errors[1])
    return out


def split_checks(scored: Sequence[Path], train: Sequence[Path] | None = None) -> Checks:
    """The wind checks of every scored flight below ``WIND_BELOW_M``, on the textbook law with the λ
    prior and discrepancy ``evaluate_live`` gives it (the other flights', or the training flights')."""
    profile = PROFILES["superbit-test"]
    flights = _usable(scored, None, [], None, None, None)
    surveyed = flights if train is None else _usable(train, None, [], None, None, None)
    survey = _rate_survey(surveyed, profile, ())
    out: Checks = {}
    for flight in flights:
        prior, discrepancy = rate_law(survey, leave_out=flight.name)
        live = LivePredictor(
            flight.cube, profile, flight.ground, NO_CORRECTION, prior=prior, discrepancy=discrepancy
        )
        reports = {
            km: at for km, at in flight.checkpoints.items() if at is not None and 1000.0 * km < WIND_BELOW_M
        }
        for km, check in replay_checks(live, flight.descent, reports).items():
            out[(flight.name, km)] = check
    return out


def flies_wind(check: Check | None, drop: float, prior: float) -> bool:
    """The check's verdict: ln(with / without) of the look-back plus ``prior`` at most 0 (no look-back
    that long yet: the prior alone)."""
    own = 0.0
    if check and drop in check:
        with_km, without_km = check[drop]
        own = math.log(max(with_km, 1e-6) / max(without_km, 1e-6))
    return own + prior <= 0.0


def log_gain(pairs: Sequence[tuple[float, float]]) -> float:
    """ln(mean landing with the wind ÷ mean without) over (with, without) pairs; 0 for none."""
    if not pairs:
        return 0.0
    with_km, without_km = np.mean(pairs, axis=0)
    return math.log(max(float(with_km), 1e-6) / max(float(without_km), 1e-6))


def choose_lookback(rows: Sequence[Row], prior: bool) -> float:
    """The look-back whose rule gives the least total landing error on the training ``rows``, each row's
    prior from the other flights' rows."""

    def total(drop: float) -> float:
        out = 0.0
        for flight, height, with_km, without_km, check in rows:
            p = log_gain([(r[2], r[3]) for r in rows if r[1] == height and r[0] != flight]) if prior else 0.0
            out += with_km if flies_wind(check, drop, p) else without_km
        return out

    return min(LOOKBACKS_M, key=total)


class WindCheck:
    """The rule *what ships, wind only where its look-back helped*, on the evaluations of ``main``."""

    def __init__(self, checks: dict[int, tuple[Checks, Checks]], prior: bool) -> None:
        self.checks = checks
        self.prior = prior
        self.lookbacks: dict[tuple[int, str], float] = {}

    def rows(self, source: Evaluation, checks: Checks, leave_out: str) -> list[Row]:
        """The training evaluation's reports where what ships flies the wind, without ``leave_out``."""
        out: list[Row] = []
        for c in source.cases:
            name = source.whole_wind_name(c)
            if c.flight != leave_out and name in NO_WIND:
                out.append(
                    (
                        c.flight,
                        c.checkpoint_km,
                        c.errors_km[name],
                        c.errors_km[NO_WIND[name]],
                        checks.get((c.flight, c.checkpoint_km)),
                    )
                )
        return out

    def __call__(self, result: Evaluation, case: Case) -> str:
        shipped = result.whole_wind_name(case)
        if shipped not in NO_WIND:
            return shipped
        scored, training = self.checks[id(result)]
        source = result.training or result
        rows = self.rows(source, training, case.flight)
        key = (id(result), case.flight)
        if key not in self.lookbacks:
            self.lookbacks[key] = choose_lookback(rows, self.prior)
        prior = log_gain([(r[2], r[3]) for r in rows if r[1] == case.checkpoint_km]) if self.prior else 0.0
        check = scored.get((case.flight, case.checkpoint_km))
        return shipped if flies_wind(check, self.lookbacks[key], prior) else NO_WIND[shipped]


DECAY_LABELS = ("1 km", "2 km", "4 km", "8 km", "16 km", "const")


def learned_decay(result: Evaluation, case: Case, gain: bool) -> Choice:
    """Where what shipped before flies the wind: on the model's law + λ (the proxy the evaluation has for
    every L), the L (or none) whose mean landing error on the other (training) flights at this checkpoint
    was least; ``gain``: each L times its shrunk gain on those flights, the L with the least mean landing
    error so flown."""
    if result.whole_wind_name(case) not in NO_WIND:
        return result.whole_wind_name(case)
    pool = others(result, case)
    options: list[Choice] = [RATE]
    for label in DECAY_LABELS:
        name = f"model · λ + wind {label}"
        options.append(
            Gained(RATE, name, gain_at(result, case, case.checkpoint_km, RATE, name).gain) if gain else name
        )
    return min(options, key=lambda o: float(np.mean([scored(c, o)[0] for c in pool])))


def below(km: float, upper_km: float, name: str, otherwise: str) -> str:
    return name if km <= upper_km else otherwise


def rules(fixes: dict[tuple[str, float], int], checks: dict[int, tuple[Checks, Checks]]) -> dict[str, Rule]:
    def restart_above(name: str) -> Rule:
        return lambda r, c: PLAIN_RESTART if c.checkpoint_km >= 22.5 else name

    table: dict[str, Rule] = {
        "band switch (before)": lambda r, c: r.band_switch_name(c),
        "textbook + λ": lambda r, c: TEXTBOOK_RATE,
        "model + λ": lambda r, c: RATE,
        "evidence": lambda r, c: evidence(r, c, VERTICAL_CANDIDATES),
        "evidence, 2": lambda r, c: evidence(r, c, (PLAIN_RESTART, TEXTBOOK_RATE)),
        "evidence, no prior": lambda r, c: evidence(r, c, VERTICAL_CANDIDATES, prior=False),
        "shrunk": lambda r, c: shrunk(r, c),
        "shrunk + wind": lambda r, c: shrunk(r, c, wind=True),
        "λ once the fit has 3 fixes": lambda r, c: (
            TEXTBOOK_RATE if fixes[(c.flight, c.checkpoint_km)] >= 3 else PLAIN_RESTART
        ),
        "restart above 22.5 km": restart_above(TEXTBOOK_RATE),
        "restart above 22.5 km, model + λ": restart_above(RATE),
    }
    for decay in ("2 km", "4 km", "8 km", "16 km"):
        table[f"restart above 22.5 km, + wind {decay} below 12.5 km (model + λ)"] = (
            lambda d: (
                lambda r, c: (
                    PLAIN_RESTART
                    if c.checkpoint_km >= 22.5
                    else below(c.checkpoint_km, 12.5, f"model · λ + wind {d}", TEXTBOOK_RATE)
                )
            )
        )(decay)
    table["textbook + λ + wind 4 km everywhere"] = lambda r, c: TEXTBOOK_RATE_WIND
    table["what ships (wind × the gain its training flights learned)"] = lambda r, c: r.shipped_name(c)
    table["what shipped before (all of the wind)"] = lambda r, c: r.whole_wind_name(c)
    table["before, wind only far from the ascent"] = lambda r, c: (
        TEXTBOOK_RATE
        if r.whole_wind_name(c) == TEXTBOOK_RATE_WIND and not far(r, c)
        else r.whole_wind_name(c)
    )
    table["before, + wind 4 km above 12.5 km when far"] = lambda r, c: (
        TEXTBOOK_RATE_WIND if r.whole_wind_name(c) == TEXTBOOK_RATE and far(r, c) else r.whole_wind_name(c)
    )
    table["wind × gain, the least-squares slope (not shrunk)"] = lambda r, c: with_gain(r, c, "raw")
    table["wind × gain, its lower 95 % bound"] = lambda r, c: with_gain(r, c, "bound")
    table["wind × one gain pooled over 10, 5 and 2 km"] = lambda r, c: with_gain(r, c, "pooled")
    table["wind × gain, also from 20 and 15 km"] = lambda r, c: with_gain(r, c, above=True)
    table["learned L (model + λ)"] = lambda r, c: learned_decay(r, c, False)
    table["learned L × its gain (model + λ)"] = lambda r, c: learned_decay(r, c, True)
    table["before, wind only where its look-back helped"] = WindCheck(checks, prior=False)
    table["before, wind only where its look-back helped, + training prior"] = WindCheck(checks, prior=True)
    return table


def main() -> None:
    superbit = {year: [p for p in SUPERBIT if p.name.startswith(year)] for year in ("18-", "19-")}

    def model(name: str) -> CalibratedModel:
        return load_model(f"docs/planning/{name}")

    splits = {
        "leave-one-out": evaluate_live(SUPERBIT, model("superbit-2018-2019-model.json")),
        "2018 → 2019": evaluate_live(
            superbit["19-"], model("superbit-2018-model.json"), train=superbit["18-"]
        ),
        "2019 → 2018": evaluate_live(
            superbit["18-"], model("superbit-2019-model.json"), train=superbit["19-"]
        ),
        "SuperBIT → EOSS": evaluate_live(EOSS, model("superbit-2018-2019-model.json"), train=SUPERBIT),
        "EOSS → SuperBIT": evaluate_live(SUPERBIT, train=EOSS),
        "EOSS leave-one-out": evaluate_live(EOSS),
    }
    own = {"SuperBIT": split_checks(SUPERBIT), "EOSS": split_checks(EOSS)}
    own.update({year: split_checks(paths) for year, paths in superbit.items()})
    checks = {
        id(splits["leave-one-out"]): (own["SuperBIT"], own["SuperBIT"]),
        id(splits["2018 → 2019"]): (split_checks(superbit["19-"], superbit["18-"]), own["18-"]),
        id(splits["2019 → 2018"]): (split_checks(superbit["18-"], superbit["19-"]), own["19-"]),
        id(splits["SuperBIT → EOSS"]): (split_checks(EOSS, SUPERBIT), own["SuperBIT"]),
        id(splits["EOSS → SuperBIT"]): (split_checks(SUPERBIT, EOSS), own["EOSS"]),
        id(splits["EOSS leave-one-out"]): (own["EOSS"], own["EOSS"]),
    }
    for name, rule in rules(window_fixes(), checks).items():
        print(f"### {name}")
        misses = 0
        for split, result in splits.items():
            cells, intervals = [], []
            for km in KMS:
                cases = _cases(result, km)
                errors = [scored(c, rule(result, c)) for c in cases]
                time = ratio_interval([e[1] for e in errors], [c.time_error_s[PLAIN_RESTART] for c in cases])
                landing = ratio_interval([e[0] for e in errors], [c.errors_km[PLAIN_RESTART] for c in cases])
                limit = 0.85 if km in (15.0, 10.0) else 1.0
                marks = (
                    "*" if round(time[0], 2) > limit else " ",
                    "*" if round(landing[0], 2) > 1.0 else " ",
                )
                misses += sum(m == "*" for m in marks)
                cells.append(f"{time[0]:.2f}{marks[0]}/{landing[0]:.2f}{marks[1]}")
                intervals.append(f"{time[1]:.2f}–{time[2]:.2f}/{landing[1]:.2f}–{landing[2]:.2f}")
            print(f"{split:20s} {' '.join(cells)}")
            if isinstance(rule, WindCheck) or name.startswith("what ship"):
                print(f"{'  95 %':20s} {' '.join(intervals)}")
            if "gain" in name:
                flown_gains = []
                for km in (20.0, 15.0, 10.0, 5.0, 2.0):
                    gains = [flown_gain(result, c, rule(result, c)) for c in _cases(result, km)]
                    gains = [g for g in gains if g is not None]
                    if gains:
                        flown_gains.append(
                            f"{km:g} km {np.mean(gains):.2f} ({min(gains):.2f}–{max(gains):.2f})"
                        )
                print(f"{'  gain flown':20s} {', '.join(flown_gains)}")
            if isinstance(rule, WindCheck):
                flown = [
                    f"{sum(rule(result, c) in NO_WIND for c in _cases(result, km))}/{len(_cases(result, km))}"
                    for km in (10.0, 5.0)
                ]
                print(f"{'  wind flown':20s} from 10 km {flown[0]}, from 5 km {flown[1]}")
        if isinstance(rule, WindCheck):
            print(f"look-backs chosen (km): {sorted(d / 1000.0 for d in rule.lookbacks.values())}")
        print(f"floors missed: {misses}")


class WorldRow(NamedTuple):
    """One report of one hard-world flight: landing errors (km) and |remaining-time errors| (s)."""

    flight: str
    shipped_km: float
    """What ships: the model file's live settings, its wind times the gain they carry."""
    whole_km: float
    """What shipped before: the same with all of the wind (no gain)."""
    no_wind_km: float
    """What ships with its wind band switched off."""
    restart_km: float
    shipped_s: float
    restart_s: float
    wind: bool
    """What ships flies the wind at this report."""
    gain: float | None
    """The gain it flies there."""
    check: Check | None
    landings: tuple[tuple[float, float], tuple[float, float], tuple[float, float]]
    """(lat, lon) of the landing without the wind, with all of it and measured."""


def world_rows(
    model: CalibratedModel, world: object, cube: object, checkpoints: Sequence[tuple[str, float]]
) -> dict[str, list[WorldRow]]:
    """Per checkpoint, every flight of a hard world (``tests.independent_world.World``) replayed as the
    hard-worlds test does, with the wind checks where what ships flies the wind."""
    from tests.independent_world import CDA_M2, GROUND_M, MASS_KG

    ground = LevelGround(GROUND_M)
    nominal = CalibratedModel(Payload(MASS_KG, CDA_M2, name="nominal"), (), None)
    out: dict[str, list[WorldRow]] = {name: [] for name, _ in checkpoints}
    for truth in world.flights:  # type: ignore[attr-defined]
        flight = clean(read_track(truth.path))
        assert flight.landing is not None
        descent = list(flight.descent)
        reports = {}
        for name, alt_m in checkpoints:
            reports[name] = next(f for f in descent[:-1] if f.alt_m <= alt_m)
        live = model.live_predictor(cube, ground)  # type: ignore[arg-type]
        wind_at = {
            name: (band := live.correction.band_at(at.alt_m - GROUND_M)) is not None
            and band.decay_m is not None
            for name, at in reports.items()
        }
        no_wind = replace(
            live.correction, bands=tuple(replace(b, decay_m=None) for b in live.correction.bands)
        )
        whole = replace(live.correction, wind_gain=None)
        live.correction = whole  # the wind check was built on all of the wind
        checks = replay_checks(live, descent, {n: at for n, at in reports.items() if wind_at[n]})
        # ``live`` has seen the whole descent: fresh predictors, fed up to each report, predict from it.
        fresh = model.live_predictor(cube, ground)  # type: ignore[arg-type]
        plain = nominal.live_predictor(cube, ground, corrected=False)  # type: ignore[arg-type]
        pending = sorted(reports.items(), key=lambda kv: kv[1].time)
        for fix in descent[:-1]:
            fresh.observe(fix)
            plain.observe(fix)
            while pending and pending[0][1] is fix:
                name, at = pending.pop(0)
                remaining = (flight.landing.time - at.time).total_seconds()
                row = []
                where = []
                gain = fresh.predict_from(at).wind_gain
                for predictor, correction in ((fresh, None), (fresh, whole), (fresh, no_wind), (plain, None)):
                    p = predictor.predict_from(at, correction).prediction
                    where.append((p.landing.lat, p.landing.lon))
                    km = (
                        float(GEOD.inv(p.landing.lon, p.landing.lat, truth.landing_lon, truth.landing_lat)[2])
                        / 1000.0
                    )
                    row.append((km, abs(p.descent_s - remaining)))
                (shipped_km, shipped_s), (whole_km, _), (no_wind_km, _), (restart_km, restart_s) = row
                out[name].append(
                    WorldRow(truth.name, shipped_km, whole_km, no_wind_km, restart_km, shipped_s, restart_s,
                             wind_at[name], gain, checks.get(name),
                             (where[2], where[1], (truth.landing_lat, truth.landing_lon)))
                )  # fmt: skip
            if not pending:
                break
    return out


def hard_worlds() -> None:
    """The wind check against what ships in the five hard worlds (D and prior from the calibration
    flights, scored on the unseen ones)."""
    sys.path.insert(0, str(Path.cwd()))
    from tests.independent_world import HARD, make_world, write_weather
    from tests.predictor.calibration.test_live_hard_worlds import (
        CHECKPOINTS,
        HARD_WORLDS,
        UNSEEN_CADENCE_S,
        UNSEEN_FLIGHTS,
        UNSEEN_SEED,
        calibrated,
    )

    with tempfile.TemporaryDirectory() as tmp:
        weather = write_weather(Path(tmp) / "gfs")
        for world, effects in HARD_WORLDS.items():
            directory = Path(tmp) / world.replace(" ", "-")
            model = calibrated(directory, effects, weather)
            cube = load_weather([str(p) for p in weather], cache_dir=directory / "cache")
            seen = make_world(directory / "calibration", effects, flights=8, seed=11, weather=weather, **HARD)  # type: ignore[arg-type]
            unseen = make_world(directory / "unseen", effects, flights=UNSEEN_FLIGHTS, seed=UNSEEN_SEED,
                                cadence_s=UNSEEN_CADENCE_S, weather=weather, **HARD)  # type: ignore[arg-type]  # fmt: skip
            train, scored = (
                world_rows(model, seen, cube, CHECKPOINTS),
                world_rows(model, unseen, cube, CHECKPOINTS),
            )
            training = [
                (r.flight, name, r.whole_km, r.no_wind_km, r.check)
                for name, rows in train.items()
                for r in rows
                if r.wind
            ]
            print(f"### {world}")
            for prior in (False, True):
                drop = choose_lookback(training, prior)
                cells = []
                for name, _ in CHECKPOINTS:
                    rows = scored[name]
                    gain = log_gain([(r[2], r[3]) for r in training if r[1] == name]) if prior else 0.0
                    flown = [r.wind and flies_wind(r.check, drop, gain) for r in rows]
                    chosen = [
                        r.whole_km if not r.wind or f else r.no_wind_km
                        for r, f in zip(rows, flown, strict=True)
                    ]
                    ratio, low, high = ratio_interval(chosen, [r.restart_km for r in rows])
                    wind = f", wind {sum(flown)}/{len(rows)}" if any(r.wind for r in rows) else ""
                    cells.append(f"{name} {ratio:.2f} ({low:.2f}–{high:.2f}{wind})")
                print(f"wind check{', + prior' if prior else ''} (D {drop / 1000:g} km): {'; '.join(cells)}")
            for how in ("shrunk", "raw", "bound"):
                cells = []
                for name, _ in CHECKPOINTS:
                    rows = scored[name]
                    fit = fit_gain([gain_sample(*r.landings) for r in train[name] if r.wind])
                    gain = {
                        "shrunk": fit.gain,
                        "raw": min(max(fit.raw, 0.0), 1.0),
                        "bound": min(max(fit.raw - 1.96 * fit.sigma, 0.0), 1.0)
                        if math.isfinite(fit.sigma)
                        else 0.0,
                    }[how]
                    landings = []
                    for r in rows:
                        if not r.wind:
                            landings.append(r.whole_km)
                            continue
                        lat, lon = gained(*r.landings[0], *r.landings[1], gain)
                        landings.append(
                            float(GEOD.inv(lon, lat, r.landings[2][1], r.landings[2][0])[2]) / 1000.0
                        )
                    ratio, low, high = ratio_interval(landings, [r.restart_km for r in rows])
                    said = (
                        f", g {gain:.2f} (ĝ {fit.raw:.2f} ± {fit.sigma:.2f})"
                        if any(r.wind for r in rows)
                        else ""
                    )
                    cells.append(f"{name} {ratio:.2f} ({low:.2f}–{high:.2f}{said})")
                print(
                    f"wind × gain ({how}; the calibration flights replayed here, landing interpolated): {'; '.join(cells)}"
                )
            for label, field in (
                ("what ships", "shipped_km"),
                ("before (all of the wind)", "whole_km"),
                ("no wind", "no_wind_km"),
            ):
                cells = []
                for name, _ in CHECKPOINTS:
                    rows = scored[name]
                    landings = [getattr(r, field) for r in rows]
                    ratio, low, high = ratio_interval(landings, [r.restart_km for r in rows])
                    gains = {round(r.gain, 3) for r in rows if r.gain is not None}
                    said = (
                        f", gain {'/'.join(f'{g:.2f}' for g in sorted(gains))}"
                        if gains and field == "shipped_km"
                        else ""
                    )
                    cells.append(f"{name} {ratio:.2f} ({low:.2f}–{high:.2f}{said})")
                print(f"{label}: {'; '.join(cells)}")
            times = [
                ratio_interval([r.shipped_s for r in scored[n]], [r.restart_s for r in scored[n]])
                for n, _ in CHECKPOINTS
            ]
            print(
                "time, every rule: "
                + "; ".join(
                    f"{n} {t[0]:.2f} ({t[1]:.2f}–{t[2]:.2f})"
                    for (n, _), t in zip(CHECKPOINTS, times, strict=True)
                )
            )


if __name__ == "__main__":
    hard_worlds() if "--hard-worlds" in sys.argv else main()

"""Is the λ departure table a function of the record's cadence? Issue #30's last missed floor:
docs/planning/departure-cadence.md.

Run from the repository root: ``.venv/bin/python docs/planning/departure_cadence.py`` (about 40 s).

The diagnosis tested: EOSS → SuperBIT from 10 km misses the 0.85× floor (0.94×) because the departure
table (``live_evaluation.rate_law``: median and 1.4826 MAD of ln(record λ / remaining λ) by height, and
the remaining-λ prior) is learned on EOSS's 15–30 s records and flown on SuperBIT's 2–5 minute ones.

Measured: (1) the table learned on the training flights as recorded and thinned to one fix per 60, 120,
180 and 300 s, and thinned to each scored flight's own cadence (its median interval between fixes:
what the record in hand says live); (2) which part of the EOSS table does not carry to SuperBIT: its
median departure, its spread and its prior, each swapped for SuperBIT's own (leave-one-out among the
SuperBIT flights), and the median departure left out; (3) the median departure of each payload's
flights on the textbook law and on the calibrated SuperBIT law; (4) whether a flight's own record shows
its departure (the trend of λ within the record against the departure). Each table is flown on the scored flights exactly
as ``drs live evaluate`` flies textbook + λ (``LivePredictor`` with the table and prior, the first
report at or below each checkpoint height; what ships flies the same λ below 22.5 km, so its time
figures from 20 km down are these): the mean |remaining-time error| ÷ the plain restart's, with the
95 % paired-bootstrap interval over the scored flights (``live_evaluation.ratio_interval``).

Thinning keeps each descent's first fix, each fix at least the interval after the last kept, and the
last three fixes as recorded, so that the touchdown every λ is measured against
(``live_evaluation._touchdown_s``: the last airborne fix carried down) is the same at every cadence.
"""

from __future__ import annotations

import dataclasses
import math
from collections.abc import Sequence
from pathlib import Path

import numpy as np

from predictor.calibration.live_evaluation import (
    SURVEY_HEIGHTS_KM,
    _Flight,
    _rate_survey,
    _touchdown_s,
    _usable,
    rate_law,
    ratio_interval,
)
from predictor.descent import PROFILES, RatePrior
from predictor.prediction.live import NO_CORRECTION, DescentRecord, LivePredictor, RateDiscrepancy, by_height
from predictor.prediction.model_file import load_model

SUPERBIT = sorted(Path("../shared/data/tracks/pyballoon_superbit").glob("*-*.csv"))
EOSS = sorted(Path("tests/data/eoss").glob("*_descent.csv"))
MODEL = Path(__file__).with_name("superbit-2018-2019-model.json")
CHECKPOINTS_KM = (25.0, 20.0, 15.0, 10.0, 5.0)
TABLE_KM = (3.5, 6.0, 8.5, 11.0, 13.5, 18.5, 23.5)
CADENCES_S: tuple[float | str | None, ...] = (None, 60.0, 120.0, 180.0, 300.0, "own")
PROFILE = PROFILES["superbit-test"]
Law = tuple[RatePrior | None, RateDiscrepancy]
Errors = dict[float, tuple[list[float], list[float]]]


def cadence_s(flight: _Flight) -> float:
    """The flight's median seconds between consecutive fixes."""
    times = [f.time for f in flight.descent]
    return float(np.median([(b - a).total_seconds() for a, b in zip(times, times[1:], strict=False)]))


def thinned(flight: _Flight, every_s: float | None) -> _Flight:
    """The descent a tracker reporting once per ``every_s`` would have sent (None: as recorded)."""
    if every_s is None:
        return flight
    kept = [flight.descent[0]]
    for fix in flight.descent[1:-3]:
        if (fix.time - kept[-1].time).total_seconds() >= every_s:
            kept.append(fix)
    return dataclasses.replace(flight, descent=[*kept, *flight.descent[-3:]])


def law_at(flights: Sequence[_Flight], every_s: float | None) -> Law:
    """The prior and departure table of ``flights`` on the textbook law, their records thinned."""
    return rate_law(_rate_survey([thinned(f, every_s) for f in flights], PROFILE, ()))


def replay(flight: _Flight, prior: RatePrior | None, discrepancy: RateDiscrepancy, errors: Errors) -> None:
    """Fly ``flight`` as ``drs live evaluate`` flies textbook + λ; add its remaining-time errors (with λ,
    plain) at each checkpoint to ``errors``."""
    live = LivePredictor(flight.cube, PROFILE, flight.ground, NO_CORRECTION, prior=prior,
                         discrepancy=discrepancy)  # fmt: skip
    touchdown_s = _touchdown_s(flight.descent, flight.landing.alt_m)
    for fix in flight.descent[:-1]:
        live.observe(fix)
        for km in CHECKPOINTS_KM:
            if flight.checkpoints.get(km) is not fix:
                continue
            remaining_s = touchdown_s - (fix.time - flight.descent[0].time).total_seconds()
            plain = live.predict_from(fix, NO_CORRECTION).prediction.descent_s
            errors[km][0].append(plain / live.rate(fix).factor - remaining_s)
            errors[km][1].append(plain - remaining_s)


def cells(errors: Errors) -> str:
    return " | ".join(f"{r:.2f} ({lo:.2f}–{hi:.2f})" for r, lo, hi in
                      (ratio_interval(a, b) for a, b in errors.values()))  # fmt: skip


def by_cadence(train: Sequence[_Flight], scored: Sequence[_Flight], every_s: float | str | None) -> str:
    """The scored flights flown with the training table learned at ``every_s`` ("own": each scored
    flight's own cadence, rounded to the second)."""
    laws: dict[float | None, Law] = {}
    errors: Errors = {km: ([], []) for km in CHECKPOINTS_KM}
    for flight in scored:
        cadence = round(cadence_s(flight)) if every_s == "own" else every_s
        assert not isinstance(cadence, str)
        if cadence not in laws:
            laws[cadence] = law_at(train, cadence)
        replay(flight, *laws[cadence], errors)
    return cells(errors)


def mixed(trained: RateDiscrepancy, own: RateDiscrepancy, parts: str) -> RateDiscrepancy:
    """The training table with the parts in ``parts`` taken from ``own`` (b: the median departure, s: its
    spread, p: the remaining-λ prior); 0: no median departure at all."""
    heights = SURVEY_HEIGHTS_KM
    bias = [0.0 if "0" in parts else (own if "b" in parts else trained).at(km)[0] for km in heights]
    spread = [(own if "s" in parts else trained).at(km)[1] for km in heights]
    prior = own if "p" in parts else trained
    mean = [by_height(km, prior.heights_km, prior.remaining_log_mean) for km in heights]
    sigma = [by_height(km, prior.heights_km, prior.remaining_log_sigma) for km in heights]
    return RateDiscrepancy(heights, tuple(bias), tuple(spread), tuple(mean), tuple(sigma),
                           (min(prior.remaining_flights),) * len(heights))  # fmt: skip


SWAPS = (
    ("", "the EOSS table (what ships)"),
    ("b", "SuperBIT's median departure"),
    ("s", "SuperBIT's spread"),
    ("p", "SuperBIT's prior"),
    ("bsp", "SuperBIT's whole table"),
    ("0", "no median departure"),
)


def report(superbit: Sequence[Path], eoss: Sequence[Path]) -> str:
    sets = {
        "2018": _usable([p for p in superbit if p.name.startswith("18-")], None, [], None, None, None),
        "2019": _usable([p for p in superbit if p.name.startswith("19-")], None, [], None, None, None),
        "EOSS": _usable(list(eoss), None, [], None, None, None),
    }
    sets["SuperBIT"] = sets["2018"] + sets["2019"]
    heading = " | ".join(f"{km:g} km" for km in CHECKPOINTS_KM)
    lines = [
        "# The λ departure table and the record's cadence (issue #30)",
        "",
        "Written by `.venv/bin/python docs/planning/departure_cadence.py` (method in its docstring). Remaining-time",
        "error of textbook + λ ÷ the plain restart's, 95 % paired-bootstrap interval over the scored flights.",
        "",
    ]
    for name in ("SuperBIT", "EOSS"):
        cadences = [cadence_s(f) for f in sets[name]]
        lines.append(
            f"* {name}: {len(sets[name])} flights, median interval {min(cadences):.0f}–{max(cadences):.0f} s"
        )
    lines += ["", "## The departure table by cadence (textbook law)", "",
              "Median / 1.4826 MAD of ln(record λ / remaining λ), all the set's flights:", "",
              "| records | " + " | ".join(f"{km:g} km" for km in TABLE_KM) + " |",
              "|---|" + "---|" * len(TABLE_KM)]  # fmt: skip
    for name, every in (("EOSS", None), ("EOSS", 60.0), ("EOSS", 180.0), ("EOSS", 300.0), ("SuperBIT", None)):
        d = law_at(sets[name], every)[1]
        row = " | ".join(f"{d.at(km)[0]:+.3f} / {d.at(km)[1]:.3f}" for km in TABLE_KM)
        lines.append(f"| {name} {'as recorded' if every is None else f'thinned to {every:g} s'} | {row} |")
    lines += ["", "## The training table learned at another cadence", "",
              f"| split | training records | {heading} |", "|---|---|" + "---|" * len(CHECKPOINTS_KM)]  # fmt: skip
    for train, scored in (("EOSS", "SuperBIT"), ("SuperBIT", "EOSS"), ("2018", "2019"), ("2019", "2018")):
        for cadence in CADENCES_S:
            label = ("as recorded" if cadence is None else
                     "thinned to each scored flight's own cadence" if cadence == "own" else f"thinned to {cadence:g} s")  # fmt: skip
            lines.append(
                f"| {train} → {scored} | {label} | {by_cadence(sets[train], sets[scored], cadence)} |"
            )
    _, trained = law_at(sets["EOSS"], None)
    own_survey = _rate_survey(sets["SuperBIT"], PROFILE, ())
    own = {f.name: rate_law(own_survey, leave_out=f.name)[1] for f in sets["SuperBIT"]}
    lines += ["", "## Which part of the EOSS table does not carry to SuperBIT", "",
              "EOSS → SuperBIT, one part of the EOSS table swapped for SuperBIT's own (each SuperBIT flight",
              "left out of its own):", "",
              f"| table | {heading} |", "|---|" + "---|" * len(CHECKPOINTS_KM)]  # fmt: skip
    for parts, label in SWAPS:
        errors: Errors = {km: ([], []) for km in CHECKPOINTS_KM}
        for flight in sets["SuperBIT"]:
            replay(flight, None, mixed(trained, own[flight.name], parts), errors)
        lines.append(f"| {label} | {cells(errors)} |")
    model = load_model(MODEL)
    lines += ["", "## The median departure is the law's shape error for the payload", "",
              "Median / 1.4826 MAD of ln(record λ / remaining λ), all the set's flights, on the textbook law and on",
              f"{MODEL.name}'s law (calibrated on all 30 SuperBIT flights, so not held out: a diagnosis, not a score):",
              "", "| flights | law | " + " | ".join(f"{km:g} km" for km in TABLE_KM) + " |",
              "|---|---|" + "---|" * len(TABLE_KM)]  # fmt: skip
    for name in ("SuperBIT", "EOSS"):
        for label, payload, terms in (("textbook", PROFILE, ()), ("calibrated", model.payload, model.terms)):
            d = rate_law(_rate_survey(sets[name], payload, terms))[1]
            row = " | ".join(f"{d.at(km)[0]:+.3f} / {d.at(km)[1]:.3f}" for km in TABLE_KM)
            lines.append(f"| {name} | {label} | {row} |")
    lines += ["", "## Does the flight's own record show its shape?", "",
              "At every fix 4–12 and 12–20 km above the ground, the record's trend (ln λ of its last 3 km less",
              "ln λ of the 3 km above them) against its departure (ln λ of its last 6 km less the remaining",
              "descent's), textbook law: the least-squares line departure = a + b · trend, and r:", "",
              "| flights | heights | fixes | mean trend | mean departure | a | b | r |",
              "|---|---|---|---|---|---|---|---|"]  # fmt: skip
    for name in ("SuperBIT", "EOSS"):
        for low_km, high_km in ((4.0, 12.0), (12.0, 20.0)):
            trend, departure = trends(sets[name], low_km, high_km)
            b, a = np.polyfit(trend, departure, 1)
            r = float(np.corrcoef(trend, departure)[0, 1])
            lines.append(f"| {name} | {low_km:g}–{high_km:g} km | {trend.size} | {trend.mean():+.3f} | "
                         f"{departure.mean():+.3f} | {a:+.3f} | {b:+.2f} | {r:+.2f} |")  # fmt: skip
    return "\n".join(lines) + "\n"


def trends(flights: Sequence[_Flight], low_km: float, high_km: float) -> tuple[np.ndarray, np.ndarray]:
    """(trend, departure) at every fix between ``low_km`` and ``high_km`` above the ground whose record
    has both 3 km windows."""
    trend, departure = [], []
    for flight in flights:
        record = DescentRecord(LivePredictor(flight.cube, PROFILE, flight.ground).law)
        touchdown_s = _touchdown_s(flight.descent, flight.landing.alt_m)
        for fix in flight.descent[:-1]:
            record.add(fix)
            height_m = fix.alt_m - flight.landing.alt_m
            law_s = record.remaining_model_s(fix.alt_m) or 0.0
            measured_s = touchdown_s - (fix.time - flight.descent[0].time).total_seconds()
            if not 1000.0 * low_km <= height_m < 1000.0 * high_km or law_s <= 0.0 or measured_s <= 0.0:
                continue
            near = record.rate_fit(fix.alt_m, window_m=3000.0)
            far = record.rate_fit(fix.alt_m + 3000.0, window_m=3000.0, earlier=True)
            whole = record.rate_fit(fix.alt_m)
            if near is None or far is None or whole is None:
                continue
            trend.append(math.log(near.factor / far.factor))
            departure.append(math.log(whole.factor) - math.log(law_s / measured_s))
    return np.array(trend), np.array(departure)


def main() -> None:
    out = Path(__file__).with_name("departure-cadence.md")
    out.write_text(report(SUPERBIT, EOSS), encoding="utf-8")
    print(out.read_text(encoding="utf-8"))


if __name__ == "__main__":
    main()

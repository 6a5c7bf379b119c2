"""Issue #30's pre-flight floor with whole seasons and whole flights held out: docs/calibration/preflight-held-out.md.

Run from the repository root: ``.venv/bin/python docs/calibration/preflight_held_out.py`` (about a minute).

Why a script: ``drs calibrate`` reports its pre-flight law held out one flight at a time **within** the
calibration (``selection.preflight_gate``: the fits without the flight, but the selection and the gate
decided on all of them). The floor "pre-flight, on the same sets: descent time and landing ≤ 1.0× the
plain law's" is also asked across seasons and on EOSS, where nothing the scored flight shows may enter
what flies on it. So each split here calibrates on its training flights exactly as ``drs calibrate
--winds ascent --payload superbit-test`` does (``run.prepare``, ``selection.calibrate``, defaults) and
flies each scored flight from its descent start with:

* **what ships**: the calibration's pre-flight law (``Calibration.preflight_terms``, what
  ``calibrated_model`` writes as the model's pre-flight law): the terms that passed the pre-flight
  gate, with the training flights' median λ under them where λ passed it too, else λ = 1;
* **the plain law**: the nominal payload's textbook law, λ = 1, nothing learned;
* **λ alone**: the plain law × the training flights' median λ under it (``selection.rate_priors``), the
  strongest simple baseline before the gate judged λ.

λ itself goes through the pre-flight gate (``selection.preflight_gate``: the training calibration's
held-out pre-flight law against the same with λ = 1, neither mean larger and one smaller beyond its
interval); where it fails, what ships flies λ = 1. The report lists each training calibration's decision.

Splits: SuperBIT 2018 → 2019 and 2019 → 2018 (calibrated on one season, the other scored), and EOSS
leave-one-out nested (each of the 10 landed EOSS flights the live reports use scored with a calibration
of the other 9: selection, gate and λ all without it), and the 18 EOSS flights copied after every
design choice (tests/data/eoss/unseen) scored with a calibration of the EOSS design set and with one of
all 30 SuperBIT flights. Ground: level at each flight's measured landing
altitude, as in the live reports (no ``--dem``). Each ratio is mean |error| of what ships ÷ the
baseline's, with its 95 % paired-bootstrap interval over the scored flights
(``live_evaluation.ratio_interval``, fixed seed): the report is deterministic.

The stated pre-flight uncertainty is checked on the same splits: the landing ellipse and the σ of ln λ
of the descent-time interval (``prior_spread``) each training calibration states, **before** (the
ellipse fitted on the held-out landings of shape × the median λ, ``Calibration.after_residuals``, and
the rate prior's sd of ln λ: what the model file carried until the pre-flight gate's law was used) and
**now** (the ellipse fitted on the held-out landings of the pre-flight law,
``Calibration.preflight_residuals``, as ``run.preflight_ellipse`` does, and
``Calibration.preflight_spread``, the |ln(predicted / measured descent time)| that 68.3 % of that law's
held-out predictions stay within), with the alternatives tried for σ beside them (the RMS of each
flight's own λ about the flown λ, the RMS of the same log ratio).
Each scored flight is flown with what ships. A flight is inside the nσ ellipse when
(along/σ∥)² + (across/σ⊥)² ≤ n² at its own predicted drift and lead time (a bivariate normal holds
39.3 % and 86.5 %), and inside the ±nσ descent-time interval when |ln(predicted / measured descent
time)| ≤ nσ (68.3 % and 95.4 %; exact for a law whose terms all scale the rate, which the plain law
every split ships does). Within a calibration (its own leave-one-out), flight i's ellipse and σ are
fitted on the other flights' held-out residuals; with the plain law shipped nothing the flight shows
enters what is stated for it but the gate's decision. Shares with their 95 % Wilson interval.
"""

from __future__ import annotations

import argparse
import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from predictor.calibration.effects import LIBRARY
from predictor.calibration.ellipse_fit import fit_parameters
from predictor.calibration.live_evaluation import ratio_interval, share_with_interval
from predictor.calibration.preflight_gate import TermGate
from predictor.calibration.residuals import FlightCase, FlightResiduals, residuals, run, score
from predictor.calibration.run import prepare
from predictor.calibration.selection import (
    ONE_SIGMA,
    RATE_SCALE,
    Calibration,
    Fit,
    FlightBatch,
    calibrate,
    rate_priors,
    t_future,
)
from predictor.descent import Payload, Term
from predictor.prediction import ErrorModel, coverage

SUPERBIT = sorted(Path("../shared/data/tracks/pyballoon_superbit").glob("*-*.csv"))
EOSS = sorted(Path("tests/data/eoss").glob("*_descent.csv"))
UNSEEN = sorted(Path("tests/data/eoss/unseen").glob("*_descent.csv"))
"""EOSS flights copied after every design choice (tests/data/eoss/SOURCES.md): scored, never trained on."""
STEP_M = 200.0
"""``drs calibrate``'s default altitude step."""
LAWS = ("what ships", "plain law", "λ alone")
FITS = ("before", "now")
"""What the stated pre-flight ellipse was fitted on: shape × median λ (before), the pre-flight law (now)."""
SIGMAS = ("before", "own λ RMS", "time RMS", "now")
"""The σ of ln λ the descent-time interval flies: the rate prior's sd (before); tried and dropped, the
RMS of each flight's own λ about the flown one and the RMS of ln(predicted / measured descent time) of
the pre-flight law, held out; now the |ln(predicted / measured descent time)| 68.3 % of those stay
within (``Calibration.preflight_spread``)."""


@dataclass(frozen=True)
class Scored:
    """Per scored flight and law: |descent-time error| s and landing error km; what shipped on it; the
    training flights' median λ on the plain law and the scored flight's own best λ on it."""

    time_s: dict[str, list[float]] = field(default_factory=lambda: {n: [] for n in LAWS})
    landing_km: dict[str, list[float]] = field(default_factory=lambda: {n: [] for n in LAWS})
    shipped: list[str] = field(default_factory=list)
    gate_passed: list[bool] = field(default_factory=list)
    trained_rate: list[float] = field(default_factory=list)
    own_rate: list[float] = field(default_factory=list)
    ellipse: dict[str, list[tuple[bool, bool]]] = field(default_factory=lambda: {f: [] for f in FITS})
    """Per fit and scored flight: inside the stated 1σ and 2σ ellipse."""
    time: dict[str, list[tuple[bool, bool]]] = field(default_factory=lambda: {f: [] for f in SIGMAS})
    """Per σ and scored flight: within the stated ±1σ and ±2σ descent-time interval."""
    sigma_km: dict[str, list[float]] = field(default_factory=lambda: {f: [] for f in FITS})
    """The stated ellipse's σ∥ at each scored flight's drift."""
    log_sigma: dict[str, list[float]] = field(default_factory=lambda: {f: [] for f in SIGMAS})


@dataclass(frozen=True)
class Stated:
    """The pre-flight uncertainty a calibration states: the ellipse per ``FITS``, the σ per ``SIGMAS``."""

    ellipse: dict[str, ErrorModel]
    log_sigma: dict[str, float]
    """σ of ln λ of the descent-time interval."""


def stated(cal: Calibration, keep: np.ndarray) -> Stated:
    """What ``cal`` states from its flights ``keep``: the ellipse as ``ellipse_fit.fit_ellipse`` fits it
    (its maximum-likelihood parameters), before on ``after_residuals``, now on ``preflight_residuals``
    (``run.preflight_ellipse``); the σ of each of ``SIGMAS``."""
    t = cal.t_future_h[keep]

    def kept(found: Sequence[FlightResiduals]) -> list[FlightResiduals]:
        return [r for r, k in zip(found, keep, strict=True) if k]

    def ellipse(found: Sequence[FlightResiduals]) -> ErrorModel:
        along, cross, d = (np.array([getattr(r, a) for r in kept(found)])
                           for a in ("landing_along_km", "landing_cross_km", "predicted_drift_km"))  # fmt: skip
        sigma0, h, k, q = fit_parameters(along, cross, d, t)[0]
        return ErrorModel(float(sigma0), float(h), float(k), float(q))

    def rms(logs: np.ndarray) -> float:
        return min(float(np.sqrt(np.mean(logs**2))), 1.0)

    prior = np.log(cal.rate_factors[keep & np.isfinite(cal.rate_factors)])
    pre = cal.preflight if cal.preflight is not None else cal.after
    own = np.log(pre.rate_factor[keep & np.isfinite(pre.rate_factor)])
    times = np.array([r.descent_time_log_ratio for r in kept(cal.preflight_residuals)])
    return Stated(
        {"before": ellipse(cal.after_residuals), "now": ellipse(cal.preflight_residuals)},
        {
            "before": min(float(np.std(prior, ddof=1)), 1.0),
            "own λ RMS": rms(own),
            "time RMS": rms(times),
            "now": min(float(np.quantile(np.abs(times), ONE_SIGMA)), 1.0),
        },
    )


def check(said: Stated, r: FlightResiduals, t_h: float, out: Scored) -> None:
    """Whether a flight flown with what ships (its residuals ``r``) lands inside the stated ellipses and
    falls within the stated descent-time intervals, at 1σ and 2σ."""
    for fit in FITS:
        parallel, perpendicular = said.ellipse[fit].sigmas_km(r.predicted_drift_km, t_h)
        radius = math.hypot(r.landing_along_km / parallel, r.landing_cross_km / perpendicular)
        out.ellipse[fit].append((radius <= 1.0, radius <= 2.0))
        out.sigma_km[fit].append(parallel)
    log_ratio = abs(r.descent_time_log_ratio)
    for name in SIGMAS:
        sigma = said.log_sigma[name]
        out.time[name].append((log_ratio <= sigma, log_ratio <= 2.0 * sigma))
        out.log_sigma[name].append(sigma)


def cases(paths: Sequence[Path]) -> tuple[list[FlightCase], Payload]:
    """The flights ``drs calibrate --winds ascent --payload superbit-test`` would use, by its rules."""
    args = argparse.Namespace(
        tracks=[str(p) for p in paths], weather=None, winds="ascent", step=STEP_M, max_effects=3,
        payload="superbit-test", mass=None, cda=None, effects=None, dem=None, cache_dir=None, date=None,
    )  # fmt: skip
    inputs = prepare(args)
    return inputs.cases, inputs.payload


def shipped(cal: Calibration) -> str:
    """What the pre-flight law flies, in words: λ and the terms besides it."""
    terms = cal.preflight_terms()
    rest = ", ".join(t.name for t in terms[1:])
    return f"λ {terms[0].parameters()['scale']:.3f}" + (f" + {rest}" if rest else "")


def fly(
    train: Sequence[FlightCase], scored: Sequence[FlightCase], payload: Payload, out: Scored
) -> Calibration:
    """Calibrate on ``train`` as ``drs calibrate`` does; add each scored flight's errors under the three
    laws to ``out``. Returns the calibration (its own leave-one-out figures are reported too)."""
    cal = calibrate(train, payload, LIBRARY, step_m=STEP_M, seed=0)
    plain_rate: Fit = rate_priors(FlightBatch(train, payload, STEP_M), [[] for _ in train], [])[2]
    laws: dict[str, tuple[Term, ...]] = {
        "what ships": cal.preflight_terms(),
        "plain law": (),
        "λ alone": (Fit(RATE_SCALE, 0, plain_rate.value).term(),),
    }
    passed = rate_gate(cal).preflight
    said = stated(cal, np.ones(len(train), dtype=bool))
    for case in scored:
        shown = residuals(case, run(case, payload, laws["what ships"], 1, STEP_M))
        check(said, shown, t_future(case), out)
        for name, terms in laws.items():
            s = score(case, run(case, payload, terms, 1, STEP_M))
            out.time_s[name].append(abs(float(s.descent_time_error_s[0])))
            out.landing_km[name].append(float(s.landing_error_km[0]))
            if name == "plain law":
                out.own_rate.append(float(s.rate_factor[0]))
        out.shipped.append(shipped(cal))
        out.gate_passed.append(passed)
        out.trained_rate.append(plain_rate.value)
    return cal


def splits(
    superbit: Sequence[Path], eoss: Sequence[Path], unseen: Sequence[Path]
) -> tuple[dict[str, Scored], dict[str, Calibration], dict[str, Scored]]:
    """The held-out splits, the calibrations whose own leave-one-out is reported beside them, and the
    coverage of what each of those states, flight by flight without it (``within_coverage``)."""
    (c18, payload), (c19, _) = (cases([p for p in superbit if p.name.startswith(y)]) for y in ("18-", "19-"))
    flights, eoss_payload = cases(eoss)
    later, _ = cases(unseen)
    out = {
        "SuperBIT 2018 → 2019": Scored(), "SuperBIT 2019 → 2018": Scored(), "EOSS leave-one-out": Scored(),
        "EOSS → unseen EOSS": Scored(), "SuperBIT 2018–2019 → unseen EOSS": Scored(),
    }  # fmt: skip
    within = {
        "SuperBIT 2018": fly(c18, c19, payload, out["SuperBIT 2018 → 2019"]),
        "SuperBIT 2019": fly(c19, c18, payload, out["SuperBIT 2019 → 2018"]),
        "SuperBIT 2018–2019": fly([*c18, *c19], later, payload, out["SuperBIT 2018–2019 → unseen EOSS"]),
        "EOSS": fly(flights, later, eoss_payload, out["EOSS → unseen EOSS"]),
    }
    for i, case in enumerate(flights):
        fly([c for j, c in enumerate(flights) if j != i], [case], eoss_payload, out["EOSS leave-one-out"])
    return out, within, {name: within_coverage(cal) for name, cal in within.items()}


def within_coverage(cal: Calibration) -> Scored:
    """A calibration's own leave-one-out of what it states: flight i against the ellipse and σ fitted on
    the other flights' held-out residuals, with its own held-out pre-flight residual."""
    out = Scored()
    for i in range(len(cal.names)):
        keep = np.arange(len(cal.names)) != i
        check(stated(cal, keep), cal.preflight_residuals[i], cal.t_future_h[i], out)
    return out


def rate_gate(cal: Calibration) -> TermGate:
    """The pre-flight gate's decision on λ in a calibration."""
    return next(g for g in cal.gate if g.term == RATE_SCALE.name)


def span(values: np.ndarray) -> str:
    """One value, or the range of the folds' values."""
    low, high = f"{values.min():.3f}", f"{values.max():.3f}"
    return low if low == high else f"{low}–{high} (per fold)"


def ratio(model: Sequence[float], baseline: Sequence[float]) -> str:
    """Mean |model| ÷ mean |baseline| with its 95 % paired-bootstrap interval."""
    value, low, high = ratio_interval(model, baseline)
    return f"{value:.2f} ({low:.2f}–{high:.2f})"


def cell(model: Sequence[float], baseline: Sequence[float], digits: int) -> str:
    """The baseline's mean and what ships ÷ it: two table cells."""
    return f"{np.mean(np.abs(baseline)):.{digits}f} | {ratio(model, baseline)}"


def floor(split: str, what: str, model: Sequence[float], plain: Sequence[float]) -> str:
    ratio = ratio_interval(model, plain)[0]
    return f"{split}, {what}: {ratio:.2f}× the plain law, {'met' if round(ratio, 2) <= 1.0 else 'MISSED'}"


HEADER = (
    "| {first} | flights | what ships pre-flight | time: ships s | plain law s | ships ÷ plain | λ alone s "
    "| ships ÷ λ alone | landing: ships km | plain law km | ships ÷ plain | λ alone km | ships ÷ λ alone |"
)


def share(hits: Sequence[bool]) -> str:
    """A share of flights with its 95 % Wilson interval, in per cent."""
    return share_with_interval(float(np.mean(hits)), len(hits))


def ellipse_rows(rows: dict[str, Scored]) -> list[str]:
    """One table row per set: the stated σ∥, then the 1σ and 2σ shares, before and now."""
    return [
        f"| {name} | {len(r.ellipse['now'])} | {np.mean(r.sigma_km['before']):.2f} / {np.mean(r.sigma_km['now']):.2f} | "
        + " | ".join(share([x[level] for x in r.ellipse[f]]) for level in (0, 1) for f in FITS)
        + " |"
        for name, r in rows.items()
    ]


def time_rows(rows: dict[str, Scored]) -> list[str]:
    """One table row per set: each σ, then its ±1σ and ±2σ shares."""
    return [
        f"| {name} | {len(r.time['now'])} | "
        + " / ".join(f"{np.mean(r.log_sigma[f]):.3f}" for f in SIGMAS)
        + " | "
        + " | ".join(share([x[level] for x in r.time[f]]) for level in (0, 1) for f in SIGMAS)
        + " |"
        for name, r in rows.items()
    ]


def report(superbit: Sequence[Path], eoss: Sequence[Path], unseen: Sequence[Path]) -> str:
    results, within, within_stated = splits(superbit, eoss, unseen)
    lines = [
        "# Pre-flight, held out whole (issue #30)",
        "",
        "Written by `.venv/bin/python docs/calibration/preflight_held_out.py` (method in its docstring; do not",
        "edit by hand). Each scored flight flown pre-flight from its descent start; mean |descent-time error|",
        "and mean landing error of what ships, each baseline's mean, and what ships ÷ it (95 % paired-bootstrap",
        "interval over the scored flights). **Plain law**: the nominal payload's textbook law, λ = 1. **λ alone**:",
        "the plain law × the training flights' median λ. Issue #30's floor: what ships ÷ the plain law ≤ 1.0",
        "(point estimate), descent time and landing.",
        "",
        "## Held out whole: calibrated on one set, flown on another",
        "",
        HEADER.format(first="split"),
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    verdicts = []
    for split, r in results.items():
        kinds = sorted(set(r.shipped), key=r.shipped.index)
        what = kinds[0] if len(kinds) == 1 else f"per fold: {'; '.join(kinds)}"
        t, g = r.time_s, r.landing_km
        lines.append(
            f"| {split} | {len(r.shipped)} | {what} | {np.mean(t['what ships']):.0f} | "
            f"{cell(t['what ships'], t['plain law'], 0)} | {cell(t['what ships'], t['λ alone'], 0)} | "
            f"{np.mean(g['what ships']):.2f} | {cell(g['what ships'], g['plain law'], 2)} | "
            f"{cell(g['what ships'], g['λ alone'], 2)} |"
        )
        verdicts += [floor(split, "descent time", t["what ships"], t["plain law"]),
                     floor(split, "landing", g["what ships"], g["plain law"])]  # fmt: skip
    lines += [
        "",
        "## Within a calibration",
        "",
        "`drs calibrate`'s own leave-one-out: the fits without each flight, the selection and the gate on all",
        "of them.",
        "",
        HEADER.format(first="calibrated on"),
        "|---|---|---|---|---|---|---|---|---|---|---|---|---|",
    ]
    for name, cal in within.items():
        pre = cal.preflight if cal.preflight is not None else cal.after
        times = [h.descent_time_error_s.tolist() for h in (pre, cal.baseline, cal.rate_only)]
        lands = [h.landing_error_km.tolist() for h in (pre, cal.baseline, cal.rate_only)]
        lines.append(
            f"| {name} | {len(cal.names)} | {shipped(cal)} | {np.mean(np.abs(times[0])):.0f} | "
            f"{cell(times[0], times[1], 0)} | {cell(times[0], times[2], 0)} | {np.mean(lands[0]):.2f} | "
            f"{cell(lands[0], lands[1], 2)} | {cell(lands[0], lands[2], 2)} |"
        )
        verdicts += [floor(f"{name}, within", "descent time", times[0], times[1]),
                     floor(f"{name}, within", "landing", lands[0], lands[1])]  # fmt: skip
    lines += [
        "",
        "## The pre-flight gate on λ",
        "",
        "λ flies pre-flight only where the training calibration's own leave-one-out says it beats the law",
        "without it by the gate's rule; otherwise the pre-flight law flies λ = 1.",
        "",
        *(f"* {split}: the calibrations of {sum(r.gate_passed)} of {len(r.gate_passed)} scored flights passed λ"
          for split, r in results.items()),
        *(f"* {name}: `descent_rate_scale` {rate_gate(cal).reason}" for name, cal in within.items()),
    ]  # fmt: skip
    lines += [
        "",
        "## λ: the training median against the scored flights' own",
        "",
        "Each scored flight's own best λ on the plain law (``Scores.rate_factor``), against the training",
        "flights' median λ (what the pre-flight gate judges): the median of the scored flights' own λ, and the mean",
        "|ln λ| of the scored flights' own λ from 1 (the plain law) and from the training median.",
        "",
        "| split | training median λ | scored flights' own λ: median (range) | own λ from 1: mean \\|ln λ\\| "
        "| own λ from the training median: mean \\|ln(λ / median)\\| |",
        "|---|---|---|---|---|",
    ]
    for split, r in results.items():
        own, trained = np.array(r.own_rate), np.array(r.trained_rate)
        lines.append(
            f"| {split} | {span(trained)} | {np.median(own):.3f} "
            f"({own.min():.3f}–{own.max():.3f}) | {np.mean(np.abs(np.log(own))):.3f} | "
            f"{np.mean(np.abs(np.log(own / trained))):.3f} |"
        )
    lines += [
        "",
        "## The stated pre-flight uncertainty, held out",
        "",
        "The landing ellipse and the descent-time interval (``prior_spread``: the pre-flight law flown at",
        "λ·e^(±σ)) each training calibration states, each scored flight flown with what ships. Shares with",
        "their 95 % Wilson interval.",
        "",
        "**The ellipse**, fitted **before** on the held-out landings of shape × the median λ (which no longer",
        "flies before release) and **now** on those of the pre-flight law (what the model file carries).",
        f"Expected for a bivariate normal: {coverage(1.0):.1%} inside the 1σ ellipse, {coverage(2.0):.1%} "
        "inside 2σ. σ∥: the stated",
        "ellipse's along-drift σ at each scored flight's drift, mean.",
        "",
        "| set | flights | σ∥ km before / now | 1σ before | 1σ now | 2σ before | 2σ now |",
        "|---|---|---|---|---|---|---|",
        *ellipse_rows(results),
        *ellipse_rows({f"{name}, within (leave-one-out)": r for name, r in within_stated.items()}),
        "",
        "**The descent-time interval**, its σ of ln λ **before** the rate prior's sd (about the live law's",
        "median); tried, held out: the RMS of the training flights' own λ about the flown λ (**own λ RMS**) and",
        "the RMS of ln(predicted / measured descent time) of the pre-flight law (**time RMS**); **now** the",
        "|ln(predicted / measured descent time)| that 68.3 % of those stay within (what the model file",
        f"carries). Expected for a normal error: {ONE_SIGMA:.1%} within ±1σ, {math.erf(2 / math.sqrt(2)):.1%} "
        "within ±2σ (the interval states ±1σ).",
        "",
        "| set | flights | σ before / own λ RMS / time RMS / now | ±1σ before | own λ RMS | time RMS | now "
        "| ±2σ before | own λ RMS | time RMS | now |",
        "|---|---|---|---|---|---|---|---|---|---|---|",
        *time_rows(results),
        *time_rows({f"{name}, within (leave-one-out)": r for name, r in within_stated.items()}),
    ]
    lines += ["", "Floor (≤ 1.0× the plain law, point estimate):", "", *(f"* {v}" for v in verdicts)]
    return "\n".join(lines) + "\n"


def main() -> None:
    out = Path(__file__).with_name("preflight-held-out.md")
    out.write_text(report(SUPERBIT, EOSS, UNSEEN), encoding="utf-8")
    print(out.read_text(encoding="utf-8"))


if __name__ == "__main__":
    main()

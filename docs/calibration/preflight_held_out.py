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
of the other 9: selection, gate and λ all without it). Ground: level at each flight's measured landing
altitude, as in the live reports (no ``--dem``). Each ratio is mean |error| of what ships ÷ the
baseline's, with its 95 % paired-bootstrap interval over the scored flights
(``live_evaluation.ratio_interval``, fixed seed): the report is deterministic.
"""

from __future__ import annotations

import argparse
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from predictor.calibration.effects import LIBRARY
from predictor.calibration.live_evaluation import ratio_interval
from predictor.calibration.preflight_gate import TermGate
from predictor.calibration.residuals import FlightCase, run, score
from predictor.calibration.run import prepare
from predictor.calibration.selection import (
    RATE_SCALE,
    Calibration,
    Fit,
    FlightBatch,
    calibrate,
    rate_priors,
)
from predictor.descent import Payload, Term

SUPERBIT = sorted(Path("../shared/data/tracks/pyballoon_superbit").glob("*-*.csv"))
EOSS = sorted(Path("tests/data/eoss").glob("*_descent.csv"))
STEP_M = 200.0
"""``drs calibrate``'s default altitude step."""
LAWS = ("what ships", "plain law", "λ alone")


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
    for case in scored:
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
    superbit: Sequence[Path], eoss: Sequence[Path]
) -> tuple[dict[str, Scored], dict[str, Calibration]]:
    """The held-out splits, and the calibrations whose own leave-one-out is reported beside them."""
    (c18, payload), (c19, _) = (cases([p for p in superbit if p.name.startswith(y)]) for y in ("18-", "19-"))
    flights, eoss_payload = cases(eoss)
    out = {"SuperBIT 2018 → 2019": Scored(), "SuperBIT 2019 → 2018": Scored(), "EOSS leave-one-out": Scored()}
    within = {
        "SuperBIT 2018": fly(c18, c19, payload, out["SuperBIT 2018 → 2019"]),
        "SuperBIT 2019": fly(c19, c18, payload, out["SuperBIT 2019 → 2018"]),
        "SuperBIT 2018–2019": calibrate([*c18, *c19], payload, LIBRARY, step_m=STEP_M, seed=0),
        "EOSS": calibrate(flights, eoss_payload, LIBRARY, step_m=STEP_M, seed=0),
    }
    for i, case in enumerate(flights):
        fly([c for j, c in enumerate(flights) if j != i], [case], eoss_payload, out["EOSS leave-one-out"])
    return out, within


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


def report(superbit: Sequence[Path], eoss: Sequence[Path]) -> str:
    results, within = splits(superbit, eoss)
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
    lines += ["", "Floor (≤ 1.0× the plain law, point estimate):", "", *(f"* {v}" for v in verdicts)]
    return "\n".join(lines) + "\n"


def main() -> None:
    out = Path(__file__).with_name("preflight-held-out.md")
    out.write_text(report(SUPERBIT, EOSS), encoding="utf-8")
    print(out.read_text(encoding="utf-8"))


if __name__ == "__main__":
    main()

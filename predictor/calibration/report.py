"""The calibration's results for people (Markdown with PNG plots) and for programs (JSON).

The JSON has a fixed set of keys that programs read (flights, excluded, baseline, candidates,
selected, after, uncertainty_model) plus extra ones (every round of the selection, the binned
correction, the verdict). The Markdown starts with the verdict in plain words, because the reader's
first question is "did the data show an effect, and how much did it help on flights it never saw".
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import matplotlib

matplotlib.use("Agg")
import matplotlib.pyplot as plt  # noqa: E402
import numpy as np  # noqa: E402

from predictor.calibration.effects import BIN_EDGES_M  # noqa: E402
from predictor.calibration.ellipse_fit import PAPER_OBJECTIVE, EllipseFit  # noqa: E402
from predictor.calibration.selection import (  # noqa: E402
    BOOTSTRAP_SAMPLES,
    Calibration,
    CandidateResult,
    FamilyResult,
    HeldOut,
    mean_median,
)

RECORD_LABELS = {
    "vertical": "time-at-altitude RMS error with each flight's own λ profiled out (the shape record)",
    "horizontal": "horizontal RMS error with the measured descent replayed (the horizontal record)",
}
RECORD_METRICS = {"vertical": "shape_time_rms_s", "horizontal": "horizontal_rms_km"}
SYSTEMATIC_SPEED = 0.03
"""A bin's measured/predicted speed within ±3 % of 1 is no systematic difference: 18 s over a 3 km bin
crossed in 10 min, below the vertical record's 10 s floor per fix once spread over the descent."""
RECORD_UNITS = {"vertical": "s", "horizontal": "km"}


@dataclass(frozen=True)
class Exclusion:
    name: str
    reason: str


def _error_block(h: HeldOut) -> dict[str, Any]:
    return h.summary()


def _family_sentence(family: FamilyResult) -> str:
    """What one family's record showed and what its selection did, held out."""
    b, a = family.before.summary(), family.after.summary()
    own = "; ".join(
        f"{RECORD_LABELS[r.name]} {b[r.metric]['mean']:.3g} → {a[r.metric]['mean']:.3g} {r.unit}"
        for r in family.records
    )
    landing = f"landing error {b['landing_error_km']['mean']:.2f} → {a['landing_error_km']['mean']:.2f} km"
    timing = (
        f", |descent-time error| {b['descent_time_error_s']['mean']:.0f} → "
        f"{a['descent_time_error_s']['mean']:.0f} s"
        if family.family == "vertical"
        else ""
    )
    if family.selected:
        names = ", ".join(f"`{f.candidate.name}` ({_params(f.parameters())})" for f in family.selected)
        return f"{family.family.capitalize()}: selected {names}; held out, {own}{timing}, {landing} (means)."
    return (
        f"{family.family.capitalize()}: nothing beat the model by more than the margin on "
        f"{' and '.join(r.name for r in family.records)} record{'s' if len(family.records) > 1 else ''} "
        f"({own})."
    )


def verdict(cal: Calibration) -> str:
    """One paragraph: what each family's record showed, what was kept, and how much it helped, held out."""
    b, a = cal.baseline.summary(), cal.after.summary()
    parts = [_family_sentence(f) for f in cal.families]
    if cal.selected:
        parts.append(
            f"With every selected effect, on flights held out of every fit, the landing error went from "
            f"{b['landing_error_km']['mean']:.2f} to {a['landing_error_km']['mean']:.2f} km (mean; median "
            f"{b['landing_error_km']['median']:.2f} → {a['landing_error_km']['median']:.2f} km) and the RMS "
            f"3-D track error from {b['track_rms_km']['mean']:.2f} to {a['track_rms_km']['mean']:.2f} km."
        )
    else:
        parts.append(
            "No library effect beat the plain model on held-out flights by more than the noise margin."
        )
    parts.append(rate_sentence(cal))
    passed = [t for t in cal.binned_tests if t.passed]
    if passed:
        lead = (
            "No library effect explains it"
            if not cal.selected
            else "The selected effects do not explain all of it"
        )
        what = "; ".join(
            f"on the {t.record} record its {'descent-rate factors' if t.record == 'vertical' else 'added wind'} "
            f"improve the held-out {RECORD_METRICS[t.record]} by {t.mean_improvement:.3f} {t.unit} "
            f"(margin {t.margin:.3f} {t.unit}, {t.wins}/{t.flights} flights better)"
            for t in passed
        )
        parts.append(
            f"{lead}: the altitude-binned correction, fitted without each held-out flight, still helps "
            f"({what}). The residual has a systematic altitude structure the library lacks "
            "(see its profile below)."
        )
    else:
        parts.append(
            "The altitude-binned correction does not improve further on held-out flights ("
            + "; ".join(
                f"{t.record} {t.mean_improvement:.3f} {t.unit}, margin {t.margin:.3f} {t.unit}"
                for t in cal.binned_tests
            )
            + "): what is left is not a systematic function of altitude that these flights can pin down."
        )
    return " ".join(parts)


def rate_sentence(cal: Calibration) -> str:
    """The hierarchical part in words: each flight's own λ, the prior, and what the shape adds to it."""
    p, spread = cal.rate_prior, cal.preflight_spread()
    a, r = cal.after.summary(), cal.rate_only.summary()
    low, high = float(np.nanmin(cal.rate_factors)), float(np.nanmax(cal.rate_factors))
    text = (
        f"Each flight's own rate factor λ on the {'selected shape' if cal.selected else 'plain law'} ranges "
        f"{low:.3f}–{high:.3f}: the rate prior is median λ {p.median:.3f}, spread of ln λ {p.log_sigma:.3f} "
        f"({p.flights} flights). The pre-flight law's descent time, each flight held out, is within "
        f"{spread.log_sigma:.3f} in ln of the measured one for 68 % of the flights: the pre-flight descent "
        f"time is uncertain by about ±{100 * spread.log_sigma:.0f} % (1σ). The whole shape flown pre-flight (each held-out flight with the median λ of the others): "
        f"time-at-altitude RMS {a['time_rms_s']['mean']:.0f} s and |descent-time error| "
        f"{a['descent_time_error_s']['mean']:.0f} s, against {r['time_rms_s']['mean']:.0f} s and "
        f"{r['descent_time_error_s']['mean']:.0f} s for the plain law with the same λ estimator (the simple "
        "baseline)."
    )
    if cal.unstable:
        text += (
            " FLAG: "
            + ", ".join(f"`{n}` was chosen in only {cal.stability.get(n, 0.0):.0%}" for n in cal.unstable)
            + " of the leave-one-flight-out folds of the decision (fewer than two thirds): it rests on one or"
            " two flights."
        )
    return text


def preflight_sentence(cal: Calibration) -> str:
    """The pre-flight gate and the vertical contest in words (``selection.preflight_gate``, ``Contest``)."""
    parts = []
    if cal.contest is not None:
        c, t = cal.contest, cal.contest.test
        name = c.library.full.candidate.name
        parts.append(
            f"Vertical contest: the binned rate factors passed on top of the law without a vertical term; "
            f"against `{name}` (shape record {c.library_improvement:.1f} s better than without it) they improve "
            f"the shape record by {t.mean_improvement:.1f} s (lower bound {t.lower_bound:.1f} s): "
            + (f"`{name}` ships instead (one parameter, not beaten beyond the interval)." if c.library_wins
               else "the binned rate factors ship.")
        )  # fmt: skip
    for g in cal.gate:
        parts.append(f"Pre-flight gate, `{g.term}`: {g.reason}.")
    pre = (cal.preflight if cal.preflight is not None else cal.after).summary()
    plain = cal.rate_only.summary()
    parts.append(
        f"Pre-flight law as shipped, held out: |descent-time error| {pre['descent_time_error_s']['mean']:.0f} s and "
        f"landing {pre['landing_error_km']['mean']:.2f} km, against {plain['descent_time_error_s']['mean']:.0f} s "
        f"and {plain['landing_error_km']['mean']:.2f} km for the plain law × the median λ."
    )
    return " ".join(parts)


def stability_sentence(cal: Calibration) -> str:
    """How much the selection rests on single flights (``selection.decision_stability``), in words."""
    how = (
        "the whole selection repeated without each of the {n} flights in turn"
        if cal.stability_method == "nested"
        else "the decisions replayed without each of the {n} flights in turn, the fits not repeated"
    ).format(n=len(cal.names))
    if not cal.stability:
        return f"Selection stability ({how}): no candidate is chosen in any fold."
    shipped = {f.candidate.name for f in cal.selected}
    shares = ", ".join(
        f"`{name}` in {share:.0%}{' (FLAG: under two thirds)' if name in shipped and share < 2 / 3 else ''}"
        for name, share in cal.stability.items()
    )
    return f"Selection stability ({how}): chosen {shares} of the folds."


def speed_finding(cal: Calibration) -> str:
    """The paper's near-ground check in one sentence: measured/predicted descent speed by altitude bin.

    Why bins and not the intervals between fixes: at 1 Hz the height between two fixes is the size of
    the GNSS noise, so a ratio per interval is noise, and dropping the intervals in which the noise made
    the altitude rise keeps only those it made fall fast (a noise-only flight then read "160 % faster").
    A bin's ratio is its predicted crossing time over its measured one (a noise error at either edge
    is one fix's, shared by both neighbouring bins), and only a difference beyond ±3 %
    (``SYSTEMATIC_SPEED``) that the flights agree on (paired bootstrap) is called systematic.
    """
    rows = speed_ratio_by_altitude(cal, BIN_EDGES_M)
    if not rows:
        return ""
    systematic = [r for r in rows if r["systematic"]]
    if not systematic:
        return (
            "With the plain law (each flight's own λ taken out) the measured descent speed shows no systematic "
            f"difference from the predicted one in any 3 km bin (every bin within ±{SYSTEMATIC_SPEED:.0%} or not agreed on by the flights)."
        )

    def words(r: dict[str, Any]) -> str:
        pct = abs(r["ratio"] - 1.0) * 100.0
        how = "slower" if r["ratio"] < 1.0 else "faster"
        return (
            f"{pct:.0f} % {how} than predicted at {r['bottom_m'] / 1000:.0f}–{r['top_m'] / 1000:.0f} km "
            f"(crossing times of {r['flights']} flights, 95 % interval {r['low']:.2f}–{r['high']:.2f})"
        )

    low = systematic[0]
    high = max(systematic, key=lambda r: abs(r["ratio"] - 1.0))
    text = f"With the plain law (each flight's own λ taken out) the measured descent is {words(low)}"
    if high is not low:
        text += f", and {words(high)}"
    return text + "."


def _params(p: dict[str, Any]) -> str:
    return ", ".join(f"{k} = {v:.4g}" if isinstance(v, float) else f"{k} = {v}" for k, v in p.items())


def result_json(
    cal: Calibration, ellipse: EllipseFit | None, excluded: Sequence[Exclusion], payload: dict[str, Any],
    weather: str,
) -> dict[str, Any]:  # fmt: skip
    def candidate(r: CandidateResult) -> dict[str, Any]:
        return {
            **r.full.describe(),
            "description": r.full.candidate.why,
            "round": r.round,
            "heldout": _error_block(r.heldout),
            "tests": [t.to_dict() for t in r.tests],
            "passed": r.passed,
        }

    return {
        "flights": list(cal.names),
        "excluded": [{"name": e.name, "reason": e.reason} for e in excluded],
        "baseline": _error_block(cal.baseline),
        "candidates": [candidate(r) for r in (cal.rounds[0] if cal.rounds else ())],
        "selected": [f.describe() for f in cal.selected],
        "after": _error_block(cal.after),
        "uncertainty_model": ellipse.to_dict() if ellipse is not None else None,
        "rounds": [[candidate(r) for r in rnd] for rnd in cal.rounds],
        "families": [
            {
                "family": f.family,
                "records": [
                    {
                        "record": r.name,
                        "metric": r.metric,
                        "replayed": r.replay,
                        "floor": r.floor,
                        "unit": r.unit,
                    }
                    for r in f.records
                ],
                "before": _error_block(f.before),
                "after": _error_block(f.after),
                "selected": [fit.describe() for fit in f.selected],
                "rounds": [[candidate(r) for r in rnd] for rnd in f.rounds],
            }
            for f in cal.families
        ],
        "binned_correction": {
            **cal.binned.to_dict(),
            "heldout": _error_block(cal.binned_heldout),
            "tests": [t.to_dict() for t in cal.binned_tests],
        },
        "landing_change": landing_change(cal),
        "speed_ratio_by_altitude": speed_ratio_by_altitude(cal, BIN_EDGES_M),
        "speed_finding": speed_finding(cal),
        "library_explains_residual": not cal.unexplained,
        "rate_prior": {
            **cal.rate_prior.to_dict(),
            "per_flight": {
                name: round(float(x), 4) for name, x in zip(cal.names, cal.rate_factors, strict=True)
            },
        },
        "rate_only": _error_block(cal.rate_only),
        "preflight_spread": cal.preflight_spread().to_dict(),
        "preflight": _error_block(cal.preflight if cal.preflight is not None else cal.after),
        "preflight_gate": [g.to_dict() for g in cal.gate],
        "live_only": list(cal.live_only),
        "vertical_contest": cal.contest.to_dict() if cal.contest is not None else None,
        "selection_stability": {name: round(share, 3) for name, share in cal.stability.items()},
        "selection_stability_method": cal.stability_method,
        "unstable": list(cal.unstable),
        "verdict": verdict(cal),
        "payload": payload,
        "weather": weather,
        "per_flight": [
            {
                "name": name,
                "baseline": _flight(cal.baseline, i),
                "after": _flight(cal.after, i),
            }
            for i, name in enumerate(cal.names)
        ],
    }


def landing_change(cal: Calibration, seed: int = 0) -> dict[str, Any]:
    """The held-out landing error after selection against before, flight by flight, with its uncertainty.

    Why: "landing error no worse" is a claim about 30 heavy-tailed numbers, so each statistic comes with
    a paired-bootstrap 95 % interval (flights resampled, both errors of a flight together): the mean
    change, the change of the median, and the median of the per-flight changes (the paired one; the
    change of the medians compares two different middle flights). The flights are then split by what
    the selected effects did to their descent time (closer to the measured one, or further), because a
    vertical effect moves the landing only through the time spent in each wind layer; and the landing
    of the replayed run (the measured altitude–time profile flown in the same winds) says what a
    perfect vertical record would have given.
    """
    before, after = cal.baseline.landing_error_km, cal.after.landing_error_km
    change = after - before
    if not np.all(np.isfinite(change)):
        return {}
    picks = np.random.default_rng(seed).integers(0, change.size, (BOOTSTRAP_SAMPLES, change.size))

    def stat(value: float, draws: np.ndarray) -> dict[str, float]:
        low, high = np.quantile(draws, (0.025, 0.975))
        return {"value": round(float(value), 4), "low": round(float(low), 4), "high": round(float(high), 4)}

    closer = np.abs(cal.after.descent_time_error_s) < np.abs(cal.baseline.descent_time_error_s)

    def group(mask: np.ndarray) -> dict[str, float | int | None]:
        return {
            "flights": int(mask.sum()),
            "landing_closer": int((change[mask] < 0.0).sum()),
            "median_change_km": round(float(np.median(change[mask])), 4) if mask.any() else None,
        }

    replayed = np.array([r.landing_error_km for r in cal.baseline_replayed])
    return {
        "mean_change_km": stat(change.mean(), change[picks].mean(axis=1)),
        "median_shift_km": stat(
            np.median(after) - np.median(before),
            np.median(after[picks], axis=1) - np.median(before[picks], axis=1),
        ),
        "median_of_changes_km": stat(np.median(change), np.median(change[picks], axis=1)),
        "landing_closer": int((change < 0.0).sum()),
        "descent_time_closer": group(closer),
        "descent_time_further": group(~closer),
        "replayed_landing_error_km": mean_median(replayed),
    }


def _landing_change_lines(change: dict[str, Any]) -> list[str]:
    if not change:
        return []

    def interval(key: str) -> str:
        c = change[key]
        return f"{c['value']:+.2f} km (95 % interval {c['low']:+.2f} to {c['high']:+.2f})"

    closer, further = change["descent_time_closer"], change["descent_time_further"]
    replayed = change["replayed_landing_error_km"]

    def median(group: dict[str, Any]) -> str:
        value = group["median_change_km"]
        return "" if value is None else f", median change {value:+.2f} km"

    return [
        "## Landing error: before and after, flight by flight (held out)",
        "",
        f"After − before, with paired-bootstrap 95 % intervals ({BOOTSTRAP_SAMPLES} draws over flights): "
        f"mean {interval('mean_change_km')}; median of the per-flight changes {interval('median_of_changes_km')}; "
        f"change of the median {interval('median_shift_km')}. {change['landing_closer']} flights land closer.",
        "",
        "A vertical effect moves the landing only through the time spent in each wind layer. Flights whose "
        f"descent time came closer to the measured one: {closer['landing_closer']} of {closer['flights']} land "
        f"closer{median(closer)}; flights whose descent time went further from it: {further['landing_closer']} "
        f"of {further['flights']}{median(further)}. With the measured altitude–time profile replayed in the "
        f"same winds (a perfect vertical record) the plain model's landing error would be {replayed['mean']:.2f} "
        f"km mean / {replayed['median']:.2f} km median.",
        "",
    ]


def _flight(h: HeldOut, i: int) -> dict[str, float]:
    return {
        "track_rms_km": round(float(h.track_rms_km[i]), 4),
        "altitude_rms_km": round(float(h.altitude_rms_km[i]), 4),
        "time_rms_s": round(float(h.time_rms_s[i]), 1),
        "horizontal_rms_km": round(float(h.horizontal_rms_km[i]), 4),
        "landing_error_km": round(float(h.landing_error_km[i]), 4),
        "descent_time_error_s": round(float(h.descent_time_error_s[i]), 1),
    }


def write_calibration_report(
    path: Path, cal: Calibration, ellipse: EllipseFit | None, excluded: Sequence[Exclusion], title: str,
    command: str, data: dict[str, Any], preface: str = "",
) -> list[Path]:  # fmt: skip
    """The Markdown report and its PNGs (named after the report, next to it). Returns the PNG paths.

    ``preface`` is Markdown placed under the title: a team's reading of the results in its own
    words, kept in its own file so that regenerating the report does not erase it.
    """
    path.parent.mkdir(parents=True, exist_ok=True)
    stem = path.with_suffix("")
    pngs = [
        _plot_vertical(cal, Path(f"{stem}-speed-ratio.png")),
        _plot_horizontal(cal, Path(f"{stem}-position-error.png")),
        _plot_before_after(cal, Path(f"{stem}-before-after.png")),
    ]
    b, a = data["baseline"], data["after"]
    lines = [
        f"# {title}",
        "",
        *([preface.strip(), ""] if preface.strip() else []),
        "## What the data showed",
        "",
        verdict(cal),
        "",
        stability_sentence(cal),
        "",
        preflight_sentence(cal),
        "",
        speed_finding(cal),
        "",
        f"Flights used: {len(cal.names)}. "
        + (
            "Excluded: " + "; ".join(f"{e.name} ({e.reason})" for e in excluded) + "."
            if excluded
            else "Excluded: none (every flight passed the cleaning rules of docs/tracks.md)."
        ),
        "",
        f"Weather: {data['weather']}. Payload: {data['payload'].get('name')} "
        f"(mass {data['payload'].get('mass_kg')} kg, Cd·A {data['payload'].get('cda_m2')} m²).",
        "",
        f"Produced by: `{command}`",
        "",
        "## Records, score and margin",
        "",
        "Each flight is predicted from its descent start. Every effect is fitted and scored on the record "
        "that shows its family. A **vertical** effect: the shape record, the RMS over the descent fixes of "
        "predicted − measured time since descent start at the fix's altitude (s; the landing fix's term is "
        "the descent-time error) after dividing the predicted times by the flight's own best rate factor λ "
        "(closed form), which the wind does not touch: a law is chosen for its shape, which the flights "
        "share, not for the scatter of λ from flight to flight, which no shared law explains. λ itself is "
        "pooled as a prior (its median and the spread of ln λ over the flights), and a pre-flight "
        "prediction flies the shape with the median λ of the training flights. A **horizontal** effect: the horizontal record, the RMS horizontal error (km) of a run that "
        "replays the flight's measured altitude–time profile, so that a descent-rate error cannot "
        "masquerade as wind. A **timing** effect: both, and it must pass on both. Every candidate is "
        "fitted leave-one-flight-out and scored on the flight it never saw; it passes a record when the "
        "paired bootstrap of the mean held-out improvement (4000 draws over flights) has its lower α/K "
        "quantile above zero (α = 0.05, K = candidates in that round) and the mean improvement is at "
        "least the record's floor (vertical 10 s, horizontal 0.1 km). The margin is mean improvement "
        "minus that lower bound. Forward selection: each round keeps, among the candidates that pass, the "
        "one with the largest improvement (in units of its records' floors).",
        "",
        "## Before and after (held out)",
        "",
        "| | time-at-altitude RMS s | shape: same, own λ profiled, s | time-at-pressure RMS s "
        "| altitude-at-time RMS km | abs(descent-time error) s | horizontal RMS, replayed, km "
        "| landing error km | RMS 3-D track km |",
        "|---|---|---|---|---|---|---|---|---|",
        _row("baseline (plain model, λ = 1)", b),
        _row("plain law × median λ of the other flights (λ alone)", data["rate_only"]),
        *(_row(f"plain + the {f['family']} family's effects", f["after"]) for f in data["families"]),
        _row("after (shape selected, refitted jointly, × median λ of the other flights)", a),
        _row("binned correction on top", data["binned_correction"]["heldout"]),
        "",
        "(means over flights; medians are in the JSON. The family rows fly the shape with λ = 1; the shape "
        "column is what the vertical family is selected on. Time-at-pressure: the vertical record read against "
        "each fix's logged pressure, placed in the weather column at the descent start, over the "
        f"{data['baseline']['pressure_time_rms_s']['flights']} flights that logged pressure; reported, "
        "not used for selection.)",
        "",
        f"![before and after]({Path(pngs[2]).name})",
        "",
        *_landing_change_lines(data["landing_change"]),
    ]
    for f in data["families"]:
        lines += _family_section(f, pngs)
    bc = data["binned_correction"]
    lines += [
        "## Altitude-binned correction (fitted on all flights, on top of the selected effects)",
        "",
        "Held out against the selected model: "
        + "; ".join(
            f"{t['record']} record ({'descent-rate factors' if t['record'] == 'vertical' else 'added wind'}): "
            f"improvement {_num(t['mean_improvement'])} {t['unit']}, margin {_num(t['margin'])} {t['unit']}, "
            f"{'passed' if t['passed'] else 'not passed'}"
            for t in bc["tests"]
        )
        + ".",
        "",
        "| bin m | descent-rate factor | added wind east m/s | north m/s | measured time s |",
        "|---|---|---|---|---|",
    ]
    for i, f in enumerate(bc["rate_factor"]):
        if bc["measured_s"][i] > 0:
            lines.append(
                f"| {bc['edges_m'][i]:.0f}–{bc['edges_m'][i + 1]:.0f} | {f:.3f} | {bc['east_ms'][i]:.2f} | "
                f"{bc['north_ms'][i]:.2f} | {bc['measured_s'][i]:.0f} |"
            )
    lines += [
        "",
        "Measured / predicted descent speed by altitude bin (plain law, each flight's predicted times divided "
        "by its own λ): predicted over measured time to cross the bin, summed over the flights that crossed it (below the last airborne fix nothing is "
        "counted, the touchdown is somewhere in that interval), with a 95 % bootstrap interval over flights; "
        f"systematic = beyond ±{SYSTEMATIC_SPEED:.0%} and agreed on by the flights:",
        "",
        "| altitude m | flights | measured s | ratio | 95 % interval | systematic |",
        "|---|---|---|---|---|---|",
        *_speed_ratio_rows(cal),
        "",
    ]
    if ellipse is not None:
        e = ellipse.to_dict()
        se = e["stderr"]
        lines += [
            "## Landing-ellipse model (bivariate-normal maximum likelihood, held-out landing errors of the "
            "pre-flight law)",
            "",
            "| | σ0 km | h | k km²/h² | q | held-out inside 1σ | inside 2σ |",
            "|---|---|---|---|---|---|---|",
            f"| this fit (± bootstrap sd) | {e['sigma0_km']:.3f} ± {se['sigma0_km']:.3f} | "
            f"{e['h']:.3g} ± {se['h']:.2g} | "
            f"{e['k_km2_per_h2']:.3g}{'' if e['k_identifiable'] else ' (not identifiable: one lead time)'} | "
            f"{e['q']:.3f} ± {se['q']:.3f} | {e['coverage_1sigma']:.1%} | {e['coverage_2sigma']:.1%} |",
        ]
        for name, p in e["paper"].items():
            label = (
                "paper's criterion refitted here"
                if name == PAPER_OBJECTIVE
                else f"paper ({name}), same errors"
            )
            lines.append(
                f"| {label} | {p['sigma0_km']} | {p['h']} | {p['k_km2_per_h2']} | {p['q']} | "
                f"{p['coverage_1sigma']:.1%} | {p['coverage_2sigma']:.1%} |"
            )
        lines += [
            f"| expected for a bivariate normal | | | | | {e['expected_1sigma']:.1%} | "
            f"{e['expected_2sigma']:.1%} |",
            "",
        ]
    lines += ["## Per flight (held out)", "", "| flight | altitude RMS km before → after "
              "| time RMS s | horizontal RMS (replayed) km | landing km | descent-time error s |",
              "|---|---|---|---|---|---|"]  # fmt: skip
    for f in data["per_flight"]:
        pb, pa = f["baseline"], f["after"]
        lines.append(
            f"| {f['name']} | {pb['altitude_rms_km']:.3f} → {pa['altitude_rms_km']:.3f} | "
            f"{pb['time_rms_s']:.0f} → {pa['time_rms_s']:.0f} | "
            f"{pb['horizontal_rms_km']:.2f} → {pa['horizontal_rms_km']:.2f} | "
            f"{pb['landing_error_km']:.2f} → {pa['landing_error_km']:.2f} | "
            f"{pb['descent_time_error_s']:.0f} → {pa['descent_time_error_s']:.0f} |"
        )
    path.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return pngs


def speed_ratio_by_altitude(
    cal: Calibration, edges_m: Sequence[float], seed: int = 0
) -> list[dict[str, Any]]:
    """The plain law's measured/predicted descent speed per altitude bin, from crossing times, with each
    flight's own λ taken out (the shape's residual).

    Per bin: Σ predicted / Σ measured time to cross it over the flights that crossed it (time-weighted,
    so a bin crossed briefly weighs little), its 95 % paired-bootstrap interval over flights, and
    whether it is a systematic difference: beyond ±``SYSTEMATIC_SPEED``, crossed by 3 or more flights
    (a partial bin at the top, crossed by one or two, says nothing general) and an interval that
    excludes 1.
    """
    # Each flight's predicted times divided by its own λ: the shape's residual, as the shape record
    # reads it (a flight family that falls 5 % slow everywhere is the rate prior, not a shape).
    own = np.where(np.isfinite(cal.baseline.rate_factor), cal.baseline.rate_factor, 1.0)
    predicted = np.array([b.predicted_s for b in cal.baseline_budgets]) / own[:, None]
    measured = np.array([b.measured_s for b in cal.baseline_budgets])
    rows = []
    rng = np.random.default_rng(seed)
    for k, (lo, hi) in enumerate(zip(edges_m[:-1], edges_m[1:], strict=True)):
        crossed = measured[:, k] > 0.0
        if not crossed.any():
            continue
        p, m = predicted[crossed, k], measured[crossed, k]
        ratio = float(p.sum() / m.sum())
        low = high = ratio
        if p.size >= 3:
            picks = rng.integers(0, p.size, (BOOTSTRAP_SAMPLES, p.size))
            low, high = (
                float(x) for x in np.quantile(p[picks].sum(axis=1) / m[picks].sum(axis=1), (0.025, 0.975))
            )
        agreed = p.size >= 3 and (low > 1.0 or high < 1.0)
        rows.append({
            "bottom_m": lo, "top_m": hi, "flights": int(p.size), "measured_s": round(float(m.sum()), 1),
            "ratio": round(ratio, 4), "low": round(low, 4), "high": round(high, 4),
            "systematic": bool(abs(ratio - 1.0) > SYSTEMATIC_SPEED and agreed),
        })  # fmt: skip
    return rows


def _speed_ratio_rows(cal: Calibration) -> list[str]:
    return [
        f"| {r['bottom_m']:.0f}–{r['top_m']:.0f} | {r['flights']} | {r['measured_s']:.0f} | {r['ratio']:.3f} | "
        f"{r['low']:.3f}–{r['high']:.3f} | {'yes' if r['systematic'] else 'no'} |"
        for r in speed_ratio_by_altitude(cal, BIN_EDGES_M)
    ]


def _num(x: float | None, digits: int = 3) -> str:
    """A number for a table; a dash for a failed run (None) so the table still renders."""
    return "–" if x is None or not np.isfinite(x) else f"{x:.{digits}f}"


def _row(label: str, block: dict[str, Any]) -> str:
    return (
        f"| {label} | {_num(block['time_rms_s']['mean'], 0)} | {_num(block['shape_time_rms_s']['mean'], 0)} | "
        f"{_num(block['pressure_time_rms_s']['mean'], 0)} | "
        f"{_num(block['altitude_rms_km']['mean'])} | "
        f"{_num(block['descent_time_error_s']['mean'], 0)} | "
        f"{_num(block['horizontal_rms_km']['mean'])} | {_num(block['landing_error_km']['mean'])} | "
        f"{_num(block['track_rms_km']['mean'])} |"
    )


FAMILY_RESIDUALS = {
    "vertical": (
        0,
        "Measured / predicted descent speed between consecutive fixes (plain model) against altitude, "
        "air density, wind speed and time since release; the table after the binned correction gives "
        "its median by altitude:",
    ),
    "horizontal": (
        1,
        "Along- and cross-track error (measured − predicted at the same time) with the measured "
        "descent replayed, before and after selection:",
    ),
}


def _family_section(family: dict[str, Any], pngs: Sequence[Path]) -> list[str]:
    """One family: the residual its record shows (plot), every candidate round, the effect chosen,
    and before/after on its own metric and on the landing error."""
    name = family["family"]
    records = [r["record"] for r in family["records"]]
    lines = [f"## {name.capitalize()} family (scored on the {' and '.join(records)} record)", ""]
    if name in FAMILY_RESIDUALS:
        k, text = FAMILY_RESIDUALS[name]
        lines += [text, "", f"![{name} residual]({Path(pngs[k]).name})", ""]
    else:
        lines += ["Its residuals are those of both records, in the two sections above.", ""]
    chosen = ", ".join(f"`{f['effect']}` ({_params(f['parameters'])})" for f in family["selected"]) or "none"
    b, a = family["before"], family["after"]
    own = "; ".join(
        f"{RECORD_METRICS[r]} {_num(b[RECORD_METRICS[r]]['mean'])} → {_num(a[RECORD_METRICS[r]]['mean'])} "
        f"{RECORD_UNITS[r]}"
        for r in records
    )
    lines += [
        f"Effect chosen: {chosen}. Held out (mean): {own}; landing error "
        f"{_num(b['landing_error_km']['mean'])} → {_num(a['landing_error_km']['mean'])} km; "
        f"abs(descent-time error) {_num(b['descent_time_error_s']['mean'], 0)} → "
        f"{_num(a['descent_time_error_s']['mean'], 0)} s.",
        "",
    ]
    for k, rnd in enumerate(family["rounds"], start=1):
        lines += [
            f"Round {k}:",
            "",
            "| effect | parameters (all flights) | record | held-out score (mean) | held-out landing km "
            "| improvement | margin | flights better | passed |",
            "|---|---|---|---|---|---|---|---|---|",
        ]
        for r in rnd:
            for t in r["tests"]:
                metric = RECORD_METRICS[t["record"]]
                lines.append(
                    f"| {r['effect']} | {_params(r['parameters'])} | {t['record']} | "
                    f"{_num(r['heldout'][metric]['mean'])} {t['unit']} | "
                    f"{_num(r['heldout']['landing_error_km']['mean'])} | "
                    f"{_num(t['mean_improvement'])} {t['unit']} | {_num(t['margin'])} {t['unit']} | "
                    f"{t['flights_improved']}/{t['flights']} | {'yes' if t['passed'] else 'no'} |"
                )
        lines.append("")
    return lines


def _plot_vertical(cal: Calibration, out: Path) -> Path:
    fig, axes = plt.subplots(1, 4, figsize=(15, 4), sharey=True)
    res = cal.baseline_residuals
    y = np.concatenate([r.speed_ratio for r in res])
    for ax, attr, label in zip(
        axes,
        ("interval_alt_m", "interval_density", "interval_wind_ms", "interval_t_s"),
        ("altitude (m)", "air density (kg/m³)", "wind speed (m/s)", "time since release (s)"),
        strict=True,
    ):
        x = np.concatenate([getattr(r, attr) for r in res])
        ax.scatter(x, y, s=8, alpha=0.6)
        ax.axhline(1.0, color="k", lw=0.8)
        ax.set_xlabel(label)
    axes[0].set_ylabel("measured / predicted descent speed")
    axes[0].set_ylim(0.3, 2.0)
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)
    return out


def _plot_horizontal(cal: Calibration, out: Path) -> Path:
    fig, axes = plt.subplots(1, 3, figsize=(13, 4), sharey=True)
    for res, label in ((cal.baseline_replayed, "plain model"), (cal.after_replayed, "after (held out)")):
        along = np.concatenate([r.along_km for r in res])
        cross = np.concatenate([r.cross_km for r in res])
        alt = np.concatenate([r.fix_alt_m for r in res])
        wind = np.concatenate([r.fix_wind_ms for r in res])
        t = np.concatenate([r.fix_t_s for r in res])
        axes[0].scatter(alt, np.hypot(along, cross), s=6, alpha=0.5, label=label)
        axes[1].scatter(wind, along, s=6, alpha=0.5, label=label)
        axes[2].scatter(t, cross, s=6, alpha=0.5, label=label)
    axes[0].set_xlabel("altitude (m)")
    axes[0].set_ylabel("horizontal error, measured descent replayed (km)")
    axes[1].set_xlabel("wind speed (m/s)  [along-track error]")
    axes[2].set_xlabel("time since release (s)  [cross-track error]")
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)
    return out


def _plot_before_after(cal: Calibration, out: Path) -> Path:
    """Per flight, held out: each record's score and the landing error, plain model against after."""
    panels = (
        ("time_rms_s", "time-at-altitude RMS (s), vertical record"),
        ("horizontal_rms_km", "horizontal RMS, replayed (km)"),
        ("landing_error_km", "landing error (km)"),
    )
    fig, axes = plt.subplots(1, 3, figsize=(15, 4))
    x = np.arange(len(cal.names))
    for ax, (attr, label) in zip(axes, panels, strict=True):
        ax.bar(x - 0.2, getattr(cal.baseline, attr), 0.4, label="baseline")
        ax.bar(x + 0.2, getattr(cal.after, attr), 0.4, label="after (held out)")
        ax.set_xticks(x, cal.names, rotation=90, fontsize=7)
        ax.set_ylabel(label)
    axes[0].legend()
    fig.tight_layout()
    fig.savefig(out, dpi=80)
    plt.close(fig)
    return out

"""The λ estimators tried for issue #30 (item 1), side by side on held-out splits: the table in docs/planning.md.

Run from the repository root: ``.venv/bin/python docs/planning/rate_estimators.py`` (about a minute).

Why a script and not ``drs live evaluate``: the evaluation flies one estimator (the one in
``predictor.prediction.live``); this one replays each candidate on the textbook law (the superbit-test
payload, v ∝ ρ^-½, each flight's ascent winds) and scores only the vertical: at the first fix at or below
25, 20, 15, 10 and 5 km above the ground, the remaining time the law predicts with the estimated λ
against the measured one, ÷ the same error with λ = 1 (the plain restart). Each split measures the
departure table and prior on its training flights and scores the others. EOSS flights whose track ends
in the air (4 of 9, at 1.6–1.7 km, the Colorado plains) count with their last fix as the ground.

Window forms (where the record's λ comes from): *count* = the Huber fit on the last 6 km, every fix one
unit (what shipped before); *box W* = each fix weighted by the height it spans, at most one independent
fix per 250 m, within W above the report; *exp L* = the same over the whole record, weighted
exp(−Δz / L) by the height above the report. Combinations (how it meets the prior): *pooled* = prior
from the training flights' remaining λ (mean, σ), record less their median departure, MAD spread (what
shipped before); *law-centred* = prior λ = 1 as wide as the training flights' RMS remaining ln λ, record
less the median departure (what ships now); *law, no bias* = the same prior, the record taken without
its median departure, RMS departure as spread.
"""

from __future__ import annotations

import math
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from predictor.calibration.live_evaluation import LevelGround
from predictor.descent import PROFILES
from predictor.prediction.live import (
    INDEPENDENT_DROP_M,
    MIN_PAIR_DROP_M,
    RECORD_WINDOW_M,
    LivePredictor,
    fit_rate,
)
from predictor.tracks import ascent_weather_cube, clean, read_track

CHECKPOINTS_KM = (25.0, 20.0, 15.0, 10.0, 5.0)
TABLE_KM = tuple(1.0 + 2.5 * k for k in range(12))


@dataclass(frozen=True)
class Record:
    name: str
    t: np.ndarray
    z: np.ndarray
    law: np.ndarray
    """The law's seconds from the top to each fix's altitude."""
    law_ground: float
    ground: float
    touchdown_s: float


def load(paths: list[Path]) -> list[Record]:
    records = []
    for path in paths:
        flight = clean(read_track(path))
        descent = list(flight.descent)
        ground = flight.landing.alt_m if flight.landing is not None else descent[-1].alt_m
        track = LivePredictor(
            ascent_weather_cube(flight), PROFILES["superbit-test"], LevelGround(ground)
        ).law(descent[0])
        z_up, t_up = track.alt_m[::-1], track.t_s[::-1] - track.t_s[0]
        t = np.array([(f.time - descent[0].time).total_seconds() for f in descent])
        z = np.array([f.alt_m for f in descent])
        end = float(t[-1])
        if len(t) >= 3 and t[-2] > t[-3] and z[-3] > z[-2]:
            # As live_evaluation._touchdown_s: the last airborne fix carried down at its own rate.
            end = min(end, float(t[-2] + max(z[-2] - ground, 0.0) * (t[-2] - t[-3]) / (z[-3] - z[-2])))
        law = np.interp(z, z_up, t_up)
        records.append(Record(flight.name, t, z, law, float(np.interp(ground, z_up, t_up)), ground, end))
    return records


def height_fit(
    t: np.ndarray, z: np.ndarray, law: np.ndarray, window_m: float, decay_m: float | None
) -> tuple[float, float] | None:
    keep = z <= z[-1] + window_m
    if keep.sum() < 2:
        keep[-2:] = True
    t, z, law = t[keep], z[keep], law[keep]
    if np.ptp(z) < MIN_PAIR_DROP_M or np.ptp(law) <= 0.0:
        return None
    padded = np.concatenate(([z[0]], z, [z[-1]]))
    weights = np.maximum(0.5 * (padded[:-2] - padded[2:]), 0.0) + 1e-3
    if decay_m is not None:
        weights = weights * np.exp(-(z - z[-1]) / decay_m)
    count = min(float(z.size), float(np.ptp(z)) / INDEPENDENT_DROP_M + 2.0)
    fit = fit_rate(t, law, weights * count / weights.sum())
    return None if fit is None else (math.log(fit.factor), fit.log_sigma)


def count_fit(t: np.ndarray, z: np.ndarray, law: np.ndarray) -> tuple[float, float] | None:
    keep = z <= z[-1] + RECORD_WINDOW_M
    if keep.sum() < 2:
        keep[-2:] = True
    if np.ptp(z[keep]) < MIN_PAIR_DROP_M:
        return None
    fit = fit_rate(t[keep], law[keep])
    return None if fit is None else (math.log(fit.factor), fit.log_sigma)


FORMS = {
    "count, last 6 km (before)": None,
    "box 3 km": (3000.0, None),
    "box 6 km (now)": (RECORD_WINDOW_M, None),
    "whole record": (math.inf, None),
    "exp L 2 km": (math.inf, 2000.0),
    "exp L 4 km": (math.inf, 4000.0),
}


@dataclass(frozen=True)
class Sample:
    height_m: float
    record: tuple[float, float] | None
    remaining_log: float
    remaining_s: float
    law_s: float


def samples(r: Record, form: tuple[float, float | None] | None) -> list[Sample]:
    out = []
    for k in range(1, len(r.t) - 1):
        remaining_s, law_s = r.touchdown_s - r.t[k], r.law_ground - r.law[k]
        if remaining_s <= 0.0 or law_s <= 0.0:
            continue
        t, z, law = r.t[: k + 1], r.z[: k + 1], r.law[: k + 1]
        fit = count_fit(t, z, law) if form is None else height_fit(t, z, law, *form)
        out.append(Sample(r.z[k] - r.ground, fit, math.log(law_s / remaining_s), remaining_s, law_s))
    return out


def nearest(per_flight: list[list[Sample]], km: float, with_record: bool) -> list[Sample]:
    chosen = []
    for s in per_flight:
        pool = [x for x in s if x.record is not None] if with_record else s
        if pool:
            best = min(pool, key=lambda x: abs(x.height_m - 1000.0 * km))
            if abs(best.height_m - 1000.0 * km) < 3000.0:
                chosen.append(best)
    return chosen


def table(train: list[Record], form: tuple[float, float | None] | None) -> dict[float, tuple[float, ...]]:
    per_flight = [samples(r, form) for r in train]
    rows: dict[float, tuple[float, ...]] = {}
    for km in TABLE_KM:
        remaining = np.array([x.remaining_log for x in nearest(per_flight, km, False)])
        measured = nearest(per_flight, km, True)
        if remaining.size < 3 or len(measured) < 3:
            continue
        departure = np.array([x.record[0] - x.remaining_log for x in measured if x.record is not None])
        bias = float(np.median(departure))
        rows[km] = (bias, 1.4826 * float(np.median(np.abs(departure - bias))), float(remaining.mean()),
                    float(remaining.std(ddof=1)), math.sqrt(float(np.mean(departure**2))))  # fmt: skip
    return rows


def score(
    train: list[Record], scored: list[Record], form: tuple[float, float | None] | None, mode: str
) -> list[float]:
    rows = table(train, form)
    heights = sorted(rows)

    def at(km: float, i: int) -> float:
        return float(np.interp(km, heights, [rows[h][i] for h in heights]))

    errors: dict[float, tuple[list[float], list[float]]] = {km: ([], []) for km in CHECKPOINTS_KM}
    for r in scored:
        done: set[float] = set()
        for s in samples(r, form):
            for km in CHECKPOINTS_KM:
                if km in done or s.height_m > 1000.0 * km:
                    continue
                done.add(km)
                if s.height_m < 600.0 * km:
                    continue
                h = s.height_m / 1000.0
                bias, spread, mean, sigma, rms = (at(h, i) for i in range(5))
                if mode == "pooled":
                    prior_mean, prior_var, observed, noise = mean, sigma**2, -bias, spread**2
                elif mode == "law-centred":
                    prior_mean, prior_var, observed, noise = 0.0, mean**2 + sigma**2, -bias, spread**2
                else:
                    prior_mean, prior_var, observed, noise = 0.0, mean**2 + sigma**2, 0.0, rms**2
                estimate = prior_mean
                if s.record is not None:
                    observed += s.record[0]
                    noise += s.record[1] ** 2
                    estimate = (prior_mean / prior_var + observed / noise) / (1.0 / prior_var + 1.0 / noise)
                errors[km][0].append(abs(s.law_s / math.exp(estimate) - s.remaining_s))
                errors[km][1].append(abs(s.law_s - s.remaining_s))
    return [float(np.mean(a) / np.mean(b)) for a, b in errors.values()]


def main() -> None:
    superbit = Path("../shared/data/tracks/pyballoon_superbit")
    sets = {
        "2018": load(sorted(superbit.glob("18-*.csv"))),
        "2019": load(sorted(superbit.glob("19-*.csv"))),
        "EOSS": load(sorted(Path("tests/data/eoss").glob("*_descent.csv"))),
    }
    sets["SuperBIT"] = sets["2018"] + sets["2019"]
    splits = (("2018", "2019"), ("2019", "2018"), ("SuperBIT", "EOSS"), ("EOSS", "SuperBIT"))
    print("| λ from the record | with the prior | " + " | ".join(f"{a} → {b}" for a, b in splits) + " |")
    print("|---|---|" + "---|" * len(splits))
    for mode in ("pooled", "law-centred", "law, no bias"):
        for name, form in FORMS.items():
            cells = [" ".join(f"{v:.2f}" for v in score(sets[a], sets[b], form, mode)) for a, b in splits]
            print(f"| {name} | {mode} | " + " | ".join(cells) + " |", flush=True)


if __name__ == "__main__":
    main()

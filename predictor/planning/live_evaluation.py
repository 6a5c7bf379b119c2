"""Does live re-prediction help on real descents? Measured on flight tracks, leave-one-flight-out.

For each flight the weather is its own ascent's winds (``ascent_weather_cube``), which is what a
forecast is to a descent: right in general, wrong in detail (an hour or two and tens of km away). The
ground is a level plane at the flight's measured landing altitude (a DEM stands in for it in
operations). At each checkpoint (the first report at or below 25, 20, 15, 10, 5 and 2 km above the
ground) the landing is predicted from that report:

* ``plain``: restarted from the report, nothing learned;
* ``rate``: plus the measured descent-rate factor;
* ``wind L`` / ``rate + wind L``: plus the measured wind error, decaying below the capsule with L.

Everything fitted is chosen leave-one-flight-out: for each held-out flight and checkpoint the
configuration with the lowest mean error on the OTHER flights is applied to it. A correction is then
kept (in ``predictor.live.DEFAULT_CORRECTION``) only in the bands where the held-out error beat plain.
The same held-out errors fit the live ellipse (σ∥² = σ0² + h·d², σ⊥ = σ∥/q, d = remaining drift).
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from pathlib import Path

import numpy as np

from predictor.calibration.ascent_winds import ascent_weather_cube
from predictor.calibration.cleaning import clean
from predictor.calibration.tracks import Fix, read_track
from predictor.errors import PredictorError
from predictor.live import NO_CORRECTION, Band, LiveCorrection, LiveErrorModel, LivePredictor
from predictor.model import Term
from predictor.payload import PROFILES, Payload
from predictor.terrain import Terrain
from predictor.uncertainty import GEOD

CHECKPOINTS_KM = (25.0, 20.0, 15.0, 10.0, 5.0, 2.0)
LOWEST_SHARE = 0.6
"""A checkpoint's report must be at least this share of its height (a data gap skips the checkpoint)."""
DECAYS_M = (1000.0, 2000.0, 4000.0, 8000.0, 16000.0, math.inf)


def configurations() -> dict[str, LiveCorrection]:
    configs = {"plain": NO_CORRECTION, "rate": LiveCorrection.everywhere(True, None)}
    for decay in DECAYS_M:
        label = "const" if math.isinf(decay) else f"{decay / 1000:g} km"
        stored = 1e12 if math.isinf(decay) else decay
        configs[f"wind {label}"] = LiveCorrection.everywhere(False, stored)
        configs[f"rate + wind {label}"] = LiveCorrection.everywhere(True, stored)
    return configs


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
    """One checkpoint of one flight: the error of every configuration there."""

    flight: str
    checkpoint_km: float
    height_m: float
    errors_km: dict[str, float]
    along_km: dict[str, float]
    across_km: dict[str, float]
    remaining_drift_km: dict[str, float]


@dataclass
class Evaluation:
    flights: list[str]
    skipped: list[str]
    cases: list[Case]
    start_errors_km: dict[str, float]
    """Error of the plain prediction from the descent start (no live updates), per flight."""
    held_out: dict[float, dict[str, list[float]]] = field(default_factory=dict)
    """Per checkpoint: errors of plain, rate, and the held-out (LOO-chosen) configuration."""
    chosen: dict[float, dict[str, str]] = field(default_factory=dict)
    """Per checkpoint: which configuration each held-out flight got."""
    all_flights_choice: dict[float, str] = field(default_factory=dict)


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


def evaluate(
    paths: Sequence[str | Path], effects: Sequence[Term] = (), payload: Payload | None = None
) -> Evaluation:
    """Every checkpoint of every usable flight under every configuration; ``effects`` extend the model
    (a calibrated model's terms), ``payload`` replaces the 2018–2019 test payload the report was made with."""
    configs = configurations()
    payload = payload or PROFILES["superbit-test"]
    result = Evaluation(flights=[], skipped=[], cases=[], start_errors_km={})
    for path in paths:
        flight = clean(read_track(path))
        if not flight.usable or flight.landing is None or flight.descent_start is None:
            result.skipped.append(f"{flight.name}: {'; '.join(flight.exclusions) or 'no landing'}")
            continue
        try:
            cube = ascent_weather_cube(flight)
        except PredictorError as exc:
            result.skipped.append(f"{flight.name}: {exc}")
            continue
        landing = flight.landing
        ground = LevelGround(landing.alt_m)
        live = LivePredictor(cube, payload, ground, NO_CORRECTION, effects=effects)
        descent = list(flight.descent)
        checkpoints = {k: _checkpoint_fix(descent, landing.alt_m, k) for k in CHECKPOINTS_KM}
        start = live.predict_from(descent[0]).prediction.landing
        result.start_errors_km[flight.name] = _errors(start.lat, start.lon, descent[0], landing)[0]
        result.flights.append(flight.name)
        for fix in descent[:-1]:
            live.observe(fix)
            for km, at in checkpoints.items():
                if at is not fix:
                    continue
                case = Case(flight.name, km, fix.alt_m - landing.alt_m, {}, {}, {}, {})
                for name, config in configs.items():
                    p = live.predict_from(fix, config).prediction
                    d, along, across = _errors(p.landing.lat, p.landing.lon, fix, landing)
                    case.errors_km[name] = d
                    case.along_km[name] = along
                    case.across_km[name] = across
                    case.remaining_drift_km[name] = p.drift_km
                result.cases.append(case)
    _leave_one_out(result, list(configs))
    return result


def _leave_one_out(result: Evaluation, names: list[str]) -> None:
    for km in CHECKPOINTS_KM:
        cases = [c for c in result.cases if c.checkpoint_km == km]
        if len(cases) < 3:
            continue
        table = np.array([[c.errors_km[n] for n in names] for c in cases])
        held: list[float] = []
        chosen: dict[str, str] = {}
        for i, case in enumerate(cases):
            others = np.delete(table, i, axis=0)
            best = int(np.argmin(others.mean(axis=0)))
            held.append(float(table[i, best]))
            chosen[case.flight] = names[best]
        result.held_out[km] = {
            "plain": [c.errors_km["plain"] for c in cases],
            "rate": [c.errors_km["rate"] for c in cases],
            "held-out choice": held,
        }
        result.chosen[km] = chosen
        result.all_flights_choice[km] = names[int(np.argmin(table.mean(axis=0)))]


def helps(result: Evaluation, km: float) -> bool:
    rows = result.held_out.get(km)
    return bool(rows) and float(np.mean(rows["held-out choice"])) < float(np.mean(rows["plain"]))


def _shipped_name(result: Evaluation, case: Case) -> str:
    """The configuration this case gets from what ships: its held-out choice where that helps, else plain."""
    km = case.checkpoint_km
    return result.chosen.get(km, {}).get(case.flight, "plain") if helps(result, km) else "plain"


def fit_live_sigma(result: Evaluation, leave_out: str | None = None) -> LiveErrorModel:
    """RMS along- and cross-track error per checkpoint of what ships (optionally without one flight)."""
    heights, parallel, perpendicular = [], [], []
    for km in CHECKPOINTS_KM:
        cases = [c for c in result.cases if c.checkpoint_km == km and c.flight != leave_out]
        if len(cases) < 3:
            continue
        along = np.array([c.along_km[_shipped_name(result, c)] for c in cases])
        across = np.array([c.across_km[_shipped_name(result, c)] for c in cases])
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
            name = _shipped_name(result, c)
            m2.append((c.along_km[name] / s_par) ** 2 + (c.across_km[name] / s_perp) ** 2)
        m2a = np.array(m2)
        out[km] = (float(np.mean(m2a <= 1.0)), float(np.mean(m2a <= 4.0)), len(cases))
    return out


def shipped_correction(result: Evaluation) -> LiveCorrection:
    """The all-flights choice in each checkpoint's band where the held-out error beat plain.

    A checkpoint's band reaches half-way to its neighbours (10 km: 7.5–12.5 km above the ground).
    """
    kms = sorted(CHECKPOINTS_KM)
    bands = []
    configs = configurations()
    for i, km in enumerate(kms):
        if not helps(result, km):
            continue
        lower = -math.inf if i == 0 else 500.0 * (kms[i - 1] + km)
        upper = math.inf if i == len(kms) - 1 else 500.0 * (km + kms[i + 1])
        band = configs[result.all_flights_choice[km]].bands[0]
        bands.append(Band(lower, upper, band.use_rate, band.decay_m))
    return LiveCorrection(bands=tuple(bands))


def write_report(result: Evaluation, out_dir: str | Path, command: str) -> Path:
    """docs/planning/live-reprediction.md and its PNG plot."""
    import matplotlib

    matplotlib.use("Agg")
    import matplotlib.pyplot as plt

    out = Path(out_dir)
    out.mkdir(parents=True, exist_ok=True)
    kms = [km for km in CHECKPOINTS_KM if km in result.held_out]
    series = ("plain", "rate", "held-out choice")
    fig, ax = plt.subplots(figsize=(7, 4.2))
    for name, style in zip(series, ("o-", "s--", "^-"), strict=True):
        ax.plot(kms, [np.mean(result.held_out[k][name]) for k in kms], style, label=f"{name} (mean)")
    ax.axhline(float(np.mean(list(result.start_errors_km.values()))), color="grey", ls=":",
               label="from descent start, no updates (mean)")  # fmt: skip
    ax.set_xlabel("height above the ground at the report, km")
    ax.set_ylabel("landing error, km")
    ax.invert_xaxis()
    ax.grid(alpha=0.3)
    ax.legend(fontsize=8)
    ax.set_title(f"Live re-prediction on {len(result.flights)} SuperBIT test flights (ascent winds)")
    fig.tight_layout()
    png = out / "live-reprediction.png"
    fig.savefig(png, dpi=110)
    plt.close(fig)
    sigma = fit_live_sigma(result)
    coverage = held_out_coverage(result)
    shipped = shipped_correction(result)
    lines = [
        "# Live re-prediction on the real test flights",
        "",
        f"Generated by `{command}` (do not edit by hand; rerun it).",
        "",
        f"Flights: {len(result.flights)} used"
        + (f", skipped: {'; '.join(result.skipped)}" if result.skipped else "")
        + ". Weather: each flight's own ascent winds (`ascent_weather_cube`); payload `superbit-test`; "
        "ground: level at the measured landing altitude. Error = distance from the predicted to the "
        "measured landing. Checkpoint = the first report at or below that height above the ground "
        f"(skipped for a flight whose next report is below {LOWEST_SHARE:.0%} of it, a data gap).",
        "",
        "The held-out choice: for each flight, the configuration (plain, rate, wind L, rate + wind L with "
        f"L in {', '.join('∞' if math.isinf(d) else f'{d / 1000:g} km' for d in DECAYS_M)}) with the "
        "lowest mean error on the other flights at that checkpoint, applied to this flight.",
        "",
        "| height km | flights | plain median / mean km | rate median / mean km | held-out choice median / "
        "mean km | helps? | choice on all flights |",
        "|---|---|---|---|---|---|---|",
    ]
    for km in kms:
        rows = result.held_out[km]
        cells = [f"{np.median(rows[n]):.2f} / {np.mean(rows[n]):.2f}" for n in series]
        lines.append(
            f"| {km:g} | {len(rows['plain'])} | {' | '.join(cells)} | "
            f"{'yes' if helps(result, km) else 'no'} | "
            f"{result.all_flights_choice[km]} |"
        )
    shown = ("plain", "rate", "wind 2 km", "wind 8 km", "wind const", "rate + wind 2 km", "rate + wind const")
    lines += [
        "",
        "Mean error (km) of fixed configurations on all flights (not held out; shows the shape):",
        "",
        "| height km | " + " | ".join(shown) + " |",
        "|---|" + "---|" * len(shown),
    ]
    for km in kms:
        cases = [c for c in result.cases if c.checkpoint_km == km]
        lines.append(
            f"| {km:g} | "
            + " | ".join(f"{np.mean([c.errors_km[n] for c in cases]):.2f}" for n in shown)
            + " |"
        )
    starts = list(result.start_errors_km.values())
    lines += [
        "",
        f"From the descent start with no live update: median {np.median(starts):.2f} km, "
        f"mean {np.mean(starts):.2f} km over {len(starts)} flights.",
        "",
        "![landing error against height](live-reprediction.png)",
        "",
        "Live ellipse (`predictor.live.LIVE_ERROR_MODEL`): RMS along/across-track error of what ships, "
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
        "What ships (`predictor.live.DEFAULT_CORRECTION`, bands of height above the ground): "
        + (
            "; ".join(
                f"{'ground' if not math.isfinite(b.lower_m) else f'{b.lower_m / 1000:g} km'}–"
                f"{'top' if not math.isfinite(b.upper_m) else f'{b.upper_m / 1000:g} km'}: "
                f"rate {'on' if b.use_rate else 'off'}, wind "
                + ("off" if b.decay_m is None else f"L = {b.decay_m / 1000:g} km")
                for b in shipped.bands
            )
            or "nothing (plain re-prediction everywhere)"
        )
        + "; elsewhere a plain re-prediction from the report.",
        "",
        "Choices per flight (held-out):",
        "",
    ]
    for km in kms:
        counts: dict[str, int] = {}
        for name in result.chosen[km].values():
            counts[name] = counts.get(name, 0) + 1
        lines.append(f"* {km:g} km: " + ", ".join(f"{n} ×{c}" for n, c in sorted(counts.items())))
    md = out / "live-reprediction.md"
    md.write_text("\n".join(lines) + "\n", encoding="utf-8")
    return md

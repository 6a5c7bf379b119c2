"""``drs live bench``: how long ``drs live evaluate`` takes on 1 Hz records of 10,000+ fixes.

Why a resampled copy: a 1 Hz logger's descent is ~10,000 fixes, the Iridium trackers we have real
flights from report every 3 minutes. The bench therefore re-samples real flights to one fix per
second (linear in time between the logged fixes, pressure and ground speed dropped, the receivers
did not give them every second), writes them as canonical CSV, and times the whole evaluation on
them: reading, cleaning, the ascent-wind weather, the live predictors fed every fix, the
leave-one-flight-out choice and the report. The numbers it answers with are speed, not accuracy:
a straight line between 3-minute fixes has none of a real record's swing, and its touchdown and
burst are smeared over an interval.

It also times what a dense record costs one live update (issue #30: a 1 Hz record of 10,000 fixes
adds ≤ 5 ms): the first flight's descent as logged down to 5 km above its landing, and the same
stretch interpolated to ``RECORD_FIXES`` fixes, each fed to a live predictor, then the prediction
from that report timed.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Sequence
from datetime import timedelta
from pathlib import Path

import numpy as np

from predictor.calibration.live_evaluation import LevelGround, evaluate_live, write_live_report
from predictor.errors import PredictorError
from predictor.prediction import CalibratedModel, flown_model
from predictor.tracks import Fix, Flight, ascent_weather_cube, clean, read_track, write_canonical_csv

GROUND_S = 300.0
"""The logger keeps logging on the ground this long after the landing, as real ones do (cleaning
recognises a landing at 1 Hz by the altitude staying put)."""
RECORD_FIXES = 10_000
"""The dense record: a 1 Hz logger's descent of ~2.8 hours, or ~37 minutes logged at 4.5 Hz."""
REPORT_HEIGHT_M = 5000.0
"""The update is timed at the first report this far above the landing or lower: λ's 6 km window is
then full, and the self-checks' heights are all in the record."""
TIMED_CALLS = 21


def resampled(path: str | Path, cadence_s: float = 1.0) -> list[Fix]:
    """The cleaned flight of a track file, one fix every ``cadence_s`` seconds from launch to landing,
    then ``GROUND_S`` on the ground at the landing."""
    flight = clean(read_track(path))
    if len(flight.fixes) < 2:
        raise PredictorError(f"{path}: fewer than two fixes to re-sample")
    span_s = (flight.fixes[-1].time - flight.fixes[0].time).total_seconds()
    return _interpolated(flight.fixes, np.arange(0.0, span_s + GROUND_S, cadence_s))


def _interpolated(fixes: Sequence[Fix], at_s: np.ndarray) -> list[Fix]:
    """Fixes at ``at_s`` seconds from the first one, linear in time between ``fixes`` (held beyond them)."""
    start = fixes[0].time
    logged = np.array([(f.time - start).total_seconds() for f in fixes])
    lat, lon, alt = (np.interp(at_s, logged, [getattr(f, k) for f in fixes]) for k in ("lat", "lon", "alt_m"))
    return [
        Fix(start + timedelta(seconds=float(t)), float(a), float(b), float(c))
        for t, a, b, c in zip(at_s, lat, lon, alt, strict=True)
    ]


def _update_ms(model: CalibratedModel, flight: Flight, record: Sequence[Fix]) -> float:
    """Median milliseconds of one prediction from the record's last fix, the record fed before it."""
    assert flight.landing is not None
    live = model.live_predictor(ascent_weather_cube(flight), LevelGround(flight.landing.alt_m))
    for fix in record:
        live.observe(fix)
    timings = []
    for _ in range(TIMED_CALLS):
        started = time.perf_counter()
        live.predict_from(record[-1])
        timings.append(time.perf_counter() - started)
    return 1000.0 * float(np.median(timings))


def update_cost(path: str | Path, model: CalibratedModel) -> str:
    """What a record of ``RECORD_FIXES`` fixes adds to one live update, against the flight as logged:
    the same descent down to the first report ``REPORT_HEIGHT_M`` above the landing, each way."""
    flight = clean(read_track(path))
    if flight.landing is None or len(flight.descent) < 3:
        raise PredictorError(f"{path}: no landed descent to time a live update on")
    descent = list(flight.descent)
    ground_m = flight.landing.alt_m
    reached = next(
        (i for i, f in enumerate(descent) if f.alt_m - ground_m <= REPORT_HEIGHT_M), len(descent) - 1
    )
    logged = descent[: reached + 1]
    logged_ms = _update_ms(model, flight, logged)
    span_s = (logged[-1].time - logged[0].time).total_seconds()
    dense_ms = _update_ms(model, flight, _interpolated(logged, np.linspace(0.0, span_s, RECORD_FIXES)))
    return (
        f"one live update {(logged[-1].alt_m - ground_m) / 1000:.1f} km above the landing of "
        f"{Path(path).stem} (median of {TIMED_CALLS}): {dense_ms:.1f} ms with {RECORD_FIXES} fixes in "
        f"the record, {logged_ms:.1f} ms with the {len(logged)} it logged: the dense record adds "
        f"{dense_ms - logged_ms:.1f} ms   [goal ≤ 5 ms]"
    )


def bench(paths: Sequence[str | Path], model: CalibratedModel | None) -> str:
    """Re-sample every track to 1 Hz in a temporary directory, then time ``evaluate_live`` +
    ``write_live_report``; and ``update_cost`` on the first track, with ``model`` or the default payload.

    The report goes to the temporary directory too and is thrown away: its errors are those of
    straight lines drawn between 3-minute fixes (a touchdown moved to the first fix on the ground, a
    burst smeared over the interval after the peak), not of a real 1 Hz descent.
    """
    with tempfile.TemporaryDirectory(prefix="drs-live-bench-") as tmp:
        files = []
        for path in paths:
            target = Path(tmp) / f"{Path(path).stem}-1hz.csv"
            write_canonical_csv(resampled(path), target)
            files.append(target)
        fixes = sum(sum(1 for _ in f.open(encoding="utf-8")) - 1 for f in files)
        started, cpu = time.perf_counter(), time.process_time()
        result = evaluate_live(files, model=model)
        write_live_report(result, tmp, f"drs live bench <{len(files)} tracks re-sampled to 1 Hz>")
        wall, used = time.perf_counter() - started, time.process_time() - cpu
    flown = model if model is not None else flown_model(None, None, None, None)
    return (
        f"drs live evaluate on {len(files)} flights re-sampled to 1 Hz: {fixes} fixes in the files, "
        f"{result.fixes_used} descent fixes fed to the live predictors (every one), "
        f"{len(result.flights)} flights used: {wall:.1f} s wall, {used:.1f} s CPU   [goal ≤ 60 s for 100,000 fixes]\n"
        + update_cost(paths[0], flown)
    )

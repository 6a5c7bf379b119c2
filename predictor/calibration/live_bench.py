"""``drs live bench``: how long ``drs live evaluate`` takes on 1 Hz records of 10,000+ fixes.

Why a resampled copy: a 1 Hz logger's descent is ~10,000 fixes, the Iridium trackers we have real
flights from report every 3 minutes. The bench therefore re-samples real flights to one fix per
second (linear in time between the logged fixes, pressure and ground speed dropped, the receivers
did not give them every second), writes them as canonical CSV, and times the whole evaluation on
them: reading, cleaning, the ascent-wind weather, the live predictors fed every fix, the
leave-one-flight-out choice and the report. The numbers it answers with are speed, not accuracy:
a straight line between 3-minute fixes has none of a real record's swing, and its touchdown and
burst are smeared over an interval.
"""

from __future__ import annotations

import tempfile
import time
from collections.abc import Sequence
from datetime import timedelta
from pathlib import Path

import numpy as np

from predictor.calibration.live_evaluation import evaluate_live, write_live_report
from predictor.errors import PredictorError
from predictor.prediction import CalibratedModel
from predictor.tracks import Fix, clean, read_track, write_canonical_csv

GROUND_S = 300.0
"""The logger keeps logging on the ground this long after the landing, as real ones do (cleaning
recognises a landing at 1 Hz by the altitude staying put)."""


def resampled(path: str | Path, cadence_s: float = 1.0) -> list[Fix]:
    """The cleaned flight of a track file, one fix every ``cadence_s`` seconds from launch to landing,
    then ``GROUND_S`` on the ground at the landing."""
    flight = clean(read_track(path))
    if len(flight.fixes) < 2:
        raise PredictorError(f"{path}: fewer than two fixes to re-sample")
    start = flight.fixes[0].time
    logged = np.array([(f.time - start).total_seconds() for f in flight.fixes])
    at = np.arange(0.0, logged[-1] + GROUND_S, cadence_s)
    lat, lon, alt = (
        np.interp(at, logged, [getattr(f, k) for f in flight.fixes]) for k in ("lat", "lon", "alt_m")
    )
    return [
        Fix(start + timedelta(seconds=float(t)), float(a), float(b), float(c))
        for t, a, b, c in zip(at, lat, lon, alt, strict=True)
    ]


def bench(paths: Sequence[str | Path], model: CalibratedModel | None) -> str:
    """Re-sample every track to 1 Hz in a temporary directory, then time ``evaluate_live`` + ``write_live_report``.

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
    return (
        f"drs live evaluate on {len(files)} flights re-sampled to 1 Hz: {fixes} fixes in the files, "
        f"{result.fixes_used} descent fixes fed to the live predictors (every one), "
        f"{len(result.flights)} flights used: {wall:.1f} s wall, {used:.1f} s CPU   [goal ≤ 60 s for 100,000 fixes]"
    )

"""Does the live λ depend on the record's cadence? The table in docs/planning.md (issue #30, item 1).

Run from the repository root: ``.venv/bin/python docs/planning/rate_cadence.py`` (about 20 s).

The EOSS flights (15 s APRS, tests/data/eoss) thinned to one fix per 60 and 180 s, and the Spanish V4
logger (1 Hz, burst at 15.3 km) thinned to 10 and 60 s, each flown by a model without live settings
(the superbit-test payload's textbook law, ``DEFAULT_DISCREPANCY``, no prior of its own): at the first
fix at or below each checkpoint height, the remaining time the law predicts with the live λ against the
measured one, ÷ the same error with λ = 1 (the plain restart); and how far ln λ moved between the
thinned and the native record at the same checkpoints. The ground is each flight's landing, or its last
fix where the track ends in the air (4 EOSS flights at 1.6–1.7 km, V4 at 867 m).
"""

from __future__ import annotations

import math
from datetime import date
from pathlib import Path

import numpy as np

from predictor.calibration.live_evaluation import LevelGround
from predictor.descent import PROFILES
from predictor.prediction.live import DEFAULT_DISCREPANCY, NO_CORRECTION, LivePredictor
from predictor.tracks import ascent_weather_cube, clean, read_track

CHECKPOINTS_KM = (25.0, 20.0, 15.0, 10.0, 5.0)
SETS = {
    "EOSS": (sorted(Path("tests/data/eoss").glob("*_descent.csv")), None, (None, 60.0, 180.0)),
    "V4 (1 Hz)": (
        [Path("../shared/data/tracks/astra_meridiaz_V4_spain/V4_flight_1hz_DERIVED.csv")],
        date(2021, 6, 1),
        (None, 10.0, 60.0),
    ),
}


def main() -> None:
    for name, (paths, day, cadences) in SETS.items():
        flights = []
        for path in paths:
            flight = clean(read_track(path, day=day))
            descent = list(flight.descent)
            flights.append((flight.name, descent, ascent_weather_cube(flight), descent[-1].alt_m))
        logs: dict[tuple[str, float, float | None], float] = {}
        for cadence in cadences:
            errors: dict[float, tuple[list[float], list[float]]] = {km: ([], []) for km in CHECKPOINTS_KM}
            for flight_name, descent, cube, ground in flights:
                kept = [descent[0]]
                for fix in descent[1:]:
                    if cadence is None or (fix.time - kept[-1].time).total_seconds() >= cadence:
                        kept.append(fix)
                end_s = (descent[-1].time - descent[0].time).total_seconds()
                live = LivePredictor(
                    cube,
                    PROFILES["superbit-test"],
                    LevelGround(ground),
                    NO_CORRECTION,
                    discrepancy=DEFAULT_DISCREPANCY,
                )
                track = live.law(descent[0])
                z_up, t_up = track.alt_m[::-1], track.t_s[::-1]
                done: set[float] = set()
                for fix in kept[:-1]:
                    live.observe(fix)
                    height = fix.alt_m - ground
                    for km in CHECKPOINTS_KM:
                        if km in done or height > 1000.0 * km:
                            continue
                        done.add(km)
                        if height < 600.0 * km:
                            continue
                        rate = live.rate(fix)
                        law_s = float(np.interp(ground, z_up, t_up) - np.interp(fix.alt_m, z_up, t_up))
                        measured_s = end_s - (fix.time - descent[0].time).total_seconds()
                        errors[km][0].append(abs(law_s / rate.factor - measured_s))
                        errors[km][1].append(abs(law_s - measured_s))
                        logs[(flight_name, km, cadence)] = math.log(rate.factor)
            cells = [
                f"{km:g} km {np.mean(a):.0f} s ÷ {np.mean(b):.0f} s = {np.mean(a) / np.mean(b):.2f}"
                for km, (a, b) in errors.items()
                if a
            ]
            print(f"| {name} | {'native' if cadence is None else f'{cadence:g} s'} | {'; '.join(cells)} |")
        for cadence in cadences[1:]:
            moved = [
                abs(v - logs[(f, km, None)])
                for (f, km, c), v in logs.items()
                if c == cadence and (f, km, None) in logs
            ]
            print(
                f"| {name} | {cadence:g} s vs native | mean Δ ln λ (absolute) {np.mean(moved):.3f}, max {np.max(moved):.3f} ({len(moved)} checkpoints) |"
            )


if __name__ == "__main__":
    main()

"""How the error of the ascent's winds at the capsule's height predicts the error below it, on real
flights (issue #30 item 4): docs/planning/wind-errors.md.

Run from the repository root: ``.venv/bin/python docs/planning/wind_errors.py`` (about 20 s).

For each usable flight (the 30 SuperBIT flights, the EOSS archive flights in tests/data/eoss; the EOSS
flights issue #30 keeps out of everything are not there), the "forecast" is its own ascent's winds
(``ascent_weather_cube``, what every live evaluation flies) and the truth its descent: each leg of the
descent (consecutive fixes, joined until they fall at least 200 m) gives the measured mean velocity,
and the wind error is that minus the ascent's mean wind over the same altitudes (east, north, m/s).
Each leg is placed by its middle altitude, the horizontal distance from there to where the ascent
passed that altitude, and the hours since it did (the ascent's nearest measured end beyond its range:
the cube repeats its nearest layer there).

Measured: (1) the correlation of the error at one height with the error Δz below it, in the same
flight (east and north pooled), by Δz, for the upper leg above and below 12.5 km, and for the lower
leg nearer and farther than the median distance from the ascent: what carrying the descent's own
drift down (live ``wind L``) can gain; (2) how the size of the error grows with the distance from the
ascent and with the time since it: what the live ellipse grows with. Intervals: 2000 bootstrap draws
of the flights (a flight's legs together).
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import numpy as np

from predictor.calibration.live_evaluation import _usable
from predictor.prediction import GEOD
from predictor.tracks import ascent_weather_cube, clean, read_track

SUPERBIT = sorted(Path("../shared/data/tracks/pyballoon_superbit").glob("*-*.csv"))
EOSS = sorted(Path("tests/data/eoss").glob("*_descent.csv"))
LEG_DROP_M = 200.0
DZ_BINS_KM = ((0.5, 1.5), (1.5, 3.0), (3.0, 6.0), (6.0, 12.0), (12.0, 24.0))
DISTANCE_BINS_KM = ((0.0, 10.0), (10.0, 25.0), (25.0, 50.0), (50.0, 100.0), (100.0, 1000.0))
SPLIT_M = 12500.0
DRAWS = 2000


@dataclass(frozen=True)
class Leg:
    flight: str
    alt_m: float
    error: tuple[float, float]
    distance_km: float
    hours: float


def legs(path: Path) -> list[Leg]:
    """The wind error of each descent leg of one flight, placed against its ascent."""
    usable = _usable([path], None, [], None, None, None)
    if not usable:
        return []
    flight = clean(read_track(path))
    cube = ascent_weather_cube(flight)
    z, u, v = cube.z_m[0, :, 0, 0], cube.u[0, :, 0, 0], cube.v[0, :, 0, 0]
    ascent = [f for f in flight.ascent]
    rising = [ascent[0]]
    for fix in ascent[1:]:
        if fix.alt_m > rising[-1].alt_m:
            rising.append(fix)
    a_alt = np.array([f.alt_m for f in rising])
    a_lat, a_lon = np.array([f.lat for f in rising]), np.array([f.lon for f in rising])
    a_t = np.array([(f.time - rising[0].time).total_seconds() for f in rising])
    out = []
    descent = list(usable[0].descent)
    start = descent[0]
    for fix in descent[1:]:
        if start.alt_m - fix.alt_m < LEG_DROP_M:
            continue
        seconds = (fix.time - start.time).total_seconds()
        if seconds > 0.0:
            azimuth, _, metres = GEOD.inv(start.lon, start.lat, fix.lon, fix.lat)
            speed = metres / seconds
            heights = np.linspace(fix.alt_m, start.alt_m, 12)
            east = speed * math.sin(math.radians(azimuth)) - float(np.mean(np.interp(heights, z, u)))
            north = speed * math.cos(math.radians(azimuth)) - float(np.mean(np.interp(heights, z, v)))
            middle = 0.5 * (start.alt_m + fix.alt_m)
            mid_lat, mid_lon = 0.5 * (start.lat + fix.lat), 0.5 * (start.lon + fix.lon)
            _, _, apart = GEOD.inv(
                mid_lon, mid_lat, np.interp(middle, a_alt, a_lon), np.interp(middle, a_alt, a_lat)
            )
            passed = rising[0].time.timestamp() + float(np.interp(middle, a_alt, a_t))
            hours = (0.5 * (start.time.timestamp() + fix.time.timestamp()) - passed) / 3600.0
            out.append(Leg(usable[0].name, middle, (east, north), apart / 1000.0, hours))
        start = fix
    return out


def bootstrap(
    flights: list[str], statistic: Callable[[list[str]], float], seed: int = 0
) -> tuple[float, float, float]:
    """The statistic on all flights and its 95 % interval over flight resamples (nan: too few)."""
    rng = np.random.default_rng(seed)
    whole = statistic(flights)
    draws = [statistic(list(rng.choice(flights, size=len(flights)))) for _ in range(DRAWS)]
    draws = [d for d in draws if np.isfinite(d)]
    if not draws:
        return whole, math.nan, math.nan
    low, high = np.quantile(draws, (0.025, 0.975))
    return whole, float(low), float(high)


def pairs(legs_: list[Leg], dz: tuple[float, float], keep: Callable[[Leg, Leg], bool]) -> np.ndarray:
    """(upper, lower) error components of every pair of one flight's legs Δz apart (east and north
    pooled), shape (2, n)."""
    found = [
        (x, y)
        for i, a in enumerate(legs_)
        for b in legs_[i + 1 :]
        if dz[0] * 1000 <= a.alt_m - b.alt_m < dz[1] * 1000 and keep(a, b)
        for x, y in zip(a.error, b.error, strict=True)
    ]
    return np.array(found).reshape(-1, 2).T


def pair_correlation(by_flight: dict[str, np.ndarray], flights: list[str]) -> float:
    """Pearson correlation of the error at a leg with the error of a leg Δz below it, over every such
    pair of every flight listed (a flight drawn twice counts twice)."""
    both = np.concatenate([by_flight[name] for name in flights], axis=1)
    return float(np.corrcoef(both[0], both[1])[0, 1]) if both.shape[1] >= 10 else math.nan


def size_correlation(by_flight: dict[str, list[Leg]], flights: list[str], x: str) -> float:
    """Pearson correlation of the error's size (m/s) with the leg's distance from the ascent or hours
    since it, over the legs of the flights listed."""
    legs_ = [leg for name in flights for leg in by_flight[name]]
    size = [math.hypot(*leg.error) for leg in legs_]
    other = [getattr(leg, x) for leg in legs_]
    return float(np.corrcoef(size, other)[0, 1]) if len(legs_) > 10 else math.nan


def fmt(value: tuple[float, float, float], digits: int = 2) -> str:
    whole, low, high = value
    return f"{whole:.{digits}f} ({low:.{digits}f}–{high:.{digits}f})" if math.isfinite(whole) else "–"


def section(label: str, paths: list[Path]) -> list[str]:
    by_flight = {}
    for path in paths:
        found = legs(path)
        if found:
            by_flight[found[0].flight] = found
    flights = sorted(by_flight)
    count = sum(len(v) for v in by_flight.values())
    distances = [leg.distance_km for v in by_flight.values() for leg in v]
    median = float(np.median(distances))
    lines = [
        f"## {label}: {len(flights)} flights, {count} descent legs",
        "",
        f"Median leg distance from where the ascent passed its altitude {median:.0f} km, median time "
        f"since {np.median([leg.hours for v in by_flight.values() for leg in v]):.1f} h.",
        "",
        "Correlation of the wind error at one height with the error Δz below it (same flight; 95 % interval):",
        "",
        "| Δz km | all | upper leg above 12.5 km | upper leg below 12.5 km | lower leg nearer the ascent "
        f"than {median:.0f} km | farther |",
        "|---|---|---|---|---|---|",
    ]
    keeps = (
        lambda a, b: True,
        lambda a, b: a.alt_m >= SPLIT_M,
        lambda a, b: a.alt_m < SPLIT_M,
        lambda a, b: b.distance_km < median,
        lambda a, b: b.distance_km >= median,
    )
    for dz in DZ_BINS_KM:
        cells = []
        for keep in keeps:
            found = {name: pairs(by_flight[name], dz, keep) for name in flights}
            cells.append(fmt(bootstrap(flights, lambda f, found=found: pair_correlation(found, f))))
        lines.append(f"| {dz[0]:g}–{dz[1]:g} | {' | '.join(cells)} |")
    lines += [
        "",
        "Size of the wind error against the distance from the ascent and the time since it (Pearson "
        "correlation of |error| with each, all legs; 95 % interval): distance "
        + fmt(bootstrap(flights, lambda f: size_correlation(by_flight, f, "distance_km")))
        + ", time "
        + fmt(bootstrap(flights, lambda f: size_correlation(by_flight, f, "hours")))
        + ".",
        "",
        "| distance from the ascent km | legs | RMS error m/s | mean time since the ascent h |",
        "|---|---|---|---|",
    ]
    for low, high in DISTANCE_BINS_KM:
        chosen = [leg for v in by_flight.values() for leg in v if low <= leg.distance_km < high]
        if chosen:
            rms = math.sqrt(float(np.mean([leg.error[0] ** 2 + leg.error[1] ** 2 for leg in chosen])))
            hours = float(np.mean([leg.hours for leg in chosen]))
            lines.append(f"| {low:g}–{high:g} | {len(chosen)} | {rms:.1f} | {hours:.1f} |")
    return [*lines, ""]


def report(superbit: list[Path], eoss: list[Path]) -> str:
    """docs/planning/wind-errors.md's text (a test checks that the committed report is this)."""
    lines = [
        "# The ascent's wind error at the capsule's height, and below it (issue #30 item 4)",
        "",
        "Generated by `.venv/bin/python docs/planning/wind_errors.py` (do not edit by hand; rerun it). "
        "What is measured and how: the script's docstring. Wind error = the descent's measured mean "
        "velocity over a leg (≥ 200 m of fall) minus the ascent's mean wind over the same altitudes.",
        "",
        *section("SuperBIT", superbit),
        *section("EOSS (the archive flights in tests/data/eoss; only the last minutes of each ascent)", eoss),
    ]
    return "\n".join(lines)


def main() -> None:
    out = Path("docs/planning/wind-errors.md")
    out.write_text(report(SUPERBIT, EOSS), encoding="utf-8")
    print(out.read_text(encoding="utf-8"))


if __name__ == "__main__":
    main()

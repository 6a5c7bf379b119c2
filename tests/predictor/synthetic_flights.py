"""Synthetic flights for the tests: a known truth, flown and then logged the way real trackers log it.

The calibration loop must be shown to find an effect that is really there and to leave alone one
that is not. Real flights cannot show that (nobody knows their truth), so this module builds
flights whose truth is known: a balloon that climbs with the weather's wind, bursts, and descends
through the predictor's own model chain with extra effects switched on (terms the predictor under
test is not told about). The result is then sampled like a tracker: every ``cadence_s`` seconds
(2–5 min for the RockBLOCK units, 1 s for modern loggers) with a random phase, so that burst and
touchdown fall between fixes, GNSS noise, on-board pressure from the weather, and ground fixes
before launch and after landing. It comes out as a ``Track``, so it goes through the same cleaning
as a real file.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass
from datetime import UTC, datetime

import numpy as np

from predictor.descent import Payload, Release, Term
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError
from predictor.prediction import GEOD, FlightSetup, predict
from predictor.tracks.reading import Fix, Track

ASCENT_STEP_S = 2.0
VERTICAL_NOISE_FACTOR = 1.5
"""GNSS altitude is about 1.5 times noisier than horizontal position."""


@dataclass(frozen=True)
class TruePath:
    """The dense true path (ascent then descent): epoch seconds, degrees, metres."""

    t: np.ndarray
    lat: np.ndarray
    lon: np.ndarray
    alt_m: np.ndarray


@dataclass(frozen=True)
class SyntheticFlight:
    track: Track
    """What a tracker would have logged."""
    truth: TruePath
    launch: Fix
    burst: Fix
    landing: Fix
    effects: tuple[Term, ...]
    """The effects switched on in the true descent (beyond the payload's drag law and the wind)."""


def synthetic_flight(
    cube: WeatherCube,
    *,
    launch_time: datetime,
    lat: float,
    lon: float,
    payload: Payload,
    effects: Sequence[Term] = (),
    terrain: Terrain | None = None,
    burst_alt_m: float = 30_000.0,
    ascent_rate_ms: float = 5.0,
    cadence_s: float = 180.0,
    noise_m: float = 3.0,
    ground_fixes: int = 5,
    with_pressure: bool = True,
    seed: int = 0,
    name: str = "synthetic",
) -> SyntheticFlight:
    if launch_time.tzinfo is None:
        raise PredictorError("synthetic flight launch_time must be timezone-aware (UTC)")
    terrain = terrain or Terrain.sea_level()
    launch_alt = float(terrain.elevation(lat, lon))
    if not cadence_s > 0 or not noise_m >= 0 or not ascent_rate_ms > 0 or ground_fixes < 0:
        raise PredictorError(
            "synthetic flight needs cadence_s > 0, noise_m >= 0, ascent_rate_ms > 0, ground_fixes >= 0"
        )
    if not burst_alt_m > launch_alt + 1000:
        raise PredictorError(
            f"burst altitude {burst_alt_m} m must be at least 1000 m above the launch ({launch_alt:.0f} m)"
        )
    rng = np.random.default_rng(seed)
    t0 = launch_time.astimezone(UTC).timestamp()
    ascent = _ascend(cube, t0, lat, lon, launch_alt, burst_alt_m, ascent_rate_ms)
    burst_time = datetime.fromtimestamp(float(ascent.t[-1]), UTC)
    burst = Release(burst_time, float(ascent.lat[-1]), float(ascent.lon[-1]), burst_alt_m)
    descent = predict(cube, burst, FlightSetup(payload, tuple(effects), terrain=terrain))
    track = descent.track
    truth = TruePath(
        t=np.concatenate((ascent.t, ascent.t[-1] + track.t_s[1:])),
        lat=np.concatenate((ascent.lat, track.lat[1:])),
        lon=np.concatenate((ascent.lon, _continuous(float(ascent.lon[-1]), track.lon[1:]))),
        alt_m=np.concatenate((ascent.alt_m, track.alt_m[1:])),
    )
    first = t0 - ground_fixes * cadence_s + rng.uniform(0.0, cadence_s)
    last = truth.t[-1] + ground_fixes * cadence_s
    times = np.arange(first, last, cadence_s)
    fixes = _sample(cube, truth, times, rng, noise_m, with_pressure)
    source = f"synthetic flight in {cube.source}; effects: {', '.join(e.name for e in effects) or 'none'}"

    def true_fix(i: int) -> Fix:
        return Fix(
            time=datetime.fromtimestamp(float(truth.t[i]), UTC),
            lat=float(truth.lat[i]), lon=float(_wrapped(truth.lon[i])), alt_m=float(truth.alt_m[i]),
        )  # fmt: skip

    return SyntheticFlight(
        track=Track(name=name, source=source, format="synthetic", fixes=tuple(fixes)),
        truth=truth,
        launch=true_fix(0),
        burst=true_fix(len(ascent.t) - 1),
        landing=true_fix(len(truth.t) - 1),
        effects=tuple(effects),
    )


def _ascend(
    cube: WeatherCube, t0: float, lat: float, lon: float, z0: float, z_top: float, rate: float
) -> TruePath:
    """The balloon moves with the wind (no inertia), midpoint rule in time, 2 s steps."""
    n = int(math.ceil((z_top - z0) / (rate * ASCENT_STEP_S)))
    t = t0 + ASCENT_STEP_S * np.arange(n + 1)
    alt = np.minimum(z0 + rate * ASCENT_STEP_S * np.arange(n + 1), z_top)
    lats = np.empty(n + 1)
    lons = np.empty(n + 1)
    lats[0], lons[0] = lat, lon
    for k in range(n):
        u, v = _wind_at(cube, t[k] + 0.5 * ASCENT_STEP_S, lats[k], lons[k], 0.5 * (alt[k] + alt[k + 1]))
        dt = t[k + 1] - t[k]
        lo, la, _ = GEOD.fwd(lons[k], lats[k], math.degrees(math.atan2(u, v)), math.hypot(u, v) * dt)
        lats[k + 1] = la
        lons[k + 1] = _continuous(lons[k], np.array([lo]))[0]
    return TruePath(t=t, lat=lats, lon=lons, alt_m=alt)


def _sample(
    cube: WeatherCube, truth: TruePath, times: np.ndarray, rng: np.random.Generator, noise_m: float,
    with_pressure: bool,
) -> list[Fix]:  # fmt: skip
    lat = np.interp(times, truth.t, truth.lat)
    lon = np.interp(times, truth.t, truth.lon)
    alt = np.interp(times, truth.t, truth.alt_m)
    east, north = rng.normal(0.0, noise_m, (2, len(times))) if noise_m else np.zeros((2, len(times)))
    up = rng.normal(0.0, VERTICAL_NOISE_FACTOR * noise_m, len(times)) if noise_m else np.zeros(len(times))
    noisy_lon, noisy_lat, _ = GEOD.fwd(lon, lat, np.degrees(np.arctan2(east, north)), np.hypot(east, north))
    speed = _ground_speed(truth, times)
    fixes = []
    for i, when in enumerate(times):
        pressure = _pressure_at(cube, when, lat[i], lon[i], alt[i]) if with_pressure else None
        fixes.append(
            Fix(
                time=datetime.fromtimestamp(float(when), UTC),
                lat=float(noisy_lat[i]),
                lon=float(_wrapped(noisy_lon[i])),
                alt_m=round(float(alt[i] + up[i]), 1),
                pressure_pa=pressure,
                speed_ms=round(float(speed[i]), 1),
                line=i + 1,
            )  # fmt: skip
        )
    return fixes


def _ground_speed(truth: TruePath, times: np.ndarray) -> np.ndarray:
    """The receiver's ground speed: the true path's speed in the segment around each time (0 outside it)."""
    _, _, dist = GEOD.inv(truth.lon[:-1], truth.lat[:-1], truth.lon[1:], truth.lat[1:])
    seg_speed = np.asarray(dist) / np.diff(truth.t)
    k = np.searchsorted(truth.t, times, side="right") - 1
    inside = (k >= 0) & (k < len(seg_speed))
    return np.where(inside, seg_speed[np.clip(k, 0, len(seg_speed) - 1)], 0.0)


def _weights(axis: np.ndarray, x: float) -> list[tuple[int, float]]:
    """Linear interpolation weights along one cube axis, held at its ends."""
    if len(axis) == 1 or x <= axis[0]:
        return [(0, 1.0)]
    if x >= axis[-1]:
        return [(len(axis) - 1, 1.0)]
    i = int(np.searchsorted(axis, x, side="right")) - 1
    w = (x - axis[i]) / (axis[i + 1] - axis[i])
    return [(i, 1.0 - w), (i + 1, w)]


def _corners(cube: WeatherCube, t: float, lat: float, lon: float) -> list[tuple[int, int, int, float]]:
    """The (time, lat, lon) indices around a point and each one's weight, shared by every field read
    there. Weighing them again for each field (the longitude's inside the time and latitude loops) was
    a quarter of a flight's generation."""
    times = cube.times.astype("datetime64[s]").astype(np.float64)
    lat_weights = _weights(cube.lats, lat)
    lon_weights = _weights(cube.lons, float(cube.lon_in_cube(lon)))
    return [
        (ti, yi, xi, wt * wy * wx)
        for ti, wt in _weights(times, t)
        for yi, wy in lat_weights
        for xi, wx in lon_weights
    ]


def _column(field: np.ndarray, corners: list[tuple[int, int, int, float]]) -> np.ndarray:
    out = np.zeros(field.shape[1])
    for ti, yi, xi, weight in corners:
        out += weight * field[ti, :, yi, xi]
    return out


def _wind_at(cube: WeatherCube, t: float, lat: float, lon: float, z: float) -> tuple[float, float]:
    corners = _corners(cube, t, lat, lon)
    z_col = _column(cube.z_m, corners)
    u = np.interp(z, z_col, _column(cube.u, corners))
    v = np.interp(z, z_col, _column(cube.v, corners))
    return float(u), float(v)


def _pressure_at(cube: WeatherCube, t: float, lat: float, lon: float, z: float) -> float:
    z_col = _column(cube.z_m, _corners(cube, t, lat, lon))
    return float(np.exp(np.interp(z, z_col, np.log(cube.levels_hpa * 100.0))))


def _continuous(previous: float, lons: np.ndarray) -> np.ndarray:
    """Longitudes unwrapped so that they continue from ``previous`` without a 360° jump."""
    return np.degrees(np.unwrap(np.radians(np.concatenate(([previous], lons)))))[1:]


def _wrapped(lon: float) -> float:
    return (float(lon) + 180.0) % 360.0 - 180.0

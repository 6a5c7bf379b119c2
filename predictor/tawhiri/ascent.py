"""The ascent of Tawhiri's standard profile: a constant rate up to the burst, carried by the wind.

Why it exists: chase software (chasemapper, the SondeHub predictor) asks a Tawhiri-API server for a
whole flight from the ground, while the project predicts descents only. Tawhiri's standard profile
rises at the constant rate the caller gives, drifting with the wind; this is the same idea, sampled
with the descent stepper's own weather sampler and midpoint steps of at most a minute (as the drift
at float), so the burst point it hands to the descent comes from the same weather.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta

import numpy as np

from predictor.descent import (
    DEFAULT_TIME_TOLERANCE_S,
    STATUS_OK,
    degrees_per_metre,
    packed,
    sample_weather,
    wrap_lon,
)
from predictor.environment import WeatherCube
from predictor.errors import PredictorError
from predictor.prediction import Point, coverage_error

ASCENT_STEP_S = 60.0


@dataclass(frozen=True)
class Ascent:
    """A stage's path: from launch to burst (the burst last), or Tawhiri's descent to the ground."""

    t_s: np.ndarray
    """Epoch seconds."""
    lat: np.ndarray
    lon: np.ndarray
    """Degrees east in [-180, 180)."""
    alt_m: np.ndarray

    def point(self, index: int) -> Point:
        moment = datetime(1970, 1, 1, tzinfo=UTC) + timedelta(seconds=float(self.t_s[index]))
        return Point(moment, float(self.lat[index]), float(self.lon[index]), float(self.alt_m[index]))

    @property
    def burst(self) -> Point:
        return self.point(-1)


Wind = Callable[[float, float, float, float], tuple[float, float]]


def wind_sampler(cube: WeatherCube, time_tolerance_s: float, stage: str) -> Wind:
    """(u, v) in m/s at (epoch s, lat, lon, alt) from the descent stepper's own sampler; leaving the
    cube is a PredictorError naming the stage."""
    w = packed(cube)
    sample = np.zeros(3)
    hint = np.zeros(1, dtype=np.int64)
    no_memo, scratch = np.empty((0, 0, 0)), np.empty((1, 1, 1, 4))

    def wind(t: float, la: float, lo: float, z: float) -> tuple[float, float]:
        code = sample_weather(w.t_s, w.lats, w.lons, w.columns, time_tolerance_s, t, la, lo, z, sample, hint,
                              no_memo, scratch)  # fmt: skip
        if code != STATUS_OK:
            raise coverage_error(cube, code, stage, t, la, lo, z)
        return float(sample[0]), float(sample[1])

    return wind


def ascend(
    cube: WeatherCube,
    time: datetime,
    lat: float,
    lon: float,
    alt_m: float,
    rate_ms: float,
    burst_alt_m: float,
    time_tolerance_s: float = DEFAULT_TIME_TOLERANCE_S,
) -> Ascent:
    """Rise from (``lat``, ``lon``, ``alt_m``) at ``time`` at ``rate_ms`` to ``burst_alt_m``, drifting with the wind."""
    if time.tzinfo is None:
        raise PredictorError("the launch time must be timezone-aware (UTC)")
    if not (math.isfinite(rate_ms) and rate_ms > 0.0):
        raise PredictorError(f"the ascent rate must be a positive number of m/s, got {rate_ms!r}")
    if not (math.isfinite(burst_alt_m) and math.isfinite(alt_m) and burst_alt_m > alt_m):
        raise PredictorError(
            f"the burst altitude {burst_alt_m!r} m must be above the launch altitude {alt_m!r} m"
        )
    wind = wind_sampler(cube, time_tolerance_s, "ascent")
    duration_s = (burst_alt_m - alt_m) / rate_ms
    steps = max(1, math.ceil(duration_s / ASCENT_STEP_S))
    h = duration_s / steps
    t, la, lo, z = time.timestamp(), float(lat), float(lon), float(alt_m)
    path = [(t, la, lo, z)]
    for k in range(1, steps + 1):
        la, lo = midpoint_step(wind, t, la, lo, z, h, rate_ms)
        t, z = t + h, alt_m + k * h * rate_ms
        path.append((t, la, lo, z))
    stage = as_stage(path)
    stage.alt_m[-1] = burst_alt_m
    return stage


def drift(
    cube: WeatherCube,
    time: datetime,
    lat: float,
    lon: float,
    alt_m: float,
    until: datetime,
    time_tolerance_s: float = DEFAULT_TIME_TOLERANCE_S,
) -> Ascent:
    """Tawhiri's float stage: carried by the wind at ``alt_m`` from ``time`` until ``until`` (the last
    step shortened to end there); just the start when ``until`` is not after it."""
    wind = wind_sampler(cube, time_tolerance_s, "float")
    t, end, la, lo = time.timestamp(), until.timestamp(), float(lat), float(lon)
    path = [(t, la, lo, float(alt_m))]
    while t < end:
        h = min(ASCENT_STEP_S, end - t)
        la, lo = midpoint_step(wind, t, la, lo, alt_m, h, 0.0)
        t += h
        path.append((t, la, lo, float(alt_m)))
    return as_stage(path)


def midpoint_step(
    wind: Wind, t: float, la: float, lo: float, z: float, h: float, rate_ms: float
) -> tuple[float, float]:
    """Where the wind carries (``la``, ``lo``) in ``h`` seconds (negative: back in time) while the
    altitude changes at ``rate_ms``: one midpoint step."""
    u, v = wind(t, la, lo, z)
    dlat, dlon = degrees_per_metre(la, z)
    la_mid, lo_mid, z_mid = la + 0.5 * h * v * dlat, lo + 0.5 * h * u * dlon, z + 0.5 * h * rate_ms
    u, v = wind(t + 0.5 * h, la_mid, lo_mid, z_mid)
    dlat, dlon = degrees_per_metre(la_mid, z_mid)
    return la + h * v * dlat, lo + h * u * dlon


def as_stage(path: list[tuple[float, float, float, float]]) -> Ascent:
    """(epoch s, lat, lon, alt) rows as a stage, longitudes wrapped to [-180, 180)."""
    t_s, lats, lons, alts = (np.array(column) for column in zip(*path, strict=True))
    return Ascent(t_s=t_s, lat=lats, lon=np.asarray(wrap_lon(lons)), alt_m=alts)

"""Synthetic worlds for the calibration loop: flights flown with a hidden effect, then logged like trackers.

Each flight gets its own weather (a jet-stream profile blowing from a different direction, changing
over the hours), so that effects tied to the wind (scale, rotation, band, lag, time offset) and
effects tied to geography (a constant eastward bias) look different from each other. The calibration
is given the same weather the truth was flown in: the hidden effect is the only thing it lacks.
"""

from __future__ import annotations

from collections.abc import Callable, Sequence
from datetime import UTC, datetime, timedelta

import numpy as np
import pytest

from predictor.calibration.residuals import FlightCase, flight_case
from predictor.descent.model import Term, WindOffset
from predictor.descent.payload import PROFILES
from predictor.environment.cube import WeatherCube
from predictor.tracks.cleaning import clean
from predictor.tracks.standard_atmosphere import R_DRY_AIR, pressure_temperature
from tests.predictor.synthetic_flights import synthetic_flight

LAUNCH = datetime(2024, 5, 1, 8, 0, 0, tzinfo=UTC)
PAYLOAD = PROFILES["superbit-test"]
DIRECTIONS_DEG = (20.0, 95.0, 160.0, 230.0, 300.0, 55.0)


def jet_cube(toward_deg: float, density_change: float = 0.0) -> WeatherCube:
    """Wind toward ``toward_deg``: 8 m/s plus a 25 m/s jet at 11 km, veering 30° over 20 km, and 40 %
    stronger 6 h after launch than 6 h before (so a time offset changes what a descent meets). The
    air is ``density_change`` denser 6 h after launch than 6 h before from 20 km up and as much less
    dense at the ground (relative, linear in between; 0: constant in time), so that a time offset can
    also change the descent rate, and not by one factor at every altitude (the shape record takes that
    for the flight's own λ)."""
    z = np.arange(-500.0, 40_001.0, 500.0)
    p, t = pressure_temperature(z)
    start = LAUNCH.replace(tzinfo=None)
    times = np.array([start - timedelta(hours=6), start + timedelta(hours=6)], dtype="datetime64[s]")
    speed = 8.0 + 25.0 * np.exp(-(((z - 11_000.0) / 3000.0) ** 2))
    heading = np.radians(toward_deg + 30.0 * np.clip(z, 0.0, 20_000.0) / 20_000.0)
    shape = (2, len(z), 2, 2)

    def spread(profile: np.ndarray, growth: float | np.ndarray = 0.0) -> np.ndarray:
        by_level = np.broadcast_to(np.asarray(growth, dtype=float), z.shape)
        scale = np.stack([1.0 - by_level, 1.0 + by_level])[:, :, None, None]
        return np.broadcast_to(profile[None, :, None, None], shape) * scale

    return WeatherCube(
        times=times, lead_h=np.array([0.0, 12.0]), levels_hpa=p / 100.0, lats=np.array([42.0, 50.0]),
        lons=np.array([0.0, 12.0]), z_m=spread(z), u=spread(speed * np.sin(heading), 0.2),
        v=spread(speed * np.cos(heading), 0.2), temperature_k=spread(t),
        density=spread(p / (R_DRY_AIR * t), 0.5 * density_change * np.clip((z - 10_000.0) / 10_000.0, -1.0, 1.0)),
        source=f"synthetic jet toward {toward_deg:g}°",
    )  # fmt: skip


def make_cases(
    effects: Sequence[Term], n: int = 5, cadence_s: float = 180.0, noise_m: float = 3.0, seed: int = 0,
    burst_alt_m: float = 28_000.0, wind_error_ms: float = 0.0, density_change: float = 0.0,
) -> list[FlightCase]:  # fmt: skip
    """``wind_error_ms``: each flight's truth also carries its own constant wind error, east and north
    each drawn from N(0, wind_error_ms) (the weather's error, which no effect of the set shares)."""
    cases = []
    errors = np.random.default_rng(seed + 1000).normal(0.0, wind_error_ms, (n, 2))
    for k in range(n):
        cube = jet_cube(DIRECTIONS_DEG[k % len(DIRECTIONS_DEG)], density_change)
        own = (
            (WindOffset(east_ms=float(errors[k, 0]), north_ms=float(errors[k, 1])),) if wind_error_ms else ()
        )
        flight = synthetic_flight(
            cube, launch_time=LAUNCH + timedelta(minutes=17 * k), lat=46.0, lon=6.0, payload=PAYLOAD,
            effects=(*effects, *own), burst_alt_m=burst_alt_m - 500.0 * k, ascent_rate_ms=8.0,
            cadence_s=cadence_s, noise_m=noise_m, seed=seed + k, name=f"synthetic-{k}",
        )  # fmt: skip
        cases.append(flight_case(clean(flight.track), cube))
    return cases


@pytest.fixture(scope="session")
def synthetic_cases() -> Callable[..., list[FlightCase]]:
    """A factory: ``synthetic_cases(effects, n=5, cadence_s=180, noise_m=3, seed=0)``."""
    return make_cases


@pytest.fixture(scope="session")
def plain_cases() -> list[FlightCase]:
    """Five flights with no hidden effect, logged every 3 min."""
    return make_cases(())

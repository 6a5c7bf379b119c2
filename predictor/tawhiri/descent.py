"""Tawhiri's descent: the caller's ``descent_rate`` is the rate at sea level, faster in thinner air.

Why it exists: chasemapper has one predictor URL for everything it tracks (the main balloon,
radiosondes, the capsules), so ``/api/v1/`` must fly what Tawhiri flies, or a radiosonde would fall
like a DRS capsule. Tawhiri's drag descent keeps ``rate × √(ρ(0)/ρ(z))`` (terminal velocity under a
fixed drag area) with ρ from NASA Glenn's piecewise standard atmosphere
(https://www.grc.nasa.gov/www/k-12/airplane/atmosmet.html), drifting with the wind until it meets
the ground. Here the ground is the served terrain, and the touchdown is found by bisection inside
the last step, so the landing does not depend on where a one-minute step happened to end.
"""

from __future__ import annotations

import math
from datetime import datetime

import numpy as np

from predictor.descent import DEFAULT_TIME_TOLERANCE_S, degrees_per_metre, wrap_lon
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError
from predictor.tawhiri.ascent import Ascent, wind_sampler

DESCENT_STEP_S = 60.0
TOUCHDOWN_BISECTIONS = 30
MAX_DESCENT_S = 48 * 3600.0
"""A descent still in the air after this long is refused rather than stepped on."""


def nasa_density(alt_m: float) -> float:
    """Air density (kg/m³) of NASA Glenn's three-layer model atmosphere at ``alt_m``."""
    if alt_m > 25_000.0:
        temp_c = -131.21 + 0.00299 * alt_m
        pressure_kpa = 2.488 * ((temp_c + 273.1) / 216.6) ** -11.388
    elif alt_m > 11_000.0:
        temp_c = -56.46
        pressure_kpa = 22.65 * math.exp(1.73 - 0.000157 * alt_m)
    else:
        temp_c = 15.04 - 0.00649 * alt_m
        pressure_kpa = 101.29 * ((temp_c + 273.1) / 288.08) ** 5.256
    return pressure_kpa / (0.2869 * (temp_c + 273.1))


def drag_descent_rate(sea_level_rate_ms: float, alt_m: float) -> float:
    """The fall speed (m/s, down) at ``alt_m`` of a payload falling at ``sea_level_rate_ms`` at 0 m."""
    return sea_level_rate_ms * math.sqrt(nasa_density(0.0) / nasa_density(alt_m))


def descend(
    cube: WeatherCube,
    terrain: Terrain,
    time: datetime,
    lat: float,
    lon: float,
    alt_m: float,
    sea_level_rate_ms: float,
    time_tolerance_s: float = DEFAULT_TIME_TOLERANCE_S,
) -> Ascent:
    """Fall from (``lat``, ``lon``, ``alt_m``) at ``time`` to the ground, drifting with the wind."""
    if not (math.isfinite(sea_level_rate_ms) and sea_level_rate_ms > 0.0):
        raise PredictorError(f"the descent rate must be a positive number of m/s, got {sea_level_rate_ms!r}")
    wind = wind_sampler(cube, time_tolerance_s, "descent")
    h = DESCENT_STEP_S

    def step(t: float, la: float, lo: float, z: float, dt: float) -> tuple[float, float, float]:
        """One midpoint step of ``dt`` seconds."""
        u, v = wind(t, la, lo, z)
        dlat, dlon = degrees_per_metre(la, z)
        w = -drag_descent_rate(sea_level_rate_ms, z)
        la_mid, lo_mid, z_mid = la + 0.5 * dt * v * dlat, lo + 0.5 * dt * u * dlon, z + 0.5 * dt * w
        u, v = wind(t + 0.5 * dt, la_mid, lo_mid, z_mid)
        dlat, dlon = degrees_per_metre(la_mid, z_mid)
        w = -drag_descent_rate(sea_level_rate_ms, z_mid)
        return la + dt * v * dlat, lo + dt * u * dlon, z + dt * w

    def above_ground(la: float, lo: float, z: float) -> float:
        return z - float(terrain.elevation(la, lo))

    t0 = time.timestamp()
    t, la, lo, z = t0, float(lat), float(lon), float(alt_m)
    path = [(t, la, lo, z)]
    while True:
        if t - t0 > MAX_DESCENT_S:
            raise PredictorError(f"the descent is still in the air after {MAX_DESCENT_S / 3600:.0f} h")
        la2, lo2, z2 = step(t, la, lo, z, h)
        if above_ground(la2, lo2, z2) > 0.0:
            t, la, lo, z = t + h, la2, lo2, z2
            path.append((t, la, lo, z))
            continue
        low, high = 0.0, h  # the ground is met inside this step: find when
        for _ in range(TOUCHDOWN_BISECTIONS):
            mid = 0.5 * (low + high)
            if above_ground(*step(t, la, lo, z, mid)) > 0.0:
                low = mid
            else:
                high = mid
        la, lo, _ = step(t, la, lo, z, high)
        path.append((t + high, la, lo, float(terrain.elevation(la, lo))))
        break
    t_s, lats, lons, alts = (np.array(column) for column in zip(*path, strict=True))
    return Ascent(t_s=t_s, lat=lats, lon=np.asarray(wrap_lon(lons)), alt_m=alts)

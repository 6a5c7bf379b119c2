"""SondeHub's reverse profile: where an ascending balloon was launched, from where it is now.

Why it exists: SondeHub's Tawhiri (the one chasemapper and the SondeHub trackers ask by default) serves
``profile=reverse_profile`` so a tracker can guess a radiosonde's launch site from its first heard
position; Cambridge's Tawhiri does not define it (its issue #95 is open). The idea, not its code: run
the constant-rate ascent backwards in time, against the wind, until the path meets the ground.
"""

from __future__ import annotations

import math
from datetime import datetime

from predictor.descent import DEFAULT_TIME_TOLERANCE_S
from predictor.environment import Terrain, WeatherCube
from predictor.errors import PredictorError
from predictor.tawhiri.ascent import ASCENT_STEP_S, Ascent, as_stage, midpoint_step, wind_sampler


def trace_back(
    cube: WeatherCube,
    terrain: Terrain,
    time: datetime,
    lat: float,
    lon: float,
    alt_m: float,
    rate_ms: float,
    time_tolerance_s: float = DEFAULT_TIME_TOLERANCE_S,
) -> Ascent:
    """The ascent that reached (``lat``, ``lon``, ``alt_m``) at ``time`` rising at ``rate_ms``, from now
    back to the ground (times decreasing): its last point is the launch estimate."""
    if not (math.isfinite(rate_ms) and rate_ms > 0.0):
        raise PredictorError(f"the ascent rate must be a positive number of m/s, got {rate_ms!r}")
    wind = wind_sampler(cube, time_tolerance_s, "reverse ascent")
    t, la, lo, z = time.timestamp(), float(lat), float(lon), float(alt_m)
    path = [(t, la, lo, z)]
    while (above := z - float(terrain.elevation(la, lo))) > 0.0:
        h = -min(ASCENT_STEP_S, above / rate_ms)
        la, lo = midpoint_step(wind, t, la, lo, z, h, rate_ms)
        t, z = t + h, z + h * rate_ms
        path.append((t, la, lo, z))
        if above / rate_ms <= ASCENT_STEP_S:
            break  # the step was sized to end on the ground under where it started
    t_last, la, lo, _ = path[-1]
    path[-1] = (t_last, la, lo, float(terrain.elevation(la, lo)))  # launched from the ground there
    return as_stage(path)

"""``--winds ascent``: the wind a flight's own ascent measured, as a ``WeatherCube``.

A balloon has almost no horizontal inertia, so between two ascent fixes it moved with the mean
wind of the layer it climbed through. That turns every real flight into its own weather source,
and real descents can be predicted with no forecast at all (the 2018–2019 test flights have none).

How the profile is built:
- For each pair of consecutive ascent fixes, the horizontal displacement on the WGS84 ellipsoid
  (``pyproj.Geod``) and the elapsed time. The pair's displacement and time are shared among the
  altitude layers it climbed through, in proportion to the altitude it spent in each (a constant
  climb rate within the pair is the assumption); a pair that did not climb (1 Hz GNSS noise) goes
  whole to the layer of its mid altitude. The first pair (last ground fix, first airborne fix)
  counts only the time its climb took at the ascent's median rate, since the launch fell within it.
  A layer's wind is its total displacement over its total time, so GNSS position noise cancels
  between neighbouring pairs instead of adding up. Layers the balloon spent less than 30 s in are
  left out (their neighbours stand in for them).
- Pressure at each level is the measured on-board pressure, interpolated in log p, where it is
  trustworthy: walking up the ascent, each step of >= 500 m must imply (hypsometric equation) an
  air temperature of 170-330 K (170-280 K above 8 km). The SuperBIT sensor fails this above
  24-29 km on most flights (it reads up to 1.7x the standard pressure at 32 km, i.e. 400 K "air").
  Above the last trusted fix, below the first, or with no pressure at all, the 1976 standard
  atmosphere's shape is used (joined to the measured value). Temperature is always the standard
  atmosphere (SuperBIT logs an internal temperature, not the air's); density is p / (R T).

Limits (each result carries them as warnings): the ascent happened 1–3 hours before the descent
and up to tens of km away; the wind is held constant in time and uniform in space; below the launch
altitude and above the peak the nearest measured layer is repeated; vertical wind is not measured.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from datetime import timedelta

import numpy as np

from predictor.environment import WeatherCube
from predictor.errors import WeatherError
from predictor.prediction import GEOD
from predictor.tracks.cleaning import Flight
from predictor.tracks.reading import Fix
from predictor.tracks.standard_atmosphere import G0, R_DRY_AIR, pressure_temperature

DEFAULT_LAYER_M = 500.0
DEFAULT_MARGIN_DEG = 2.0
"""Half-width of the cube around the flight: a descent drifts at most ~100 km (about 1°)."""
DEFAULT_FLOOR_M = -500.0
"""Lowest cube level: landings can be far below the launch site and on the sea shore."""
DEFAULT_HEADROOM_M = 2000.0
DEFAULT_PADDING = timedelta(hours=12)
MIN_ASCENT_FIXES = 3
MIN_PRESSURE_FIXES = 3
PRESSURE_STEP_M = 500.0
PLAUSIBLE_AIR_K = (170.0, 330.0)
"""Air temperatures the hypsometric check accepts: colder than any tropopause, hotter than any desert."""
UPPER_AIR_MAX_K = 280.0
UPPER_AIR_FROM_M = 8000.0
"""Between 8 and 35 km real air is never warmer than ~270 K: a warmer implied layer is a sensor error."""
MIN_LAYER_SECONDS = 30.0
"""A layer crossed faster than this (the partial layers at launch and burst) is not used: with 1 Hz fixes
its wind would rest on a few noisy positions. The nearest measured layer stands in for it."""


@dataclass(frozen=True)
class WindProfile:
    """The measured wind by altitude layer, ascending, before it is spread into a cube."""

    flight: str
    alt_m: np.ndarray
    """Layer centres, m above mean sea level, ascending."""
    u: np.ndarray
    v: np.ndarray
    seconds: np.ndarray
    """Time the balloon spent in each layer, s (how much measurement each value rests on)."""


def ascent_wind_profile(flight: Flight, layer_m: float = DEFAULT_LAYER_M) -> WindProfile:
    if layer_m <= 0:
        raise WeatherError(f"ascent wind layer thickness must be positive, got {layer_m} m")
    fixes = flight.ascent
    if len(fixes) < MIN_ASCENT_FIXES:
        raise WeatherError(
            f"flight {flight.name}: its ascent has {len(fixes)} fixes; "
            f"ascent winds need at least {MIN_ASCENT_FIXES}"
        )
    lat = np.array([f.lat for f in fixes])
    lon = np.array([f.lon for f in fixes])
    alt = np.array([f.alt_m for f in fixes])
    t = np.array([f.time.timestamp() for f in fixes])
    az12, az21, dist = GEOD.inv(lon[:-1], lat[:-1], lon[1:], lat[1:])
    heading = np.radians(_mean_heading(np.asarray(az12), np.asarray(az21) + 180.0))
    east = np.asarray(dist) * np.sin(heading)
    north = np.asarray(dist) * np.cos(heading)
    dt = _airborne_seconds(np.diff(t), np.diff(alt))

    base = np.floor(alt.min() / layer_m) * layer_m
    n_layers = int(np.ceil((alt.max() - base) / layer_m)) or 1
    edges = base + layer_m * np.arange(n_layers + 1)
    shares = _layer_shares(alt[:-1], alt[1:], edges)
    seconds = shares.T @ dt
    covered = seconds >= MIN_LAYER_SECONDS
    if not covered.any():
        raise WeatherError(
            f"flight {flight.name}: its ascent spent under {MIN_LAYER_SECONDS:g} s in every layer"
        )
    centres = 0.5 * (edges[:-1] + edges[1:])
    u = (shares.T @ east)[covered] / seconds[covered]
    v = (shares.T @ north)[covered] / seconds[covered]
    return WindProfile(
        flight=flight.name,
        alt_m=centres[covered],
        u=u,
        v=v,
        seconds=seconds[covered],
    )


def ascent_weather_cube(
    flight: Flight,
    *,
    layer_m: float = DEFAULT_LAYER_M,
    margin_deg: float = DEFAULT_MARGIN_DEG,
    floor_m: float = DEFAULT_FLOOR_M,
    headroom_m: float = DEFAULT_HEADROOM_M,
    use_measured_pressure: bool = True,
) -> WeatherCube:
    """A horizontally uniform, time-constant cube around the flight, from its ascent's winds."""
    profile = ascent_wind_profile(flight, layer_m)
    top = max(float(profile.alt_m[-1]), max(f.alt_m for f in flight.fixes)) + headroom_m
    bottom = min(floor_m, float(profile.alt_m[0]) - layer_m)
    z = np.concatenate(([bottom], profile.alt_m, [top]))
    u = np.concatenate(([profile.u[0]], profile.u, [profile.u[-1]]))
    v = np.concatenate(([profile.v[0]], profile.v, [profile.v[-1]]))
    std_p, temperature = pressure_temperature(z)
    pressure = std_p
    trusted = trusted_pressure_fixes(flight.ascent) if use_measured_pressure else []
    if not use_measured_pressure:
        pressure_note = "the standard atmosphere (measured pressure not used, as asked)"
    elif len(trusted) < MIN_PRESSURE_FIXES:
        pressure_note = "the standard atmosphere (fewer than 3 trustworthy measured pressures in the ascent)"
    else:
        pressure = _measured_pressure(trusted, z, std_p)
        pressure_note = (
            f"measured on board from {trusted[0].alt_m:.0f} to {trusted[-1].alt_m:.0f} m "
            "(the standard atmosphere's shape beyond)"
        )
    density = pressure / (R_DRY_AIR * temperature)

    lats = np.array([f.lat for f in flight.fixes])
    lons = np.unwrap(np.radians([f.lon for f in flight.fixes]))
    lons = np.degrees(lons)
    cube_lats = np.array([max(-90.0, lats.min() - margin_deg), min(90.0, lats.max() + margin_deg)])
    cube_lons = np.array([lons.min() - margin_deg, lons.max() + margin_deg])
    start = flight.fixes[0].time - DEFAULT_PADDING
    end = flight.fixes[-1].time + DEFAULT_PADDING
    times = np.array([start.replace(tzinfo=None), end.replace(tzinfo=None)], dtype="datetime64[s]")
    shape = (len(times), len(z), len(cube_lats), len(cube_lons))

    def spread(values: np.ndarray) -> np.ndarray:
        return np.broadcast_to(values[None, :, None, None], shape).copy()

    launch = flight.launch or flight.fixes[0]
    peak = flight.peak or flight.fixes[0]
    source = (
        f"ascent-measured wind of flight {flight.name} "
        f"({launch.time:%Y-%m-%d %H:%M}–{peak.time:%H:%M} UTC, "
        f"{launch.alt_m:.0f}–{peak.alt_m:.0f} m, {layer_m:g} m layers)"
    )
    warnings = (
        "winds measured by the ascent, held constant in time and uniform in space: the descent happens "
        "1-3 h later and up to tens of km from where they were measured",
        f"below {profile.alt_m[0]:.0f} m and above {profile.alt_m[-1]:.0f} m "
        "the nearest measured layer is repeated",
        f"temperature is the 1976 standard atmosphere; pressure is {pressure_note}",
    )
    return WeatherCube(
        times=times,
        lead_h=np.zeros(len(times)),
        levels_hpa=pressure / 100.0,
        lats=cube_lats,
        lons=cube_lons,
        z_m=spread(z),
        u=spread(u),
        v=spread(v),
        temperature_k=spread(temperature),
        density=spread(density),
        source=source,
        warnings=warnings,
        measured_along=_measured_along(flight.ascent),
    )


def _measured_along(ascent: Sequence[Fix]) -> np.ndarray | None:
    """(altitude, lat, lon) of the ascent's fixes, altitude rising (each altitude's first pass): where
    the cube's winds were measured. None for a track without an ascent."""
    if len(ascent) < 2:
        return None
    rows = np.array([(f.alt_m, f.lat, f.lon) for f in ascent])
    rising = rows[:, 0] > np.maximum.accumulate(np.concatenate(([-np.inf], rows[:-1, 0])))
    return rows[rising]


def _airborne_seconds(dt: np.ndarray, dz: np.ndarray) -> np.ndarray:
    """The launch falls somewhere between the last ground fix and the first airborne one; the balloon
    did not move before it, so that pair's time is its climb at the ascent's typical rate, not the
    whole interval (otherwise the lowest layer's wind reads low by the ground time's share, on average
    half of it). A first pair that climbed faster than typical keeps its own time."""
    climb = dz / dt
    typical = float(np.median(climb[1:])) if len(climb) > 1 else 0.0
    airborne = dt.copy()
    if typical > 0 and 0 < climb[0] < typical:
        airborne[0] = dz[0] / typical
    return airborne


def _layer_shares(z0: np.ndarray, z1: np.ndarray, edges: np.ndarray) -> np.ndarray:
    """Fraction of each pair (rows) that belongs to each layer (columns); rows sum to 1."""
    lo = np.minimum(z0, z1)[:, None]
    hi = np.maximum(z0, z1)[:, None]
    overlap = np.clip(np.minimum(hi, edges[None, 1:]) - np.maximum(lo, edges[None, :-1]), 0.0, None)
    span = (hi - lo)[:, 0]
    shares = np.zeros_like(overlap)
    climbed = span > 0
    shares[climbed] = overlap[climbed] / span[climbed, None]
    mid = 0.5 * (z0 + z1)[~climbed]
    layer = np.clip(np.searchsorted(edges, mid, side="right") - 1, 0, len(edges) - 2)
    shares[np.nonzero(~climbed)[0], layer] = 1.0
    return shares


def _mean_heading(a_deg: np.ndarray, b_deg: np.ndarray) -> np.ndarray:
    """Circular mean of the departure and arrival azimuths: the heading at the pair's midpoint."""
    a, b = np.radians(a_deg), np.radians(b_deg)
    return np.degrees(np.arctan2(np.sin(a) + np.sin(b), np.cos(a) + np.cos(b)))


def trusted_pressure_fixes(fixes: tuple[Fix, ...]) -> list[Fix]:
    """Ascent fixes, upward, whose pressures agree with a physically possible air temperature."""
    measured = sorted(
        ((f, f.pressure_pa) for f in fixes if f.pressure_pa is not None), key=lambda pair: pair[0].alt_m
    )
    trusted = measured[:1]
    for fix, pressure_pa in measured[1:]:
        below, below_pa = trusted[-1]
        dz = fix.alt_m - below.alt_m
        if dz < PRESSURE_STEP_M:
            continue
        ratio = pressure_pa / below_pa
        if ratio >= 1.0:
            break
        implied_k = -G0 * dz / (R_DRY_AIR * np.log(ratio))
        warmest = UPPER_AIR_MAX_K if below.alt_m >= UPPER_AIR_FROM_M else PLAUSIBLE_AIR_K[1]
        if not PLAUSIBLE_AIR_K[0] <= implied_k <= warmest:
            break
        trusted.append((fix, pressure_pa))
    return [f for f, _ in trusted]


def _measured_pressure(trusted: list[Fix], z: np.ndarray, std_p: np.ndarray) -> np.ndarray:
    """Log-linear in altitude through the trusted fixes; beyond them the standard atmosphere's shape."""
    alt = np.array([f.alt_m for f in trusted])
    log_p = np.log(np.array([f.pressure_pa for f in trusted], dtype=float))
    inside = np.interp(z, alt, log_p)
    std_low, _ = pressure_temperature(alt[0])
    std_high, _ = pressure_temperature(alt[-1])
    below = log_p[0] + np.log(std_p) - np.log(std_low)
    above = log_p[-1] + np.log(std_p) - np.log(std_high)
    return np.exp(np.where(z < alt[0], below, np.where(z > alt[-1], above, inside)))

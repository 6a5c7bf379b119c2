"""Generated DEMO weather: an analytic atmosphere written as GFS-like GRIB2, for running without a network.

Why GRIB and not a cube built in memory: the demo then exercises exactly the path real forecasts take
(eccodes files → ``load_weather`` → cube), so a demo that works says something about the product.
Every file is marked with ``DEMO_GENERATING_PROCESS`` in its GRIB header; ``load_weather`` turns that
into ``is_demo=True`` and a source that says DEMO, which every output carries.

The atmosphere:
- temperature and geopotential height of the ICAO standard atmosphere at each pressure level
  (1000 … 1 hPa, i.e. up to ~48 km, above any release altitude), with a weak poleward cooling
  below 250 hPa;
- a westerly jet stream of ~40 m/s at 250 hPa whose core meanders in latitude and strength with
  longitude and time, weak winds (a few m/s, turning easterly) in the stratosphere above ~22 km,
  and a small meridional wind wave;
- geopotential height tilted across the jet so that the jet is roughly geostrophic.
It is plausible, not a forecast: it must never be mistaken for one.

It is one fixed function of place and time (``demo_atmosphere``), whatever region or time span a
call writes: ``drs serve predictor --demo-weather`` and ``drs predict --demo-weather`` see the same
air. The jets lie at ±``JET_LATITUDE`` (Esrange's, where the demo console flies) and at
±``SUBTROPICAL_JET_LATITUDE``, the stronger of the two winning at each place; the tilt is
integrated from there, and the winds taper to nothing at the poles, where a wind "from the west" has
no meaning. A region reaching within ``POLAR_CAP_DEG`` of a pole covers every longitude.
"""

from __future__ import annotations

import hashlib
import math
import os
import threading
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import platformdirs

from predictor.environment.gribwrite import (
    DEMO_GENERATING_PROCESS,
    GFS_LEVELS_HPA,
    gfs_file_name,
    write_gfs_grib2,
)
from predictor.errors import WeatherError

GRID_DEG = 0.5
STEP_H = 3
_GAS_CONSTANT = 287.05287
_G0 = 9.80665
_OMEGA = 7.2921e-5
_ISA_LAYERS = (
    # geopotential base height (m), base temperature (K), lapse rate (K/m), base pressure (Pa)
    (0.0, 288.15, -0.0065, 101325.0),
    (11000.0, 216.65, 0.0, 22632.06),
    (20000.0, 216.65, 0.001, 5474.889),
    (32000.0, 228.65, 0.0028, 868.0187),
    (47000.0, 270.65, 0.0, 110.9063),
)
_VERSION = 2  # bump when the atmosphere changes, so cached demo files are regenerated
JET_LATITUDE = 68.0
"""|latitude| of the polar-front jet cores; the tilt and the meridional temperature gradient are
referred to it."""
SUBTROPICAL_JET_LATITUDE = 45.0
"""|latitude| of a second pair of jets, so mid-latitude releases drift as far as polar ones."""
JET_LONGITUDE = 21.0
"""Longitude where the jet's meander has phase 0 (at 2000-01-01T00Z)."""
TAPER_FROM_DEG = 80.0
"""The winds fall off as cos(latitude) poleward of this, to zero at the poles."""
POLAR_CAP_DEG = 10.0
"""A region reaching this close to a pole is written for every longitude."""
MAX_DEMO_HOURS = 72
"""The longest span one call writes (25 files): a caller asking for more is refused, not served by
filling the disk (a 0.01 m/s ascent once asked for 282 files)."""


def default_demo_dir() -> Path:
    return platformdirs.user_cache_path("drs") / "demo-weather"


def demo_weather_files(
    center_lat: float,
    center_lon: float,
    start: datetime,
    cache_dir: str | Path | None = None,
    *,
    hours: int = 12,
    half_width_deg: float = 8.0,
) -> list[Path]:
    """GRIB2 files of the demo atmosphere around a point, valid from before ``start`` to ``start + hours``.

    Files are made on first use under ``cache_dir`` (default ``~/.cache/drs/demo-weather``) and reused:
    one "cycle" (``start`` rounded down to 00/06/12/18 UTC) with 3-hourly steps, on a 0.5° grid of
    ±``half_width_deg`` around the point (rounded to the grid), named like NOMADS files.
    """
    if not (isinstance(hours, int | float) and 0 <= hours <= MAX_DEMO_HOURS):
        raise WeatherError(f"demo weather is written for 0 to {MAX_DEMO_HOURS} hours, not {hours!r}")
    start_utc = start.astimezone(UTC) if start.tzinfo else start.replace(tzinfo=UTC)
    cycle = start_utc.replace(hour=start_utc.hour - start_utc.hour % 6, minute=0, second=0, microsecond=0)
    last_step = math.ceil((start_utc + timedelta(hours=hours) - cycle) / timedelta(hours=STEP_H)) * STEP_H
    lat0 = round(float(center_lat) / GRID_DEG) * GRID_DEG
    lon0 = round((float(center_lon) + 180.0) % 360.0 / GRID_DEG) * GRID_DEG - 180.0
    lats = np.arange(max(lat0 - half_width_deg, -90.0), min(lat0 + half_width_deg, 90.0) + 1e-9, GRID_DEG)
    if 90.0 - max(abs(lats[0]), abs(lats[-1])) <= POLAR_CAP_DEG:
        lons = np.arange(-180.0, 180.0 + 1e-9, GRID_DEG)  # every meridian meets at the pole
    else:
        lons = np.arange(lon0 - half_width_deg, lon0 + half_width_deg + 1e-9, GRID_DEG)

    key = hashlib.sha256(
        f"{_VERSION} {lat0} {lon0} {half_width_deg} {cycle.isoformat()} {last_step}".encode()
    ).hexdigest()[:16]
    folder = (Path(cache_dir) if cache_dir is not None else default_demo_dir()) / key
    files = []
    for step in range(0, last_step + 1, STEP_H):
        path = folder / gfs_file_name(cycle, step)
        if not path.is_file():
            # One partial file per writer: two processes making the same cold entry at once (two
            # consoles, a console and `drs predict`, the suite's workers) once wrote one shared name.
            partial = path.with_name(f"{path.name}.{os.getpid()}-{threading.get_ident():x}.partial")
            u, v, t, gh = demo_atmosphere(lats, lons, cycle + timedelta(hours=step))
            write_gfs_grib2(
                partial,
                cycle,
                step,
                GFS_LEVELS_HPA,
                lats,
                lons,
                u,
                v,
                t,
                gh,
                generating_process=DEMO_GENERATING_PROCESS,
            )
            os.replace(partial, path)  # a half-written file never looks complete
        files.append(path)
    return files


def isa_height_and_temperature(pressure_hpa: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """Geopotential height (gpm) and temperature (K) of the standard atmosphere at given pressures."""
    p = np.asarray(pressure_hpa, dtype=np.float64) * 100.0
    height = np.empty_like(p)
    temperature = np.empty_like(p)
    for index, pressure in np.ndenumerate(p):
        base_h, base_t, lapse, base_p = next(
            layer for layer in reversed(_ISA_LAYERS) if pressure <= layer[3] or layer[0] == 0.0
        )
        if lapse == 0.0:
            h = base_h - _GAS_CONSTANT * base_t / _G0 * math.log(pressure / base_p)
        else:
            h = base_h + base_t / lapse * ((pressure / base_p) ** (-_GAS_CONSTANT * lapse / _G0) - 1.0)
        height[index] = h
        temperature[index] = base_t + lapse * (h - base_h)
    return height, temperature


def demo_atmosphere(
    lats: np.ndarray, lons: np.ndarray, valid: datetime
) -> tuple[np.ndarray, np.ndarray, np.ndarray, np.ndarray]:
    """u, v (m/s), t (K), gh (gpm) on ``GFS_LEVELS_HPA`` × lats × lons at one valid time.

    ``lats`` must be on the 0.5° grid: the tilt is integrated on it from ``JET_LATITUDE``."""
    levels = np.asarray(GFS_LEVELS_HPA, dtype=np.float64)
    height, temperature = isa_height_and_temperature(levels)
    lats = np.asarray(lats, dtype=np.float64)
    lo, hi = min(float(lats[0]), JET_LATITUDE), max(float(lats[-1]), JET_LATITUDE)
    path = np.arange(lo, hi + 1e-9, GRID_DEG)  # from the reference latitude to every row asked for
    u, v = _winds(path, np.asarray(lons, dtype=np.float64), valid, height)
    rows = np.rint((lats - lo) / GRID_DEG).astype(int)

    troposphere = (levels >= 250.0)[:, None, None]
    lat2 = np.broadcast_to(lats[:, None], (lats.size, len(lons)))
    t = temperature[:, None, None] - np.where(troposphere, 0.4 * (np.abs(lat2) - JET_LATITUDE), 0.0)

    # Geostrophic tilt: u = -(g/f)·∂gh/∂y, integrated from the jet latitude (one f, the jet's).
    coriolis = 2.0 * _OMEGA * math.sin(math.radians(JET_LATITUDE))
    dy = np.radians(np.diff(path)) * 6371000.0
    u_mid = 0.5 * (u[:, 1:, :] + u[:, :-1, :])
    slope = np.concatenate([np.zeros_like(u[:, :1, :]), np.cumsum(u_mid * dy[None, :, None], axis=1)], axis=1)
    reference = int(np.rint((JET_LATITUDE - lo) / GRID_DEG))
    tilt = -(coriolis / _G0) * (slope - slope[:, reference : reference + 1, :])
    gh = height[:, None, None] + tilt[:, rows, :]
    return u[:, rows, :], v[:, rows, :], np.array(np.broadcast_to(t, gh.shape)), gh


def _winds(
    lats: np.ndarray, lons: np.ndarray, valid: datetime, height: np.ndarray
) -> tuple[np.ndarray, np.ndarray]:
    """u, v (levels × lats × lons): westerly jets meandering about ±JET_LATITUDE, tapered at the poles."""
    hours = (valid - datetime(2000, 1, 1, tzinfo=UTC)).total_seconds() / 3600.0
    lat2, lon2 = np.meshgrid(lats, lons, indexing="ij")
    phase = 2.0 * np.pi * ((lon2 - JET_LONGITUDE) / 30.0 - hours / 48.0)
    meander = 2.0 * np.sin(phase)
    core = np.maximum(
        np.exp(-(((np.abs(lat2) - JET_LATITUDE - meander) / 8.0) ** 2)),
        np.exp(-(((np.abs(lat2) - SUBTROPICAL_JET_LATITUDE - meander) / 8.0) ** 2)),
    )
    jet_shape = 0.25 + 0.75 * core * (1.0 + 0.1 * np.cos(phase))
    taper = np.minimum(1.0, np.cos(np.radians(lat2)) / math.cos(math.radians(TAPER_FROM_DEG)))

    h = height[:, None, None]
    jet_speed = 36.0 * np.exp(-(((h - 10400.0) / 4500.0) ** 2))
    stratosphere = -6.0 / (1.0 + np.exp(-(h - 22000.0) / 3000.0))
    u = (4.0 * np.exp(-h / 12000.0) + jet_speed * jet_shape + stratosphere) * taper
    v = 3.0 * np.cos(phase + np.pi / 3.0) * (0.3 + jet_speed / 36.0) * taper
    return u, v

"""The weather cube: the one shape in which every weather source reaches the descent model.

GRIB files, the generated demo atmosphere and the analytic atmospheres of the tests all become
a ``WeatherCube``; the model terms sample it and never see where it came from.

Conventions (the loader guarantees them, the samplers rely on them):
- ``times`` ascending, ``levels_hpa`` descending (so altitude rises with the level index),
  ``lats`` ascending, ``lons`` ascending and continuous in degrees east. A region that crosses
  0° or 180° is stored with longitudes that keep increasing (e.g. 350 … 370 or -10 … 10); a
  global cube repeats its first column at +360 so that interpolation never has to wrap. Use
  ``lon_in_cube`` to bring a query longitude into the cube's range.
- 4-D fields are indexed ``[time, level, lat, lon]``; ``z_m`` is geometric altitude above mean
  sea level (not geopotential height).
"""

from __future__ import annotations

from dataclasses import dataclass, field

import numpy as np

STANDARD_GRAVITY = 9.80665
"""g0, m/s²: the WMO geopotential metre, gpm = geopotential (m²/s²) / g0 (ECMWF's z → GFS's gh), and the
reference of the latitude-dependent gravity in the altitude conversion."""


@dataclass(frozen=True, eq=False)
class WeatherCube:
    times: np.ndarray
    """Valid times, ``datetime64[s]``, shape (T,), ascending."""
    lead_h: np.ndarray
    """Forecast lead time in hours of each valid time (the paper's t_future), shape (T,)."""
    levels_hpa: np.ndarray
    """Pressure levels in hPa, shape (L,), descending."""
    lats: np.ndarray
    """Latitudes in degrees, shape (Y,), ascending."""
    lons: np.ndarray
    """Longitudes in degrees east, shape (X,), ascending and continuous."""
    z_m: np.ndarray
    """Geometric altitude above mean sea level, m, shape (T, L, Y, X)."""
    u: np.ndarray
    """Eastward wind, m/s, shape (T, L, Y, X)."""
    v: np.ndarray
    """Northward wind, m/s, shape (T, L, Y, X)."""
    temperature_k: np.ndarray
    """Air temperature, K, shape (T, L, Y, X)."""
    density: np.ndarray
    """Air density from p and T (ideal gas, dry air), kg/m³, shape (T, L, Y, X)."""
    source: str
    """What the data are, for every output (e.g. 'GFS 0.50° cycle 2024-05-01 06Z')."""
    is_demo: bool = False
    """Generated demo weather: every output built on it must say so."""
    warnings: tuple[str, ...] = field(default=())
    """Things the loader noticed that the operator should know (passed into each result)."""
    measured_along: np.ndarray | None = None
    """Where these winds were measured, for winds measured by one sounding (an ascent): rows of
    (altitude m, lat, lon), altitude rising; None for a forecast. Live re-prediction widens its ellipse
    with the distance between this track and the descent still to come (``predictor.prediction.live``):
    on real flights the wind error grows with it (docs/planning/wind-errors.md)."""

    def __post_init__(self) -> None:
        shape = (len(self.times), len(self.levels_hpa), len(self.lats), len(self.lons))
        for name in ("z_m", "u", "v", "temperature_k", "density"):
            if getattr(self, name).shape != shape:
                raise ValueError(
                    f"WeatherCube.{name} has shape {getattr(self, name).shape}, expected {shape}"
                )
        if len(self.lead_h) != len(self.times):
            raise ValueError("WeatherCube.lead_h must have one entry per valid time")

    @property
    def is_global(self) -> bool:
        return bool(self.lons[-1] - self.lons[0] >= 360.0 - 1e-6)

    def lon_in_cube(self, lon: float | np.ndarray) -> float | np.ndarray:
        """The query longitude shifted by a multiple of 360° into [lons[0], lons[0] + 360)."""
        return (np.asarray(lon) - self.lons[0]) % 360.0 + self.lons[0]

    def covers(self, lat: float, lon: float) -> bool:
        lon_c = self.lon_in_cube(lon)
        return bool(self.lats[0] <= lat <= self.lats[-1] and self.lons[0] <= lon_c <= self.lons[-1])

"""Write GFS-like GRIB2 files with eccodes: the demo atmosphere, test fixtures and benchmarks.

Why our own writer: the demo mode and every weather test need real GRIB2 files that go through the
same decoder (cfgrib/eccodes) as NOAA's, without a network. The files mimic a NOMADS ``pgrb2`` file
or grib-filter subset: centre ``kwbc``, one message per variable and isobaric level, u/v/t/gh with
their WMO parameter numbers, a regular lat/lon grid scanned north to south, one file per forecast step.

Values are packed as IEEE 32-bit floats (template 5.4), so a file reads back exactly as the float32
of what was written; real GFS files use lossy complex packing, which changes nothing for the reader.
"""

from __future__ import annotations

from collections.abc import Sequence
from datetime import UTC, datetime
from pathlib import Path
from typing import TYPE_CHECKING

if TYPE_CHECKING:  # numpy is loaded on first write: `drs weather --help` names GFS_LEVELS_HPA only
    import numpy as np

_written: set[tuple[int, int, int, int]] = set()


def _identity(path: Path) -> tuple[int, int, int, int]:
    stat = path.stat()
    return stat.st_dev, stat.st_ino, stat.st_size, stat.st_mtime_ns


def written_here(path: Path) -> bool:
    """Whether this process wrote ``path`` in full and it is unchanged since (device, inode, size,
    modification time): such a file is decoded in-process, every other in a child (``gribsandbox``)."""
    try:
        return _identity(path) in _written
    except OSError:
        return False


GFS_GENERATING_PROCESS = 96
"""NCEP's generating-process number of the GFS model (ON388 table A), as real GFS files carry it."""

DEMO_GENERATING_PROCESS = 254
"""Marks a file written by the demo atmosphere: ``load_weather`` flags a cube built from it as DEMO."""

GFS_LEVELS_HPA = (
    1000,
    975,
    950,
    925,
    900,
    850,
    800,
    750,
    700,
    650,
    600,
    550,
    500,
    450,
    400,
    350,
    300,
    250,
    200,
    150,
    100,
    70,
    50,
    40,
    30,
    20,
    15,
    10,
    7,
    5,
    3,
    2,
    1,
)
"""The whole-hPa isobaric levels of u, v, t and gh in NOMADS ``pgrb2.0p50``/``0p25`` files (1000 … 1 mb)."""

# (discipline, parameterCategory, parameterNumber) of GRIB2 code table 4.2, as NCEP writes them.
_PARAMETERS = {
    "u": (0, 2, 2),
    "v": (0, 2, 3),
    "t": (0, 0, 0),
    "gh": (0, 3, 5),
}


def gfs_file_name(cycle: datetime, step_h: int, resolution: str = "0p50") -> str:
    """The NOMADS name of a forecast file, e.g. ``gfs.t06z.pgrb2.0p50.f003``."""
    return f"gfs.t{cycle.hour:02d}z.pgrb2.{resolution}.f{step_h:03d}"


def write_gfs_grib2(
    path: str | Path,
    cycle: datetime,
    step_h: int,
    levels_hpa: Sequence[float] | np.ndarray,
    lats: Sequence[float] | np.ndarray,
    lons: Sequence[float] | np.ndarray,
    u: np.ndarray,
    v: np.ndarray,
    t: np.ndarray,
    gh: np.ndarray,
    *,
    generating_process: int = GFS_GENERATING_PROCESS,
) -> Path:
    """Write one forecast step of u, v, t, gh on isobaric levels as a GRIB2 file; return its path.

    ``cycle`` is the model run (reference) time, UTC (naive datetimes are taken as UTC); ``step_h``
    the forecast hour. ``levels_hpa`` in hPa, any order. ``lats``/``lons`` are evenly spaced axes in
    degrees, either direction for latitudes; longitudes ascending and continuous, in 0–360 or ±180 or
    across 0° (``[350, 350.5, …, 370]`` or ``[-10, …, 10]``, written as GRIB's 350 → 10 wrap) or a
    whole globe. ``u``, ``v`` (m/s), ``t`` (K) and ``gh`` (geopotential metres) are arrays shaped
    ``[level, lat, lon]`` in the order of the given axes.
    """
    import predictor.environment.native_libs  # noqa: F401  (PROJ before eccodes, see there)

    # isort: split
    import eccodes  # loaded on first write: `drs weather --help` needs no GRIB library
    import numpy as np

    levels = np.asarray(levels_hpa, dtype=np.float64)
    lat_axis = np.asarray(lats, dtype=np.float64)
    lon_axis = np.asarray(lons, dtype=np.float64)
    fields = {"u": u, "v": v, "t": t, "gh": gh}
    shape = (levels.size, lat_axis.size, lon_axis.size)
    for name, values in fields.items():
        if np.shape(values) != shape:
            raise ValueError(f"{name} has shape {np.shape(values)}, expected [level, lat, lon] = {shape}")
    if not (np.all(levels >= 1.0) and np.all(levels == np.round(levels))):
        raise ValueError("levels must be whole hPa ≥ 1 (GRIB isobaricInhPa levels are integers)")
    dlat = _even_spacing(lat_axis, "latitude")
    dlon = _even_spacing(lon_axis, "longitude")
    if dlon <= 0:
        raise ValueError("longitudes must be ascending")
    north_first = dlat < 0
    if not north_first:
        lat_axis = lat_axis[::-1]
        fields = {name: np.asarray(values)[:, ::-1, :] for name, values in fields.items()}
    if cycle.tzinfo is not None:
        cycle = cycle.astimezone(UTC).replace(tzinfo=None)

    target = Path(path)
    target.parent.mkdir(parents=True, exist_ok=True)
    # One handle rewritten for every message: cloning per message costs more than encoding the field.
    message = eccodes.codes_grib_new_from_samples("regular_ll_pl_grib2")
    try:
        _set_grid_and_time(message, cycle, step_h, lat_axis, lon_axis, abs(dlat), dlon, generating_process)
        eccodes.codes_set(message, "typeOfLevel", "isobaricInhPa")
        with open(target, "wb") as out:
            for name, values in fields.items():
                discipline, category, number = _PARAMETERS[name]
                eccodes.codes_set(message, "discipline", discipline)
                eccodes.codes_set(message, "parameterCategory", category)
                eccodes.codes_set(message, "parameterNumber", number)
                for level_index, level in enumerate(levels):
                    eccodes.codes_set(message, "level", int(level))
                    plane = np.ascontiguousarray(values[level_index], dtype=np.float64)
                    eccodes.codes_set_values(message, plane.ravel())
                    eccodes.codes_write(message, out)
    finally:
        eccodes.codes_release(message)
    _written.add(_identity(target))
    return target


def _even_spacing(axis: np.ndarray, name: str) -> float:
    if axis.ndim != 1 or axis.size < 2:
        raise ValueError(f"{name} axis needs at least 2 points")
    import numpy as np

    steps = np.diff(axis)
    if not np.allclose(steps, steps[0], rtol=0, atol=1e-6):
        raise ValueError(f"{name} axis is not evenly spaced")
    return float(steps[0])


def _set_grid_and_time(
    message: int,
    cycle: datetime,
    step_h: int,
    lats: np.ndarray,
    lons: np.ndarray,
    dlat: float,
    dlon: float,
    generating_process: int,
) -> None:
    import eccodes

    eccodes.codes_set(message, "centre", "kwbc")
    eccodes.codes_set(message, "subCentre", 0)
    eccodes.codes_set(message, "generatingProcessIdentifier", generating_process)
    eccodes.codes_set(message, "typeOfGeneratingProcess", 2)  # forecast
    eccodes.codes_set(message, "significanceOfReferenceTime", 1)  # start of forecast
    eccodes.codes_set(message, "dataDate", int(cycle.strftime("%Y%m%d")))
    eccodes.codes_set(message, "dataTime", cycle.hour * 100 + cycle.minute)
    eccodes.codes_set(message, "indicatorOfUnitOfTimeRange", 1)  # hours
    eccodes.codes_set(message, "forecastTime", int(step_h))
    eccodes.codes_set(message, "shapeOfTheEarth", 6)  # sphere of radius 6 371 229 m, as GFS
    eccodes.codes_set(message, "Ni", lons.size)
    eccodes.codes_set(message, "Nj", lats.size)
    eccodes.codes_set(message, "iScansNegatively", 0)
    eccodes.codes_set(message, "jScansPositively", 0)
    eccodes.codes_set(message, "latitudeOfFirstGridPointInDegrees", float(lats[0]))
    eccodes.codes_set(message, "latitudeOfLastGridPointInDegrees", float(lats[-1]))
    eccodes.codes_set(message, "longitudeOfFirstGridPointInDegrees", float(lons[0] % 360.0))
    eccodes.codes_set(message, "longitudeOfLastGridPointInDegrees", float(lons[-1] % 360.0))
    eccodes.codes_set(message, "iDirectionIncrementInDegrees", dlon)
    eccodes.codes_set(message, "jDirectionIncrementInDegrees", dlat)
    eccodes.codes_set(message, "packingType", "grid_ieee")
    eccodes.codes_set(message, "precision", 1)  # 32-bit IEEE

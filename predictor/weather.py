"""GFS GRIB files → one regional ``WeatherCube`` (valid time, level, lat, lon), cached for the next load.

Why this shape: the descent model samples u, v, T, ρ and altitude many thousand times per prediction,
so every file-format question (GRIB editions, longitudes in 0–360 or ±180, regions that cross 0°,
several forecast steps and cycles, north-to-south scanning) is answered once here and never again.

Reading: xarray + cfgrib, filtered to u/v/t/gh on ``isobaricInhPa`` (real GFS files also carry these
variables on other level types, which would otherwise make cfgrib give up on a variable). cfgrib
decodes a whole message at a time, so fields are read one level at a time and cropped at once to the
requested box: memory stays at one global field plus the small regional cube. cfgrib never writes
``.idx`` files next to the user's data (``indexpath=''``).

Physics of the conversion:
- geometric altitude from geopotential height with latitude-dependent gravity and effective Earth
  radius (Lambert's normal gravity and the radius that makes the free-air gradient consistent):
  z = R(φ)·h / (g(φ)/g0·R(φ) − h). With a constant radius the error reaches ~80 m at 30 km near the
  poles and the equator, comparable to the 100 m integration step, so the latitude term is kept;
- density of dry air from the ideal gas law, ρ = p / (R_d·T), R_d = 287.05 J/(kg·K); humidity is
  ignored (it changes ρ by < 1 % below 5 km and nothing in the stratosphere).

Files from several cycles may give the same valid time; the freshest cycle (shortest lead) wins,
which is what an operator would use. The lead time of every valid time is kept (the paper's t_future).
"""

from __future__ import annotations

import hashlib
import json
import os
import tempfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path

import predictor.native_libs  # noqa: F401  (PROJ before eccodes/cfgrib, see there)

# isort: split
import numpy as np
import xarray as xr

from predictor.cube import WeatherCube
from predictor.errors import WeatherError
from predictor.gribcheck import scan_grib_file
from predictor.gribwrite import DEMO_GENERATING_PROCESS

VARIABLES = ("u", "v", "t", "gh")
DEMO_SOURCE = "DEMO weather (generated analytic atmosphere, not a forecast)"
STANDARD_GRAVITY = 9.80665
DRY_AIR_GAS_CONSTANT = 287.05
_CACHE_FORMAT = 1
_DECODE_BUDGET = 8_000_000
"""Grid points cfgrib may decode per request (32 MB of float32): bounds memory on global files."""

BBox = tuple[float, float, float, float]
"""(lat_min, lat_max, lon_min, lon_max) in degrees; longitudes in any convention, crossing 0° or 180°."""


def default_cache_dir() -> Path:
    base = os.environ.get("XDG_CACHE_HOME") or str(Path.home() / ".cache")
    return Path(base) / "drs" / "weather"


def load_weather(
    paths: str | Path | Iterable[str | Path],
    bbox: BBox | None = None,
    cache_dir: str | Path | None = None,
) -> WeatherCube:
    """One cube from GFS GRIB files, cropped to ``bbox`` (whole grid when None), cached in ``cache_dir``.

    The cache key is every file's absolute path, size and modification time plus the box, so a
    re-downloaded file is read again. ``cache_dir`` defaults to ``~/.cache/drs/weather``.
    """
    files = [Path(paths)] if isinstance(paths, str | Path) else [Path(p) for p in paths]
    if not files:
        raise WeatherError("no weather files given")
    for file in files:
        if not file.is_file():
            raise WeatherError(f"weather file {file} does not exist")
    box = _normalise_bbox(bbox) if bbox is not None else None
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    cache_file = cache / f"{_cache_key(files, box)}.npz"
    cached = _read_cache(cache_file)
    if cached is not None:
        return cached
    cube = _build_cube(files, box, cache / "files")
    _write_cache(cache_file, cube)
    return cube


@dataclass
class _Field:
    """One valid time of one file, already cropped: arrays [level, lat, lon]."""

    file: Path
    cycle: np.datetime64
    valid: np.datetime64
    levels: np.ndarray
    lats: np.ndarray
    lons: np.ndarray
    spacing: tuple[float, float]
    values: dict[str, np.ndarray]

    @property
    def lead_h(self) -> float:
        return float((self.valid - self.cycle) / np.timedelta64(1, "h"))


def _normalise_bbox(bbox: BBox) -> BBox:
    lat_min, lat_max, lon_min, lon_max = (float(x) for x in bbox)
    if not (-90.0 <= lat_min < lat_max <= 90.0):
        raise WeatherError(f"bbox latitudes {lat_min}, {lat_max} must satisfy -90 ≤ min < max ≤ 90")
    if lon_max <= lon_min:
        lon_max += 360.0  # a box given as (…, 170, -170) crosses the antimeridian
    if lon_max - lon_min > 360.0:
        lon_max = lon_min + 360.0
    return lat_min, lat_max, lon_min, lon_max


def _cache_key(files: Sequence[Path], box: BBox | None) -> str:
    stamps = []
    for file in sorted(files, key=lambda f: str(f.resolve())):
        stat = file.stat()
        stamps.append([str(file.resolve()), stat.st_size, stat.st_mtime_ns])
    text = json.dumps({"format": _CACHE_FORMAT, "files": stamps, "bbox": box})
    return hashlib.sha256(text.encode()).hexdigest()[:32]


_ARRAYS = ("times", "lead_h", "levels_hpa", "lats", "lons", "z_m", "u", "v", "temperature_k", "density")


def _read_cache(cache_file: Path) -> WeatherCube | None:
    """The cached cube, or None when there is none or it cannot be read (it is then rebuilt)."""
    try:
        with np.load(cache_file, allow_pickle=False) as stored:
            meta = json.loads(str(stored["meta"]))
            arrays = {name: stored[name] for name in _ARRAYS}
    except (OSError, KeyError, ValueError):
        return None
    return WeatherCube(
        **arrays, source=meta["source"], is_demo=meta["is_demo"], warnings=tuple(meta["warnings"])
    )


def _write_cache(cache_file: Path, cube: WeatherCube) -> None:
    """Atomic write, so a crash mid-write never leaves a cache entry that loads as a wrong cube."""
    meta = json.dumps({"source": cube.source, "is_demo": cube.is_demo, "warnings": list(cube.warnings)})
    try:
        cache_file.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=cache_file.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as out:
            np.savez(out, meta=np.array(meta), **{name: getattr(cube, name) for name in _ARRAYS})
        os.replace(tmp, cache_file)
    except OSError:
        # A read-only or full cache costs speed on the next load, never the prediction.
        return


def _build_cube(files: Sequence[Path], box: BBox | None, file_cache: Path) -> WeatherCube:
    fields: list[_Field] = []
    demo_files = 0
    for file in files:
        stamp = _file_stamp(file)
        demo_files += DEMO_GENERATING_PROCESS in _generating_processes(file, file_cache / f"{stamp}.scan.json")
        fields.extend(_read_file(file, box, str(file_cache / f"{stamp}.{{short_hash}}.idx")))
    _check_same_grid(fields)
    warnings: list[str] = []
    levels = _common_levels(fields, warnings)

    freshest: dict[np.datetime64, _Field] = {}
    for item in fields:
        kept = freshest.get(item.valid)
        if kept is None or item.lead_h < kept.lead_h:
            freshest[item.valid] = item
    chosen = [freshest[valid] for valid in sorted(freshest)]

    lats = chosen[0].lats
    lons = chosen[0].lons
    stacked = {}
    for name in VARIABLES:
        stacked[name] = np.stack(
            [item.values[name][np.searchsorted(-item.levels, -levels)] for item in chosen]
        ).astype(np.float64)
    z_m = geometric_altitude(stacked["gh"], lats[np.newaxis, np.newaxis, :, np.newaxis])
    density = levels[np.newaxis, :, np.newaxis, np.newaxis] * 100.0 / (DRY_AIR_GAS_CONSTANT * stacked["t"])
    is_demo = demo_files > 0
    if is_demo and demo_files < len(files):
        warnings.append(f"{demo_files} of {len(files)} weather files are generated DEMO weather")
    return WeatherCube(
        times=np.array([item.valid for item in chosen], dtype="datetime64[s]"),
        lead_h=np.array([item.lead_h for item in chosen]),
        levels_hpa=levels,
        lats=lats,
        lons=lons,
        z_m=z_m,
        u=stacked["u"],
        v=stacked["v"],
        temperature_k=stacked["t"],
        density=density,
        source=DEMO_SOURCE if is_demo else _describe_source(chosen),
        is_demo=is_demo,
        warnings=tuple(warnings),
    )


def geometric_altitude(geopotential_height_m: np.ndarray, lat_deg: np.ndarray | float) -> np.ndarray:
    """Geometric altitude above MSL (m) from geopotential height (gpm) at latitude φ.

    Uses Lambert's normal gravity g(φ) and the effective radius R(φ) of the List (1968) tables.
    """
    phi = np.radians(lat_deg)
    sin2 = np.sin(phi) ** 2
    gravity = 9.780356 * (1.0 + 0.0052885 * sin2 - 0.0000059 * np.sin(2.0 * phi) ** 2)
    radius = 6378137.0 / (1.006803 - 0.006706 * sin2)
    h = geopotential_height_m
    return radius * h / (gravity / STANDARD_GRAVITY * radius - h)


def _describe_source(chosen: Sequence[_Field]) -> str:
    spacing = chosen[0].spacing[1]
    cycles = sorted({item.cycle for item in chosen})
    names = ", ".join(np.datetime_as_string(c, unit="h").replace("T", " ") + "Z" for c in cycles)
    label = "cycle" if len(cycles) == 1 else "cycles"
    return f"GFS {spacing:.2f}° {label} {names}"


def _file_stamp(file: Path) -> str:
    """Names what we learn about one version of a file: its absolute path, size and mtime."""
    stat = file.stat()
    stamp = json.dumps([str(file.resolve()), stat.st_size, stat.st_mtime_ns])
    return hashlib.sha256(stamp.encode()).hexdigest()[:32]


def _generating_processes(file: Path, scan_record: Path) -> set[int]:
    """Integrity scan of the file (once per file version; the verdict is kept next to the cube cache)."""
    try:
        return set(json.loads(scan_record.read_text())["generating_processes"])
    except (OSError, ValueError, KeyError, TypeError):
        pass
    processes = set(scan_grib_file(file).generating_processes)
    try:
        scan_record.parent.mkdir(parents=True, exist_ok=True)
        scan_record.write_text(json.dumps({"generating_processes": sorted(processes)}))
    except OSError:
        pass  # without a writable cache the next load scans again
    return processes


def _open_isobaric(file: Path, index_path: str) -> xr.Dataset:
    """The file's u/v/t/gh on isobaric levels; cfgrib's message index is kept in our cache.

    Indexing is most of the cost of a first read; keeping the index lets a new box on the same files
    (a new release point) skip it. cfgrib falls back to an in-memory index if it cannot write there.
    """
    try:
        return xr.open_dataset(
            file,
            engine="cfgrib",
            decode_timedelta=True,
            backend_kwargs={
                "indexpath": index_path,
                "filter_by_keys": {"typeOfLevel": "isobaricInhPa", "shortName": list(VARIABLES)},
            },
        )
    except Exception as exc:  # cfgrib reports unreadable content with assorted exception types
        raise WeatherError(f"{file}: cannot decode the GRIB content ({exc})") from exc


def _read_file(file: Path, box: BBox | None, index_path: str) -> list[_Field]:
    with _open_isobaric(file, index_path) as ds:
        missing = [name for name in VARIABLES if name not in ds.data_vars]
        if "isobaricInhPa" not in ds.coords or len(missing) == len(VARIABLES):
            raise WeatherError(
                f"{file} has no u, v, t or gh on isobaric (hPa) levels; a GFS pgrb2 file or a NOMADS "
                "grib-filter subset with UGRD, VGRD, TMP and HGT on the mb levels is needed"
            )
        if missing:
            raise WeatherError(f"{file} lacks {', '.join(missing)} on isobaric levels (needs u, v, t and gh)")
        for name in VARIABLES:
            dims = set(ds[name].dims)
            if not {"latitude", "longitude"} <= dims:
                raise WeatherError(
                    f"{file}: {name} is on a projected grid (dimensions {', '.join(ds[name].dims)}); "
                    "only regular lat/lon grids such as GFS are supported"
                )
            if "number" in dims:
                raise WeatherError(f"{file} holds {ds.sizes['number']} ensemble members; pass one member per file")
        levels = np.atleast_1d(np.asarray(ds["isobaricInhPa"].values, dtype=np.float64))
        if levels.size < 2:
            raise WeatherError(f"{file} has only one isobaric level ({levels[0]:g} hPa); at least two are needed")
        lat_index, lats, dlat = _crop_latitudes(file, np.asarray(ds["latitude"].values, dtype=np.float64), box)
        lon_index, lons, dlon = _crop_longitudes(file, np.asarray(ds["longitude"].values, dtype=np.float64), box)
        cycles = np.atleast_1d(ds["time"].values).astype("datetime64[s]")
        steps = np.atleast_1d(ds["step"].values).astype("timedelta64[s]")
        fields = []
        for ci, cycle in enumerate(cycles):
            for si, step in enumerate(steps):
                values = {}
                for name in VARIABLES:
                    values[name] = _read_levels(ds[name], ci, si, levels.size, lat_index, lon_index)
                    if np.isnan(values[name]).any():
                        raise WeatherError(f"{file}: {name} has missing values inside the requested region")
                order = np.argsort(-levels)
                fields.append(
                    _Field(
                        file=file,
                        cycle=cycle,
                        valid=cycle + step,
                        levels=levels[order],
                        lats=lats,
                        lons=lons,
                        spacing=(dlat, dlon),
                        values={name: array[order] for name, array in values.items()},
                    )
                )
    return fields


def _read_levels(
    variable: xr.DataArray, cycle_index: int, step_index: int, n_levels: int, lat_index: np.ndarray,
    lon_index: np.ndarray,
) -> np.ndarray:
    """[level, lat, lon] for one valid time, cropped to the region.

    cfgrib decodes whole messages into a full-grid array per request, so levels are requested in
    batches of at most ``_DECODE_BUDGET`` grid points: one batch for a regional subset, a few levels
    at a time for a global 0.25° file.
    """
    lat_slice = slice(int(lat_index.min()), int(lat_index.max()) + 1)
    lon_slice = slice(int(lon_index.min()), int(lon_index.max()) + 1)
    selection: dict[str, int | slice] = {"latitude": lat_slice, "longitude": lon_slice}
    if "time" in variable.dims:
        selection["time"] = cycle_index
    if "step" in variable.dims:
        selection["step"] = step_index
    if "isobaricInhPa" not in variable.dims:
        block = variable.isel(selection).values[np.newaxis]
        return block[:, lat_index - lat_slice.start][:, :, lon_index - lon_slice.start]
    grid_points = variable.sizes["latitude"] * variable.sizes["longitude"]
    batch = max(1, _DECODE_BUDGET // grid_points)
    blocks = []
    for start in range(0, n_levels, batch):
        selection["isobaricInhPa"] = slice(start, min(start + batch, n_levels))
        block = variable.isel(selection).values
        blocks.append(block[:, lat_index - lat_slice.start][:, :, lon_index - lon_slice.start])
    return np.concatenate(blocks)


def _axis_spacing(file: Path, axis: np.ndarray, name: str) -> float:
    if axis.size < 2:
        raise WeatherError(f"{file}: the grid has a single {name}; a region of at least 2×2 points is needed")
    steps = np.diff(axis) % 360.0 if name == "longitude" else np.abs(np.diff(axis))
    if not np.allclose(steps, steps[0], rtol=1e-4, atol=1e-6):
        raise WeatherError(f"{file}: the {name} axis is not evenly spaced (not a regular lat/lon grid)")
    return float(steps[0])


def _crop_latitudes(file: Path, file_lats: np.ndarray, box: BBox | None) -> tuple[np.ndarray, np.ndarray, float]:
    """Indices into the file's latitude axis (ascending latitude), those latitudes, the spacing."""
    spacing = _axis_spacing(file, file_lats, "latitude")
    order = np.argsort(file_lats)
    lats = file_lats[order]
    if box is None:
        return order, lats, spacing
    lat_min, lat_max = box[0], box[1]
    first = max(int(np.searchsorted(lats, lat_min, side="right")) - 1, 0)
    last = min(int(np.searchsorted(lats, lat_max, side="left")), lats.size - 1)
    if lats[-1] < lat_min or lats[0] > lat_max or last - first < 1:
        raise WeatherError(
            f"{file} covers latitudes {lats[0]:g}…{lats[-1]:g}, not the requested {lat_min:g}…{lat_max:g}"
        )
    return order[first : last + 1], lats[first : last + 1], spacing


def _crop_longitudes(file: Path, file_lons: np.ndarray, box: BBox | None) -> tuple[np.ndarray, np.ndarray, float]:
    """Indices into the file's longitude axis, continuous ascending longitudes, the spacing.

    The result starts in [-180, 180) so that files of one grid always give identical axes. A global
    grid cropped to a box across its seam gets indices that wrap; a whole global grid gets the
    repeated first column at +360 that the cube conventions ask for.
    """
    spacing = _axis_spacing(file, file_lons, "longitude")
    if file_lons[1] < file_lons[0] and not np.isclose((file_lons[1] - file_lons[0]) % 360.0, spacing):
        raise WeatherError(f"{file}: longitudes run westward; only eastward-scanned grids are supported")
    continuous = file_lons[0] + np.concatenate([[0.0], np.cumsum(np.diff(file_lons) % 360.0)])
    count = continuous.size
    is_global = continuous[-1] - continuous[0] + spacing >= 360.0 - 1e-6
    if is_global:
        start = continuous[0]
        if box is None or box[3] - box[2] >= 360.0 - spacing:
            k = np.arange(count + 1)
        else:
            lo = start + (box[2] - start) % 360.0
            hi = lo + (box[3] - box[2])
            k = np.arange(int(np.floor((lo - start) / spacing + 1e-9)), int(np.ceil((hi - start) / spacing - 1e-9)) + 1)
        lons = start + k * spacing
        index = k % count
    else:
        index = np.arange(count)
        lons = continuous
        if box is not None:
            centre_file = (continuous[0] + continuous[-1]) / 2.0
            centre_box = (box[2] + box[3]) / 2.0
            shift = 360.0 * np.round((centre_file - centre_box) / 360.0)
            lo, hi = box[2] + shift, box[3] + shift
            first = max(int(np.searchsorted(continuous, lo, side="right")) - 1, 0)
            last = min(int(np.searchsorted(continuous, hi, side="left")), count - 1)
            if continuous[-1] < lo or continuous[0] > hi or last - first < 1:
                raise WeatherError(
                    f"{file} covers longitudes {continuous[0]:g}…{continuous[-1]:g}, "
                    f"not the requested {box[2]:g}…{box[3]:g}"
                )
            index = index[first : last + 1]
            lons = continuous[first : last + 1]
    offset = 360.0 * np.floor((lons[0] + 180.0) / 360.0)
    return index, lons - offset, spacing


def _check_same_grid(fields: Sequence[_Field]) -> None:
    reference = fields[0]
    for item in fields[1:]:
        same = (
            np.allclose(item.spacing, reference.spacing)
            and item.lats.shape == reference.lats.shape
            and item.lons.shape == reference.lons.shape
            and np.allclose(item.lats, reference.lats)
            and np.allclose(item.lons, reference.lons)
        )
        if not same:
            raise WeatherError(
                f"weather files on different grids: {reference.file} has {_grid_text(reference)}, "
                f"{item.file} has {_grid_text(item)}; use files of one resolution and region"
            )


def _grid_text(item: _Field) -> str:
    return (
        f"{item.spacing[0]:g}°×{item.spacing[1]:g}° lat {item.lats[0]:g}…{item.lats[-1]:g} "
        f"lon {item.lons[0]:g}…{item.lons[-1]:g}"
    )


def _common_levels(fields: Sequence[_Field], warnings: list[str]) -> np.ndarray:
    """Levels every file has; dropping some is worth a warning, fewer than two left is an error."""
    common = set(fields[0].levels.tolist())
    union = set(common)
    for item in fields[1:]:
        common &= set(item.levels.tolist())
        union |= set(item.levels.tolist())
    if len(common) < 2:
        raise WeatherError("the weather files share fewer than two isobaric levels; use files of one product")
    if union != common:
        dropped = ", ".join(f"{level:g}" for level in sorted(union - common, reverse=True))
        warnings.append(f"isobaric levels not present in every weather file were ignored: {dropped} hPa")
    return np.array(sorted(common, reverse=True), dtype=np.float64)

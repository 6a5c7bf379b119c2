"""GFS GRIB files → one regional ``WeatherCube`` (valid time, level, lat, lon), cached for the next load.

Why this shape: the descent model samples u, v, T, ρ and altitude many thousand times per prediction,
so every file-format question (GRIB editions, longitudes in 0–360 or ±180, regions that cross 0°,
several forecast steps and cycles, north-to-south scanning) is answered once here and never again.

Reading (``predictor.environment.gribread``): u/v/t/gh on ``isobaricInhPa`` only, one message at a time, each
cropped to the requested box at once; nothing is written next to the user's files. The cropped cube
is cached (``.npz`` keyed by every file's path, size and mtime and the box), so a second load of the
same files and box costs milliseconds. Each entry also records its files and box, so cache upkeep
(``predictor.environment.gfs_cache``) can tell an entry a load can still hit from one that no load ever will.

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
import zipfile
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np
import platformdirs

from predictor.environment.cube import STANDARD_GRAVITY, WeatherCube
from predictor.errors import WeatherError, WeatherFileError

if TYPE_CHECKING:  # the GRIB reader (eccodes) loads when files are decoded: a cached cube needs none of it
    from predictor.environment.gribread import BBox, GribField
from predictor.environment.gribwrite import DEMO_GENERATING_PROCESS

DEMO_SOURCE = "DEMO weather (generated analytic atmosphere, not a forecast)"
DRY_AIR_GAS_CONSTANT = 287.05
_CACHE_FORMAT = 3  # 2: entries record their source files and box; 3: time gaps checked, z read


def default_cache_dir() -> Path:
    """The platform's cache directory (``$XDG_CACHE_HOME/drs`` on Linux): decoded cubes are rebuilt if lost."""
    return platformdirs.user_cache_path("drs") / "weather"


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
            if file.exists():
                raise WeatherFileError(
                    file, "not a regular file (a device, FIFO or directory); give a GRIB file"
                )
            raise WeatherError(f"weather file {file} does not exist")
    box = _normalise_bbox(bbox) if bbox is not None else None
    cache = Path(cache_dir) if cache_dir is not None else default_cache_dir()
    cache_file = cache / f"{_cache_key(files, box)}.npz"
    cached = _read_cache(cache_file)
    if cached is not None:
        return cached
    cube = _build_cube(files, box)
    _write_cache(cache_file, cube, files, box)
    return cube


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
        return WeatherCube(
            **arrays, source=meta["source"], is_demo=meta["is_demo"], warnings=tuple(meta["warnings"])
        )
    except (OSError, EOFError, KeyError, TypeError, ValueError, zipfile.BadZipFile):
        return None


def _write_cache(cache_file: Path, cube: WeatherCube, files: Sequence[Path], box: BBox | None) -> None:
    """Atomic write, so a crash mid-write never leaves a cache entry that loads as a wrong cube."""
    meta = json.dumps(
        {
            "source": cube.source,
            "is_demo": cube.is_demo,
            "warnings": list(cube.warnings),
            "files": [str(file.resolve()) for file in files],
            "bbox": box,
        }
    )
    try:
        cache_file.parent.mkdir(parents=True, exist_ok=True)
        fd, tmp = tempfile.mkstemp(dir=cache_file.parent, suffix=".tmp")
        with os.fdopen(fd, "wb") as out:
            np.savez(out, meta=np.array(meta), **{name: getattr(cube, name) for name in _ARRAYS})
        os.replace(tmp, cache_file)
    except OSError:
        # A read-only or full cache costs speed on the next load, never the prediction.
        return


@dataclass(frozen=True)
class CubeCacheEntry:
    """One cached cube, as cache upkeep sees it."""

    path: Path
    size_bytes: int
    sources: tuple[Path, ...]
    """The weather files it was built from; empty when the entry does not say (older format, damaged)."""
    current: bool
    """A load of the same files and box would hit it: the files are there, unchanged, and it is this format."""


def cube_cache_entries(cache_dir: str | Path) -> list[CubeCacheEntry]:
    """Every entry in ``cache_dir`` (none when it does not exist), each checked against its files now.

    An entry whose files are gone or were re-downloaded can never be hit again (the key holds their size
    and mtime), so it is dead weight on the disk; an entry of an older format likewise.
    """
    entries = []
    for path in sorted(Path(cache_dir).glob("*.npz")):
        try:
            size = path.stat().st_size
        except FileNotFoundError:
            continue  # removed by another process since the listing
        sources: tuple[Path, ...] = ()
        current = False
        try:
            with np.load(path, allow_pickle=False) as stored:
                meta = json.loads(str(stored["meta"]))
            sources = tuple(Path(name) for name in meta["files"])
            box = tuple(meta["bbox"]) if meta["bbox"] is not None else None
            if sources and all(source.is_file() for source in sources):
                current = _cache_key(sources, box) == path.stem
        except (OSError, EOFError, KeyError, TypeError, ValueError, zipfile.BadZipFile):
            pass  # unreadable or without a source record: no load can hit it
        entries.append(CubeCacheEntry(path=path, size_bytes=size, sources=sources, current=current))
    return entries


def _build_cube(files: Sequence[Path], box: BBox | None) -> WeatherCube:
    from predictor.environment.gribread import VARIABLES, assemble_fields, merge_planes
    from predictor.environment.gribsandbox import read_planes

    parts = read_planes(files, box)
    demo_files = sum(DEMO_GENERATING_PROCESS in part.processes for part in parts)
    fields = [item for part in parts if part.complete for item in assemble_fields(part)]
    partial = [part for part in parts if not part.complete]
    if partial:
        fields.extend(assemble_fields(merge_planes(partial)))
    _check_same_grid(fields)
    warnings: list[str] = []
    levels = _common_levels(fields, warnings)

    freshest: dict[np.datetime64, GribField] = {}
    for item in fields:
        kept = freshest.get(item.valid)
        if kept is None or item.lead_h < kept.lead_h:
            freshest[item.valid] = item
    chosen = [freshest[valid] for valid in sorted(freshest)]
    _check_time_gaps([item.valid for item in chosen], warnings)
    for item in chosen:
        if item.dropped_levels:
            warnings.append(
                f"{item.file} at {_hour(item.valid)}: left out {', '.join(item.dropped_levels)}; "
                "the profile is interpolated across them"
            )

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


MAX_TIME_GAP = np.timedelta64(24, "h")
"""No forecast is interpolated across a day: a set with such a gap is two sets (e.g. cycles months apart)."""


def _check_time_gaps(valid_times: Sequence[np.datetime64], warnings: list[str]) -> None:
    """Valid times further apart than the set's own step: warned about, and refused beyond a day.

    A missing forecast step (one file of a download failed) leaves a gap a descent can still be
    interpolated across, with a warning that names it; cycles days or months apart loaded together
    would silently interpolate a release between them across that whole time.
    """
    times = np.asarray(valid_times, dtype="datetime64[s]")
    steps = np.diff(times)
    if steps.size == 0:
        return
    too_long = np.flatnonzero(steps > MAX_TIME_GAP)
    if too_long.size:
        _refuse_gap(times, int(too_long[0]))
    values, counts = np.unique(steps, return_counts=True)
    step = values[np.argmax(counts)]
    for index in np.flatnonzero(steps > step):
        hours = steps[index] / np.timedelta64(1, "h")
        warnings.append(
            f"the weather has a {hours:g} h gap from {_hour(times[index])} to {_hour(times[index + 1])} "
            f"(its step is {step / np.timedelta64(1, 'h'):g} h): a forecast file is missing there"
        )


def _refuse_gap(times: np.ndarray, index: int) -> None:
    start, end = times[index], times[index + 1]
    days = (end - start) / np.timedelta64(1, "D")
    raise WeatherError(
        f"the weather files leave a {days:.1f}-day gap from {_hour(start)} to {_hour(end)}: they are "
        "not one forecast (different cycles or seasons?); load the files of one period"
    )


def _hour(moment: np.datetime64) -> str:
    return np.datetime_as_string(moment, unit="m").replace("T", " ") + "Z"


def _describe_source(chosen: Sequence[GribField]) -> str:
    spacing = chosen[0].spacing[1]
    cycles = sorted({item.cycle for item in chosen})
    names = ", ".join(np.datetime_as_string(c, unit="h").replace("T", " ") + "Z" for c in cycles)
    label = "cycle" if len(cycles) == 1 else "cycles"
    return f"GFS {spacing:.2f}° {label} {names}"


def _check_same_grid(fields: Sequence[GribField]) -> None:
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


def _grid_text(item: GribField) -> str:
    return (
        f"{item.spacing[0]:g}°×{item.spacing[1]:g}° lat {item.lats[0]:g}…{item.lats[-1]:g} "
        f"lon {item.lons[0]:g}…{item.lons[-1]:g}"
    )


def _common_levels(fields: Sequence[GribField], warnings: list[str]) -> np.ndarray:
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

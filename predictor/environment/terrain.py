"""Ground elevation under a descent: SRTM tiles, a coarse global DEM where they are silent, then sea level.

Why three layers: SRTM tiles are precise but cover land only and contain voids; a coarse global DEM
(ETOPO-like NetCDF) answers everywhere but blurs valleys; and with no data at all the capsule must
still stop somewhere, so the last answer is the sea surface (0 m). Every answer is a finite float in
metres above mean sea level: the SRTM void value -32768 and negative bathymetry never leave this module
(a capsule that comes down over water lands on the water surface, not on the sea floor).

Tiles are found by their standard names (``N47E009.hgt`` covers 47–48° N, 9–10° E; ``S12W077.hgt``
covers 12–11° S, 77–76° W). The name is built from ``floor`` of the coordinates, so west and south
coordinates read the right tile (pyBalloon truncated toward zero and read the neighbour). Tiles are
memory-mapped on first use, so a directory of thousands of tiles costs nothing until a path crosses one.
"""

from __future__ import annotations

import math
import re
from dataclasses import dataclass, field
from pathlib import Path
from typing import TYPE_CHECKING, overload

import numpy as np

from predictor.errors import TerrainError

if TYPE_CHECKING:
    import xarray as xr

SRTM_VOID = -32768
SEA_LEVEL_SOURCE = "sea level (no terrain data here)"

_TILE_NAME = re.compile(r"^([NS])(\d{2})([EW])(\d{3})$", re.IGNORECASE)
_SAMPLES_BY_BYTES = {2 * 1201 * 1201: (1201, "SRTM3"), 2 * 3601 * 3601: (3601, "SRTM1")}
_NETCDF_SUFFIXES = (".nc", ".cdf", ".nc4", ".netcdf")
_NETCDF3_SIGNATURES = (b"CDF\x01", b"CDF\x02")
_CDF5_SIGNATURE = b"CDF\x05"
_HDF5_SIGNATURE = b"\x89HDF\r\n\x1a\n"
_ENGINE_FORMATS = {"scipy": "netCDF3", "h5netcdf": "netCDF4/HDF5"}


def tile_name(lat_south: int, lon_west: int) -> str:
    """The SRTM name of the 1°×1° tile whose south-west corner is (lat_south, lon_west)."""
    ns = "N" if lat_south >= 0 else "S"
    ew = "E" if lon_west >= 0 else "W"
    return f"{ns}{abs(lat_south):02d}{ew}{abs(lon_west):03d}"


def tile_corner_of(lat: float, lon: float) -> tuple[int, int]:
    """South-west corner of the tile holding (lat, lon): floor, never truncation toward zero."""
    return math.floor(lat), math.floor(_wrap_lon(lon))


@overload
def _wrap_lon(lon: float) -> float: ...
@overload
def _wrap_lon(lon: np.ndarray) -> np.ndarray: ...
def _wrap_lon(lon: float | np.ndarray) -> float | np.ndarray:
    """Longitude in [-180, 180), the range SRTM tile names use."""
    return (np.asarray(lon, dtype=np.float64) + 180.0) % 360.0 - 180.0


@dataclass
class _SrtmTile:
    path: Path
    samples: int
    kind: str
    lat_south: int
    lon_west: int
    _heights: np.ndarray | None = field(default=None, repr=False)

    @property
    def label(self) -> str:
        return f"{self.kind} {tile_name(self.lat_south, self.lon_west)}"

    def heights(self) -> np.ndarray:
        if self._heights is None:
            try:
                self._heights = np.memmap(
                    self.path, dtype=">i2", mode="r", shape=(self.samples, self.samples)
                )
            except (OSError, ValueError) as exc:
                raise TerrainError(f"cannot read SRTM tile {self.path}: {exc}") from exc
        return self._heights

    def bilinear(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """Heights at points inside this tile; NaN where all four neighbouring samples are void.

        A void corner is left out and the remaining corners' weights renormalised, so a point beside
        a void still gets an answer from the measured samples around it.
        """
        n = self.samples
        row = (self.lat_south + 1 - lat) * (n - 1)
        col = (lon - self.lon_west) * (n - 1)
        r0 = np.clip(np.floor(row).astype(np.int64), 0, n - 2)
        c0 = np.clip(np.floor(col).astype(np.int64), 0, n - 2)
        fr = np.clip(row - r0, 0.0, 1.0)
        fc = np.clip(col - c0, 0.0, 1.0)
        grid = self.heights()
        corners = np.stack([grid[r0, c0], grid[r0, c0 + 1], grid[r0 + 1, c0], grid[r0 + 1, c0 + 1]]).astype(
            np.float64
        )
        weights = np.stack([(1 - fr) * (1 - fc), (1 - fr) * fc, fr * (1 - fc), fr * fc])
        valid = corners != SRTM_VOID
        weights = np.where(valid, weights, 0.0)
        total = weights.sum(axis=0)
        # A point sitting on a void sample puts all its weight there: average the valid corners instead.
        any_valid = valid.any(axis=0)
        weights = np.where(any_valid & (total == 0.0), valid.astype(np.float64), weights)
        total = weights.sum(axis=0)
        with np.errstate(invalid="ignore", divide="ignore"):
            heights = (weights * np.where(valid, corners, 0.0)).sum(axis=0) / total
        return np.where(any_valid, heights, np.nan)


@dataclass
class _CoarseDem:
    """A regular lat/lon grid from a NetCDF file, global or regional, sampled bilinearly."""

    path: Path
    lats: np.ndarray
    lons: np.ndarray
    heights: np.ndarray
    is_global: bool

    @property
    def label(self) -> str:
        return f"coarse DEM {self.path.name}"

    @property
    def spacing_deg(self) -> float:
        return float(self.lats[1] - self.lats[0])

    def bilinear(self, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
        """Heights (negative bathymetry clamped to 0); NaN outside a regional grid."""
        lats, lons = self.lats, self.lons
        dlat = lats[1] - lats[0]
        dlon = lons[1] - lons[0]
        lon_q = (lon - lons[0]) % 360.0 + lons[0]
        if self.is_global:
            # Cell-centred global grids stop half a cell short of the poles: hold the edge row there.
            lat_q = np.clip(lat, lats[0], lats[-1])
            inside = np.ones(lat.shape, dtype=bool)
        else:
            lat_q = lat
            inside = (lat >= lats[0]) & (lat <= lats[-1]) & (lon_q <= lons[-1])
        row = np.clip((lat_q - lats[0]) / dlat, 0.0, len(lats) - 1.0)
        col = np.clip((lon_q - lons[0]) / dlon, 0.0, len(lons) - 1.0)
        r0 = np.minimum(np.floor(row).astype(np.int64), len(lats) - 2)
        c0 = np.minimum(np.floor(col).astype(np.int64), len(lons) - 2)
        fr = row - r0
        fc = col - c0
        h = self.heights
        value = (
            h[r0, c0] * (1 - fr) * (1 - fc)
            + h[r0, c0 + 1] * (1 - fr) * fc
            + h[r0 + 1, c0] * fr * (1 - fc)
            + h[r0 + 1, c0 + 1] * fr * fc
        )
        return np.where(inside, np.maximum(value, 0.0), np.nan)


def _netcdf_engine(path: Path) -> str:
    """The xarray engine for this file, chosen from its signature instead of left to xarray's guess.

    Why: xarray's guess fails with a multi-line message that names neither the file nor the fix, and
    netCDF4 needs a different reader (HDF5) from the netCDF3 files the scipy engine reads. An HDF5
    file may start with a user block, which moves its signature to byte 512, 1024, 2048, …
    """
    try:
        with path.open("rb") as stream:
            first = stream.read(8)
            if not first:
                raise TerrainError(f"DEM {path} is empty (0 bytes)")
            if first[:4] in _NETCDF3_SIGNATURES:
                return "scipy"
            if first[:4] == _CDF5_SIGNATURE:
                raise TerrainError(
                    f"DEM {path} is 64-bit-data netCDF (CDF-5), which cannot be read; "
                    "convert it to netCDF4 with `nccopy -k nc4 IN OUT`"
                )
            head, offset = first, 0
            while len(head) == len(_HDF5_SIGNATURE):
                if head == _HDF5_SIGNATURE:
                    _require_hdf5_reader(path)
                    return "h5netcdf"
                offset = max(512, 2 * offset)
                stream.seek(offset)
                head = stream.read(len(_HDF5_SIGNATURE))
    except OSError as exc:
        raise TerrainError(f"cannot read DEM {path}: {exc.strerror or exc}") from exc
    raise TerrainError(
        f"DEM {path} is neither netCDF3 nor netCDF4/HDF5 (it starts with {first[:4]!r}, not 'CDF' or '\\x89HDF')"
    )


def _require_hdf5_reader(path: Path) -> None:
    """h5netcdf ≥ 1.8 no longer pulls in h5py by itself: say so instead of failing inside xarray."""
    try:
        import h5netcdf  # noqa: F401
        import h5py  # noqa: F401
    except ImportError as exc:
        raise TerrainError(
            f"DEM {path} is netCDF4/HDF5, which needs the h5netcdf and h5py packages "
            f"({exc.name or 'one of them'} is missing): pip install 'h5netcdf[h5py]'"
        ) from exc


def _first_line(exc: BaseException) -> str:
    lines = str(exc).strip().splitlines()
    return lines[0] if lines else exc.__class__.__name__


def _read_coarse_dem(path: Path) -> _CoarseDem:
    import xarray as xr  # only NetCDF DEMs need it; SRTM tiles and sea level predict without pandas

    engine = _netcdf_engine(path)
    try:
        with xr.open_dataset(path, engine=engine) as ds:
            grid = _pick_elevation_grid(ds, path)
            lat_name, lon_name = grid.dims
            lats = np.asarray(ds[lat_name].values, dtype=np.float64)
            lons = np.asarray(ds[lon_name].values, dtype=np.float64)
            heights = np.asarray(grid.values, dtype=np.float64)
    except TerrainError:
        raise
    except Exception as exc:  # any decoder failure means the file is unusable as a DEM
        raise TerrainError(f"cannot read DEM {path} ({_ENGINE_FORMATS[engine]}): {_first_line(exc)}") from exc
    if len(lats) < 2 or len(lons) < 2:
        raise TerrainError(f"DEM {path} has fewer than 2 points along an axis")
    if lats[0] > lats[-1]:
        lats, heights = lats[::-1], heights[::-1, :]
    if lons[0] > lons[-1]:
        lons, heights = lons[::-1], heights[:, ::-1]
    for name, axis in (("latitude", lats), ("longitude", lons)):
        steps = np.diff(axis)
        if not np.allclose(steps, steps[0], rtol=1e-4, atol=1e-6) or steps[0] <= 0:
            raise TerrainError(f"DEM {path}: {name} axis is not evenly spaced")
    if np.isnan(heights).any():
        raise TerrainError(f"DEM {path} has missing elevation values; only complete grids are supported")
    dlon = lons[1] - lons[0]
    span = lons[-1] - lons[0]
    is_global = span + dlon >= 360.0 - 1e-3
    if is_global and span < 360.0 - 1e-3:
        # Close the grid with a copy of its first column so that interpolation never has to wrap.
        lons = np.append(lons, lons[0] + 360.0)
        heights = np.concatenate([heights, heights[:, :1]], axis=1)
    return _CoarseDem(path=path, lats=lats, lons=lons, heights=heights, is_global=bool(is_global))


def _pick_elevation_grid(ds: xr.Dataset, path: Path) -> xr.DataArray:
    """The one 2-D variable on (latitude, longitude) axes; axes recognised by units or names."""

    def axis_kind(name: str) -> str | None:
        coord = ds[name] if name in ds.variables else None
        units = str(coord.attrs.get("units", "")).lower() if coord is not None else ""
        lowered = name.lower()
        if (units.startswith("degree") and units.endswith(("north", "_n"))) or lowered in ("lat", "latitude"):
            return "lat"
        if (units.startswith("degree") and units.endswith(("east", "_e"))) or lowered in ("lon", "longitude"):
            return "lon"
        return None

    candidates = []
    for var in ds.data_vars.values():
        if var.ndim == 2 and [axis_kind(str(d)) for d in var.dims] == ["lat", "lon"]:
            candidates.append(var)
    if len(candidates) != 1:
        found = "none" if not candidates else ", ".join(str(v.name) for v in candidates)
        raise TerrainError(
            f"DEM {path}: expected exactly one 2-D elevation variable on (latitude, longitude), found {found}"
        )
    return candidates[0]


def _read_tile_entry(path: Path) -> _SrtmTile:
    stem = path.name.split(".")[0]
    match = _TILE_NAME.match(stem)
    if match is None:
        raise TerrainError(f"SRTM tile {path}: name is not a tile name like N46E006.hgt or S12W077.hgt")
    ns, lat_deg, ew, lon_deg = match.groups()
    lat_south = int(lat_deg) * (1 if ns.upper() == "N" else -1)
    lon_west = int(lon_deg) * (1 if ew.upper() == "E" else -1)
    if not (-90 <= lat_south < 90 and -180 <= lon_west < 180):
        raise TerrainError(f"SRTM tile {path}: corner {lat_south}, {lon_west} is not on Earth")
    size = path.stat().st_size
    if size not in _SAMPLES_BY_BYTES:
        raise TerrainError(
            f"SRTM tile {path} has {size} bytes; an SRTM3 tile has {2 * 1201 * 1201} "
            f"and an SRTM1 tile {2 * 3601 * 3601} (truncated or not an .hgt file)"
        )
    samples, kind = _SAMPLES_BY_BYTES[size]
    return _SrtmTile(path=path, samples=samples, kind=kind, lat_south=lat_south, lon_west=lon_west)


class Terrain:
    """Ground elevation in metres above mean sea level, from the best source that covers a point."""

    def __init__(self, tiles: list[_SrtmTile] | None = None, coarse: list[_CoarseDem] | None = None) -> None:
        self._tiles: dict[tuple[int, int], _SrtmTile] = {}
        for tile in tiles or []:
            key = (tile.lat_south, tile.lon_west)
            # Two copies of one tile: keep the finer (SRTM1 over SRTM3).
            if key not in self._tiles or tile.samples > self._tiles[key].samples:
                self._tiles[key] = tile
        # Finest grid first: each coarser grid only fills what the finer ones left unanswered.
        self._coarse = sorted(coarse or [], key=lambda dem: dem.spacing_deg)

    @classmethod
    def from_dir(cls, path: str | Path) -> Terrain:
        """Every ``*.hgt`` tile and every NetCDF DEM under ``path`` (searched recursively)."""
        root = Path(path)
        if not root.is_dir():
            raise TerrainError(f"terrain directory {root} does not exist or is not a directory")
        tiles = []
        coarse = []
        for file in sorted(root.rglob("*")):
            if not file.is_file():
                continue
            name = file.name.lower()
            if name.endswith(".hgt"):
                tiles.append(_read_tile_entry(file))
            elif name.endswith(_NETCDF_SUFFIXES):
                coarse.append(_read_coarse_dem(file))
        if not tiles and not coarse:
            raise TerrainError(
                f"terrain directory {root} holds no SRTM .hgt tiles and no NetCDF DEM "
                "(use Terrain.sea_level() to predict without terrain)"
            )
        return cls(tiles=tiles, coarse=coarse)

    @classmethod
    def from_netcdf(cls, path: str | Path) -> Terrain:
        """A coarse DEM alone (e.g. ETOPO): global cover at low resolution."""
        file = Path(path)
        if not file.is_file():
            raise TerrainError(f"DEM file {file} does not exist")
        return cls(coarse=[_read_coarse_dem(file)])

    @classmethod
    def sea_level(cls) -> Terrain:
        """No terrain: every point answers 0 m (the descent stops at mean sea level)."""
        return cls()

    def elevation(self, lat: float | np.ndarray, lon: float | np.ndarray) -> np.ndarray:
        """Bilinear ground height (m MSL, float64) at each point; shape of the broadcast inputs."""
        lat_a, lon_a = np.broadcast_arrays(
            np.asarray(lat, dtype=np.float64), np.asarray(lon, dtype=np.float64)
        )
        shape = lat_a.shape
        lat_f = lat_a.ravel()
        lon_f = _wrap_lon(lon_a.ravel())
        self._check_coordinates(lat_f, lon_f)
        heights, _, _ = self._answer(lat_f, lon_f)
        return heights.reshape(shape)

    def source_at(self, lat: float, lon: float) -> str:
        """Which source gives the elevation at this point, for the warnings of a result."""
        lat_f = np.array([float(lat)])
        lon_f = _wrap_lon(np.array([float(lon)]))
        self._check_coordinates(lat_f, lon_f)
        _, source_index, labels = self._answer(lat_f, lon_f)
        return labels[source_index[0]]

    @staticmethod
    def _check_coordinates(lat: np.ndarray, lon: np.ndarray) -> None:
        if not (np.isfinite(lat).all() and np.isfinite(lon).all()):
            raise TerrainError("terrain query with a non-finite latitude or longitude")
        if (np.abs(lat) > 90.0).any():
            raise TerrainError(f"terrain query at latitude {lat[np.abs(lat) > 90.0][0]:g}, beyond ±90°")

    def _answer(self, lat: np.ndarray, lon: np.ndarray) -> tuple[np.ndarray, np.ndarray, list[str]]:
        """Heights, per point the index of the source that answered, and the sources' labels."""
        heights = np.full(lat.shape, np.nan)
        source_index = np.full(lat.shape, -1, dtype=np.int64)
        labels: list[str] = []
        if self._tiles:
            lat_s = np.floor(lat).astype(np.int64)
            lon_w = np.floor(lon).astype(np.int64)
            # Latitude exactly +90 belongs to the tile below it.
            lat_s = np.minimum(lat_s, 89)
            for key in set(zip(lat_s.tolist(), lon_w.tolist(), strict=True)):
                tile = self._tiles.get(key)
                if tile is None:
                    continue
                in_tile = (lat_s == key[0]) & (lon_w == key[1])
                answered = tile.bilinear(lat[in_tile], lon[in_tile])
                idx = np.flatnonzero(in_tile)
                ok = ~np.isnan(answered)
                heights[idx[ok]] = answered[ok]
                labels.append(tile.label)
                source_index[idx[ok]] = len(labels) - 1
        for dem in self._coarse:
            missing = np.isnan(heights)
            if not missing.any():
                break
            answered = dem.bilinear(lat[missing], lon[missing])
            idx = np.flatnonzero(missing)
            ok = ~np.isnan(answered)
            heights[idx[ok]] = answered[ok]
            labels.append(dem.label)
            source_index[idx[ok]] = len(labels) - 1
        labels.append(SEA_LEVEL_SOURCE)
        unanswered = np.isnan(heights)
        heights[unanswered] = 0.0
        source_index[unanswered] = len(labels) - 1
        return heights, source_index, labels

"""Terrain: real SRTM and ETOPO data, synthetic tiles in every hemisphere, voids, and malformed input."""

from __future__ import annotations

import shutil
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from predictor.environment.terrain import SEA_LEVEL_SOURCE, Terrain, tile_corner_of, tile_name
from predictor.errors import TerrainError

SRTM3 = 1201


def write_tile(path: Path, heights: np.ndarray) -> Path:
    heights.astype(">i2").tofile(path)
    return path


def plane_tile(base: int, samples: int = SRTM3) -> np.ndarray:
    """Heights base + row + 2*col: bilinear interpolation reproduces it exactly."""
    rows, cols = np.mgrid[0:samples, 0:samples]
    return base + rows + 2 * cols


@pytest.fixture(scope="module")
def constance_dir(tmp_path_factory: pytest.TempPathFactory, shared_data: Path) -> Path:
    directory = tmp_path_factory.mktemp("srtm")
    shutil.copy(shared_data / "dem/srtm3_N47E009_hgt-elevation/137.hgt", directory / "N47E009.hgt")
    return directory


@pytest.fixture(scope="module")
def etopo20(shared_data: Path) -> Path:
    return shared_data / "dem/ferret_etopo/etopo20.cdf"


def test_real_srtm_tile_gives_lake_constance_and_alpine_summits(constance_dir: Path) -> None:
    terrain = Terrain.from_dir(constance_dir)
    lake, saentis, schesaplana = terrain.elevation([47.60, 47.2493, 47.0540], [9.40, 9.3433, 9.7078])
    assert 385.0 <= lake <= 405.0  # Lake Constance surface is at about 395 m
    assert 2400.0 <= saentis <= 2502.0  # Säntis summit 2502 m, smoothed by the 90 m grid
    assert 2800.0 <= schesaplana <= 2964.0  # Schesaplana 2964 m
    assert terrain.source_at(47.6, 9.4) == "SRTM3 N47E009"


def test_query_outside_every_source_answers_sea_level(constance_dir: Path) -> None:
    terrain = Terrain.from_dir(constance_dir)
    assert terrain.elevation(46.5, 6.6) == 0.0
    assert terrain.source_at(46.5, 6.6) == SEA_LEVEL_SOURCE


def test_elevation_keeps_the_shape_of_broadcast_inputs(constance_dir: Path) -> None:
    terrain = Terrain.from_dir(constance_dir)
    lats = np.linspace(47.1, 47.9, 12).reshape(3, 4)
    result = terrain.elevation(lats, 9.5)
    assert result.shape == (3, 4) and result.dtype == np.float64
    assert np.asarray(terrain.elevation(47.5, 9.5)).shape == ()
    assert terrain.elevation(47.5, 9.5) == terrain.elevation(47.5, 369.5) == terrain.elevation(47.5, -350.5)


def test_tile_names_use_floor_in_the_west_and_south() -> None:
    assert tile_corner_of(-11.25, -76.5) == (-12, -77)
    assert tile_name(-12, -77) == "S12W077"
    assert tile_name(47, 9) == "N47E009"
    assert tile_corner_of(-0.5, 359.5) == (-1, -1)
    assert tile_name(-1, -1) == "S01W001"


def test_south_west_tile_is_read_at_the_right_row_and_column(tmp_path: Path) -> None:
    write_tile(tmp_path / "S12W077.hgt", plane_tile(1000))
    # The tiles pyBalloon's truncation would read instead hold a constant that cannot be mistaken.
    write_tile(tmp_path / "S11W076.hgt", np.full((SRTM3, SRTM3), 7))
    write_tile(tmp_path / "S12W076.hgt", np.full((SRTM3, SRTM3), 7))
    write_tile(tmp_path / "S11W077.hgt", np.full((SRTM3, SRTM3), 7))
    terrain = Terrain.from_dir(tmp_path)
    # lat -11.25: row (−11 − (−11.25))·1200 = 300; lon −76.5: column 0.5·1200 = 600.
    assert terrain.elevation(-11.25, -76.5) == pytest.approx(1000 + 300 + 2 * 600)
    # Between samples the plane is reproduced exactly by bilinear interpolation.
    lat = -11.25 - 0.4 / 1200
    lon = -76.5 + 0.3 / 1200
    assert terrain.elevation(lat, lon) == pytest.approx(1000 + 300.4 + 2 * 600.3)
    assert terrain.source_at(-11.25, -76.5) == "SRTM3 S12W077"


def test_srtm1_tile_is_recognised_and_preferred_over_a_duplicate_srtm3(tmp_path: Path) -> None:
    (tmp_path / "srtm1").mkdir()
    write_tile(tmp_path / "srtm1" / "N46E006.hgt", plane_tile(100, 3601))
    write_tile(tmp_path / "N46E006.hgt", np.full((SRTM3, SRTM3), 5))
    terrain = Terrain.from_dir(tmp_path)
    # lat 46.5 → row 1800, lon 6.25 → column 900 on a 3601² grid.
    assert terrain.elevation(46.5, 6.25) == pytest.approx(100 + 1800 + 2 * 900)
    assert terrain.source_at(46.5, 6.25) == "SRTM1 N46E006"


def test_voids_are_filled_from_measured_neighbours_then_from_the_fallback(
    tmp_path: Path, etopo20: Path
) -> None:
    heights = np.full((SRTM3, SRTM3), 500)
    heights[600:700, 600:700] = -32768
    write_tile(tmp_path / "N10E020.hgt", heights)
    terrain = Terrain.from_dir(tmp_path)
    deep_in_void = (11.0 - 650 / 1200, 20.0 + 650 / 1200)
    beside_void = (11.0 - 599.5 / 1200, 20.0 + 620.25 / 1200)
    on_void_corner = (11.0 - 699 / 1200, 20.0 + 699 / 1200)
    values = terrain.elevation(*np.array([deep_in_void, beside_void, on_void_corner]).T)
    assert not (values == -32768).any()
    assert values[0] == 0.0 and terrain.source_at(*deep_in_void) == SEA_LEVEL_SOURCE
    assert values[1] == pytest.approx(500.0)
    assert values[2] == pytest.approx(500.0)

    shutil.copy(etopo20, tmp_path / "etopo20.cdf")
    with_fallback = Terrain.from_dir(tmp_path)
    assert with_fallback.source_at(*deep_in_void) == "coarse DEM etopo20.cdf"
    assert with_fallback.elevation(*deep_in_void) == pytest.approx(
        Terrain.from_netcdf(etopo20).elevation(*deep_in_void)
    )
    assert with_fallback.elevation(*beside_void) == pytest.approx(500.0)


def test_coarse_dem_clamps_the_sea_floor_to_the_water_surface(etopo20: Path) -> None:
    raw = xr.open_dataset(etopo20)["ROSE"].interp(ETOPO20Y=40.0, ETOPO20X1_1081=330.0)
    assert float(raw) < -1000.0  # mid-Atlantic: the DEM itself says deep ocean
    terrain = Terrain.from_netcdf(etopo20)
    assert terrain.elevation(40.0, -30.0) == 0.0
    assert terrain.source_at(40.0, -30.0) == "coarse DEM etopo20.cdf"
    assert terrain.elevation(27.99, 86.93) > 4000.0  # Himalaya, blurred by the 20′ grid


def test_coarse_dem_is_continuous_across_its_seam_and_the_antimeridian(shared_data: Path) -> None:
    for name in ("etopo20.cdf", "etopo60.cdf"):
        terrain = Terrain.from_netcdf(shared_data / "dem/ferret_etopo" / name)
        # Both files start near 20° E; etopo60 has no closing column, so the loader adds one.
        seam = terrain.elevation([10.0, 10.0, 10.0], [19.999, 20.0, 20.001])
        assert np.ptp(seam) < 5.0 and (seam > 0).all()  # Chad, about 400 m
        dateline = terrain.elevation([-17.0, -17.0], [179.9999, -179.9999])
        assert dateline[0] == pytest.approx(dateline[1], abs=5.0)


def test_regional_netcdf_dem_is_silent_outside_its_grid(tmp_path: Path) -> None:
    lats = np.arange(45.0, 48.01, 0.5)
    lons = np.arange(5.0, 8.01, 0.5)
    grid = xr.Dataset(
        {"elevation": (("lat", "lon"), np.full((lats.size, lons.size), 1234.0))},
        coords={"lat": lats, "lon": lons},
    )
    grid.to_netcdf(tmp_path / "alps.nc", engine="scipy")
    terrain = Terrain.from_dir(tmp_path)
    assert terrain.elevation(46.0, 6.0) == pytest.approx(1234.0)
    assert terrain.source_at(46.0, 6.0) == "coarse DEM alps.nc"
    assert terrain.elevation(50.0, 6.0) == 0.0
    assert terrain.source_at(50.0, 6.0) == SEA_LEVEL_SOURCE


def test_sea_level_terrain_answers_zero_everywhere() -> None:
    terrain = Terrain.sea_level()
    assert (terrain.elevation(np.array([-60.0, 0.0, 45.0]), 10.0) == 0.0).all()
    assert terrain.source_at(0.0, 0.0) == SEA_LEVEL_SOURCE


def test_truncated_tile_is_refused_naming_the_file(tmp_path: Path) -> None:
    np.zeros(1000, dtype=">i2").tofile(tmp_path / "N10E010.hgt")
    with pytest.raises(TerrainError, match=r"N10E010\.hgt has 2000 bytes"):
        Terrain.from_dir(tmp_path)


def test_tile_with_a_name_that_is_not_a_tile_is_refused(tmp_path: Path) -> None:
    write_tile(tmp_path / "137.hgt", np.zeros((SRTM3, SRTM3)))
    with pytest.raises(TerrainError, match=r"137\.hgt: name is not a tile name"):
        Terrain.from_dir(tmp_path)


def test_corrupt_netcdf_dem_is_refused_naming_the_file(tmp_path: Path) -> None:
    (tmp_path / "etopo.nc").write_bytes(b"CDF\x01 this is not really netcdf")
    with pytest.raises(TerrainError, match=r"cannot read DEM .*etopo\.nc"):
        Terrain.from_dir(tmp_path)


def test_netcdf_without_an_elevation_grid_is_refused(tmp_path: Path) -> None:
    xr.Dataset({"t": (("time",), np.arange(3.0))}).to_netcdf(tmp_path / "t.nc", engine="scipy")
    with pytest.raises(TerrainError, match=r"t\.nc: expected exactly one 2-D elevation variable"):
        Terrain.from_netcdf(tmp_path / "t.nc")


def test_missing_or_empty_directory_is_refused(tmp_path: Path) -> None:
    with pytest.raises(TerrainError, match="does not exist"):
        Terrain.from_dir(tmp_path / "nowhere")
    with pytest.raises(TerrainError, match="holds no SRTM .hgt tiles and no NetCDF DEM"):
        Terrain.from_dir(tmp_path)
    with pytest.raises(TerrainError, match="does not exist"):
        Terrain.from_netcdf(tmp_path / "none.nc")


def test_queries_off_the_globe_are_refused() -> None:
    terrain = Terrain.sea_level()
    with pytest.raises(TerrainError, match="beyond ±90°"):
        terrain.elevation(91.0, 0.0)
    with pytest.raises(TerrainError, match="non-finite"):
        terrain.elevation(np.nan, 0.0)

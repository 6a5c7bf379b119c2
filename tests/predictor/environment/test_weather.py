"""Loading GFS GRIB into a WeatherCube: real NCEP files, generated files of every layout, every error."""

from __future__ import annotations

import os
from datetime import datetime, timedelta
from pathlib import Path

import eccodes
import numpy as np
import pytest
import xarray as xr

import predictor.environment.weather as weather
from predictor.environment.gribwrite import DEMO_GENERATING_PROCESS, GFS_GENERATING_PROCESS, write_gfs_grib2
from predictor.environment.weather import DEMO_SOURCE, geometric_altitude, load_weather
from predictor.errors import WeatherError

LEVELS = np.array([1000.0, 850.0, 500.0, 250.0, 100.0, 50.0, 10.0])
CYCLE = datetime(2024, 5, 1, 6)


def marker_u(lat: np.ndarray, lon: np.ndarray, level_index: int, cycle_tag: float = 0.0) -> np.ndarray:
    """A u field whose value tells where it was read: exact in float32 on a 0.5° grid."""
    lon_east = np.mod(lon, 360.0)
    return level_index * 20.0 + lat * 0.5 + lon_east / 8.0 + cycle_tag  # within ±250 m/s


def write_marked(
    path: Path,
    lats: np.ndarray,
    lons: np.ndarray,
    cycle: datetime = CYCLE,
    step_h: int = 0,
    cycle_tag: float = 0.0,
    generating_process: int = GFS_GENERATING_PROCESS,
) -> Path:
    lat2, lon2 = np.meshgrid(lats, lons, indexing="ij")
    u = np.stack([marker_u(lat2, lon2, k, cycle_tag) for k in range(LEVELS.size)])
    v = np.full_like(u, 2.0 + step_h)
    t = np.broadcast_to(np.linspace(288.0, 230.0, LEVELS.size)[:, None, None], u.shape)
    gh = np.broadcast_to(np.array([110, 1500, 5600, 10400, 16200, 20600, 31000.0])[:, None, None], u.shape)
    return write_gfs_grib2(
        path, cycle, step_h, LEVELS, lats, lons, u, v, t, gh, generating_process=generating_process
    )


def copy_messages(source: Path, target: Path, keep_short_names: set[str]) -> Path:
    with open(source, "rb") as stream, open(target, "wb") as out:
        while (handle := eccodes.codes_grib_new_from_file(stream)) is not None:
            if eccodes.codes_get(handle, "shortName") in keep_short_names:
                eccodes.codes_write(handle, out)
            eccodes.codes_release(handle)
    return target


@pytest.fixture
def cache(tmp_path: Path) -> Path:
    return tmp_path / "cache"


@pytest.fixture(scope="module")
def real_gfs(shared_data: Path) -> Path:
    return shared_data / "weather/pygrib_sampledata/gfs.t12z.pgrbf120.2p5deg.grib2"


def first_u_at(path: Path, level: int, lat: float, lon: float) -> float:
    """u straight from eccodes, independently of cfgrib and the loader."""
    with open(path, "rb") as stream:
        while (handle := eccodes.codes_grib_new_from_file(stream)) is not None:
            try:
                if (
                    eccodes.codes_get(handle, "shortName") == "u"
                    and eccodes.codes_get(handle, "typeOfLevel") == "isobaricInhPa"
                    and eccodes.codes_get(handle, "level") == level
                ):
                    return float(eccodes.codes_grib_find_nearest(handle, lat, lon)[0]["value"])
            finally:
                eccodes.codes_release(handle)
    raise AssertionError("no such message")


def test_real_gfs_file_gives_a_plausible_european_cube(real_gfs: Path, cache: Path) -> None:
    cube = load_weather([real_gfs], bbox=(40.0, 55.0, -10.0, 10.0), cache_dir=cache)
    assert cube.source == "GFS 2.50° cycle 2011-01-10 12Z" and not cube.is_demo
    assert cube.times.tolist() == [np.datetime64("2011-01-15T12:00:00")]
    assert cube.lead_h.tolist() == [120.0]
    assert cube.levels_hpa[0] == 1000.0 and cube.levels_hpa[-1] == 10.0 and cube.levels_hpa.size == 26
    np.testing.assert_array_equal(cube.lats, np.arange(40.0, 55.1, 2.5))
    np.testing.assert_array_equal(cube.lons, np.arange(-10.0, 10.1, 2.5))
    assert np.all(np.diff(cube.z_m, axis=1) > 0)  # altitude rises with the level index
    assert 29_000 < cube.z_m[0, -1].mean() < 33_000  # 10 hPa is near 31 km
    assert 1.0 < cube.density[0, 0].mean() < 1.4 and 0.01 < cube.density[0, -1].mean() < 0.02
    assert 200 < cube.temperature_k.min() and cube.temperature_k.max() < 310
    lat_i, lon_i = 2, 7  # 45° N, 7.5° E
    assert cube.u[0, 12, lat_i, lon_i] == pytest.approx(first_u_at(real_gfs, 500, 45.0, 7.5), abs=1e-4)


def test_reader_agrees_with_cfgrib_on_every_variable_of_the_real_file(real_gfs: Path, cache: Path) -> None:
    cube = load_weather([real_gfs], bbox=(-40.0, -20.0, -80.0, -60.0), cache_dir=cache)
    reference = xr.open_dataset(
        real_gfs,
        engine="cfgrib",
        backend_kwargs={
            "indexpath": "",
            "filter_by_keys": {"typeOfLevel": "isobaricInhPa", "shortName": ["u", "v", "t", "gh"]},
        },
    ).sel(latitude=cube.lats, longitude=cube.lons % 360.0, isobaricInhPa=cube.levels_hpa)
    for ours, name in ((cube.u, "u"), (cube.v, "v"), (cube.temperature_k, "t")):
        np.testing.assert_array_equal(ours[0].astype(np.float32), reference[name].values)  # cfgrib: float32
    lats = cube.lats[None, :, None]
    np.testing.assert_allclose(
        cube.z_m[0], geometric_altitude(reference["gh"].values.astype(np.float64), lats)
    )


def test_grib1_files_load_like_grib2(tmp_path: Path, cache: Path) -> None:
    grib2 = write_marked(tmp_path / "f.grib2", np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5))
    grib1 = tmp_path / "f.grib1"
    with open(grib2, "rb") as stream, open(grib1, "wb") as out:
        while (handle := eccodes.codes_grib_new_from_file(stream)) is not None:
            values = eccodes.codes_get_values(handle)
            eccodes.codes_set(handle, "packingType", "grid_simple")
            eccodes.codes_set(handle, "edition", 1)
            eccodes.codes_set(handle, "bitsPerValue", 24)
            eccodes.codes_set_values(handle, values)
            assert eccodes.codes_get(handle, "edition") == 1
            eccodes.codes_write(handle, out)
            eccodes.codes_release(handle)
    from_grib1 = load_weather([grib1], cache_dir=cache)
    from_grib2 = load_weather([grib2], cache_dir=cache)
    np.testing.assert_array_equal(from_grib1.times, from_grib2.times)
    np.testing.assert_allclose(from_grib1.u, from_grib2.u, atol=1e-3)
    np.testing.assert_allclose(from_grib1.z_m, from_grib2.z_m, atol=1e-2)


def test_file_named_grb_is_grib2_and_loads(shared_data: Path, cache: Path) -> None:
    cube = load_weather(
        [shared_data / "weather/pygrib_sampledata/gfs.grb"], bbox=(-40, -20, 280, 300), cache_dir=cache
    )
    assert cube.source == "GFS 2.50° cycle 2011-10-08 00Z" and cube.lead_h.tolist() == [72.0]
    np.testing.assert_array_equal(cube.lons, np.arange(-80.0, -59.9, 2.5))


def test_whole_global_file_gets_the_wrap_column(real_gfs: Path, cache: Path) -> None:
    cube = load_weather(real_gfs, cache_dir=cache)
    assert cube.is_global and cube.lons[0] == 0.0 and cube.lons[-1] == 360.0
    np.testing.assert_array_equal(cube.u[..., -1], cube.u[..., 0])
    assert cube.lats[0] == -90.0 and cube.lats[-1] == 90.0
    assert cube.covers(-33.9, -70.6) and cube.covers(64.1, -21.9)


def test_box_across_greenwich_from_a_global_0_360_file(tmp_path: Path, cache: Path) -> None:
    lats = np.arange(-90.0, 90.1, 1.0)
    lons = np.arange(0.0, 359.6, 1.0)
    path = write_marked(tmp_path / "global.grib2", lats, lons)
    cube = load_weather([path], bbox=(44.2, 46.8, -3.2, 2.9), cache_dir=cache)
    np.testing.assert_array_equal(cube.lats, np.arange(44.0, 47.1, 1.0))
    np.testing.assert_array_equal(cube.lons, np.arange(-4.0, 3.01, 1.0))
    lat2, lon2 = np.meshgrid(cube.lats, cube.lons, indexing="ij")
    for k in range(LEVELS.size):
        np.testing.assert_array_equal(cube.u[0, k], marker_u(lat2, lon2, k))
    assert cube.covers(45.0, 359.0) and cube.covers(45.0, -1.0) and not cube.covers(45.0, 5.0)


def test_nomads_subset_crossing_greenwich(tmp_path: Path, cache: Path) -> None:
    lats = np.arange(40.0, 50.1, 0.5)
    lons = np.arange(350.0, 370.1, 0.5)  # written as a grid from 350° to 10°, as the grib filter cuts it
    path = write_marked(tmp_path / "subset.grib2", lats, lons)
    for box in [(42.0, 48.0, -5.0, 5.0), (42.0, 48.0, 355.0, 365.0), None]:
        cube = load_weather([path], bbox=box, cache_dir=cache)
        assert cube.lons[0] < 0.0 < cube.lons[-1] and np.all(np.diff(cube.lons) == 0.5)
        lat2, lon2 = np.meshgrid(cube.lats, cube.lons, indexing="ij")
        np.testing.assert_array_equal(cube.u[0, 3], marker_u(lat2, lon2, 3))
    assert not cube.is_global and cube.lons[0] == -10.0 and cube.lons[-1] == 10.0


def test_plus_minus_180_global_file_with_a_box_across_the_antimeridian(tmp_path: Path, cache: Path) -> None:
    lats = np.arange(-50.0, -44.9, 0.5)
    lons = np.arange(-180.0, 179.6, 0.5)
    path = write_marked(tmp_path / "pm180.grib2", lats, lons)
    cube = load_weather([path], bbox=(-50.0, -45.0, 175.0, -175.0), cache_dir=cache)
    np.testing.assert_array_equal(cube.lons, np.arange(175.0, 185.01, 0.5))
    lat2, lon2 = np.meshgrid(cube.lats, cube.lons, indexing="ij")
    np.testing.assert_array_equal(cube.u[0, 0], marker_u(lat2, lon2, 0))
    assert cube.covers(-47.0, -178.0) and cube.covers(-47.0, 179.0)


def test_west_and_south_box_in_either_longitude_convention(tmp_path: Path, cache: Path) -> None:
    lats = np.arange(-20.0, 0.1, 0.5)
    lons = np.arange(280.0, 300.1, 0.5)
    path = write_marked(tmp_path / "peru.grib2", lats, lons)
    east = load_weather([path], bbox=(-13.0, -9.0, 282.0, 287.0), cache_dir=cache)
    west = load_weather([path], bbox=(-13.0, -9.0, -78.0, -73.0), cache_dir=cache)
    np.testing.assert_array_equal(east.lons, west.lons)
    np.testing.assert_array_equal(east.lons, np.arange(-78.0, -72.9, 0.5))
    np.testing.assert_array_equal(east.u, west.u)


def test_steps_and_cycles_keep_the_freshest_forecast_of_each_valid_time(tmp_path: Path, cache: Path) -> None:
    lats = np.arange(45.0, 47.1, 0.5)
    lons = np.arange(6.0, 8.1, 0.5)
    older = CYCLE - timedelta(hours=6)
    files = [
        write_marked(tmp_path / f"old{s}", lats, lons, older, s, cycle_tag=0.25) for s in (0, 3, 6, 9, 12, 15)
    ]
    files += [write_marked(tmp_path / f"new{s}", lats, lons, CYCLE, s) for s in (0, 3, 6)]
    cube = load_weather(files[::-1], cache_dir=cache)
    hours = (cube.times - np.datetime64("2024-05-01T00:00")) / np.timedelta64(1, "h")
    assert hours.tolist() == [0, 3, 6, 9, 12, 15]
    assert cube.lead_h.tolist() == [0, 3, 0, 3, 6, 15]
    assert cube.source == "GFS 0.50° cycles 2024-05-01 00Z, 2024-05-01 06Z"
    tag = cube.u[:, 0, 0, 0] - marker_u(cube.lats[0], cube.lons[0], 0)
    assert tag.tolist() == [0.25, 0.25, 0.0, 0.0, 0.0, 0.25]
    assert cube.v[:, 0, 0, 0].tolist() == [2.0 + 0, 2.0 + 3, 2.0 + 0, 2.0 + 3, 2.0 + 6, 2.0 + 15]  # 2 + step


def test_altitude_and_density_follow_the_documented_physics(tmp_path: Path, cache: Path) -> None:
    path = write_marked(tmp_path / "f", np.arange(-90.0, 90.1, 45.0), np.arange(0.0, 10.1, 5.0))
    cube = load_weather([path], cache_dir=cache)
    gh = 31000.0
    z_10hpa = cube.z_m[0, -1, :, 0]
    spherical = 6371008.8 * gh / (6371008.8 - gh)
    assert np.all(np.abs(z_10hpa - spherical) < 0.004 * gh)
    assert z_10hpa[2] > z_10hpa[0]  # weaker gravity at the equator: a geopotential metre is longer
    assert geometric_altitude(np.array(0.0), 45.0) == 0.0
    np.testing.assert_allclose(
        cube.density[0, :, 0, 0], LEVELS * 100.0 / (287.05 * cube.temperature_k[0, :, 0, 0])
    )


def test_second_load_comes_from_the_cache_and_a_changed_file_is_read_again(
    tmp_path: Path, cache: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    lats = np.arange(45.0, 47.1, 0.5)
    lons = np.arange(6.0, 8.1, 0.5)
    path = write_marked(tmp_path / "f", lats, lons)
    first = load_weather([path], cache_dir=cache)
    assert not list(tmp_path.glob("*.idx")) and len(list(cache.glob("*.npz"))) == 1

    def must_not_decode(*args: object) -> None:
        raise AssertionError("the cube was decoded again instead of read from the cache")

    with monkeypatch.context() as patch:
        patch.setattr(weather, "_build_cube", must_not_decode)
        again = load_weather([path], cache_dir=cache)
    for name in (
        "times",
        "lead_h",
        "levels_hpa",
        "lats",
        "lons",
        "z_m",
        "u",
        "v",
        "temperature_k",
        "density",
    ):
        np.testing.assert_array_equal(getattr(again, name), getattr(first, name))
    assert again.source == first.source

    before = path.stat()
    write_marked(path, lats, lons, cycle_tag=0.5)  # same size: only the modification time tells
    os.utime(path, ns=(before.st_atime_ns, before.st_mtime_ns + 10**9))
    changed = load_weather([path], cache_dir=cache)
    assert changed.u[0, 0, 0, 0] == first.u[0, 0, 0, 0] + 0.5


def test_an_unreadable_cache_entry_is_rebuilt(tmp_path: Path, cache: Path) -> None:
    path = write_marked(tmp_path / "f", np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5))
    first = load_weather([path], cache_dir=cache)
    (entry,) = cache.glob("*.npz")
    valid_entry = entry.read_bytes()
    for damaged in (b"garbage", valid_entry[: len(valid_entry) // 2], b"PK\x03\x04" + b"\x00" * 40):
        entry.write_bytes(damaged)
        again = load_weather([path], cache_dir=cache)
        np.testing.assert_array_equal(again.u, first.u)


def test_demo_files_make_a_demo_cube(tmp_path: Path, cache: Path) -> None:
    lats = np.arange(45.0, 47.1, 0.5)
    lons = np.arange(6.0, 8.1, 0.5)
    demo = write_marked(tmp_path / "demo", lats, lons, generating_process=DEMO_GENERATING_PROCESS)
    cube = load_weather([demo], cache_dir=cache)
    assert cube.is_demo and cube.source == DEMO_SOURCE and "DEMO" in cube.source
    real = write_marked(tmp_path / "real", lats, lons, step_h=3)
    mixed = load_weather([demo, real], cache_dir=cache)
    assert mixed.is_demo and any(
        "1 of 2 weather files are generated DEMO weather" in w for w in mixed.warnings
    )


def test_levels_missing_from_one_file_are_dropped_with_a_warning(tmp_path: Path, cache: Path) -> None:
    lats = np.arange(45.0, 47.1, 0.5)
    lons = np.arange(6.0, 8.1, 0.5)
    full = write_marked(tmp_path / "full", lats, lons)
    fewer_levels = LEVELS[:-1]
    shape = (fewer_levels.size, lats.size, lons.size)
    short = write_gfs_grib2(
        tmp_path / "short",
        CYCLE,
        3,
        fewer_levels,
        lats,
        lons,
        np.zeros(shape),
        np.zeros(shape),
        np.full(shape, 250.0),
        np.broadcast_to(np.array([110, 1500, 5600, 10400, 16200, 20600.0])[:, None, None], shape),
    )
    cube = load_weather([full, short], cache_dir=cache)
    assert cube.levels_hpa.tolist() == fewer_levels.tolist()
    assert cube.warnings == ("isobaric levels not present in every weather file were ignored: 10 hPa",)


# --- every error an operator can meet, each one line that names the problem ---


def test_no_files_is_refused(cache: Path) -> None:
    with pytest.raises(WeatherError, match="no weather files given"):
        load_weather([], cache_dir=cache)


def test_missing_file_is_named(tmp_path: Path, cache: Path) -> None:
    with pytest.raises(WeatherError, match=r"weather file .*nothere\.grib2 does not exist"):
        load_weather([tmp_path / "nothere.grib2"], cache_dir=cache)


def test_missing_variable_is_named_with_its_file(tmp_path: Path, cache: Path) -> None:
    full = write_marked(tmp_path / "full", np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5))
    no_v_gh = copy_messages(full, tmp_path / "no_v_gh.grib2", {"u", "t"})
    with pytest.raises(WeatherError, match=r"no_v_gh\.grib2 lacks v, gh on isobaric levels"):
        load_weather([no_v_gh], cache_dir=cache)


def test_file_with_several_ensemble_members_is_refused(shared_data: Path, cache: Path) -> None:
    era5 = shared_data / "weather/cfgrib_sample_data/era5-levels-members.grib"  # GRIB1, 10 members
    with pytest.raises(
        WeatherError, match=r"era5-levels-members\.grib holds several (gh|t) fields at 500 hPa"
    ):
        load_weather([era5], cache_dir=cache)


def test_projected_grid_is_refused(shared_data: Path, cache: Path) -> None:
    with pytest.raises(
        WeatherError, match=r"eta\.grb: (u|v|t|gh) is on a lambert grid; only regular lat/lon"
    ):
        load_weather([shared_data / "weather/pygrib_sampledata/eta.grb"], cache_dir=cache)


def test_file_without_isobaric_levels_is_refused(tmp_path: Path, cache: Path) -> None:
    full = write_marked(tmp_path / "full", np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5))
    surface = tmp_path / "surface.grib2"
    with open(full, "rb") as stream, open(surface, "wb") as out:
        handle = eccodes.codes_grib_new_from_file(stream)
        eccodes.codes_set(handle, "typeOfLevel", "surface")
        eccodes.codes_write(handle, out)
        eccodes.codes_release(handle)
    with pytest.raises(
        WeatherError, match=r"surface\.grib2 has no u, v, t or gh \(or ECMWF z\) on isobaric \(hPa\) levels"
    ):
        load_weather([surface], cache_dir=cache)


def test_truncated_file_is_named(tmp_path: Path, cache: Path) -> None:
    full = write_marked(tmp_path / "full", np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5))
    cut = tmp_path / "gfs.t06z.pgrb2.0p50.f003"
    data = full.read_bytes()
    cut.write_bytes(data[: len(data) // 2 + 11])
    with pytest.raises(
        WeatherError, match=r"gfs\.t06z\.pgrb2\.0p50\.f003: GRIB message \d+ is truncated or corrupt"
    ):
        load_weather([full, cut], cache_dir=cache)


def test_file_that_is_not_grib_is_named(tmp_path: Path, cache: Path) -> None:
    html = tmp_path / "gfs.t06z.pgrb2.0p50.f000"
    html.write_text("<html><body>503 Service Unavailable</body></html>")
    with pytest.raises(WeatherError, match=r"f000 is not a GRIB file"):
        load_weather([html], cache_dir=cache)


def test_files_on_different_grids_are_refused_naming_both(tmp_path: Path, cache: Path) -> None:
    half = write_marked(tmp_path / "half.grib2", np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5))
    quarter = write_marked(tmp_path / "quarter.grib2", np.arange(45.0, 47.1, 0.25), np.arange(6.0, 8.1, 0.25))
    with pytest.raises(
        WeatherError, match=r"different grids: .*half\.grib2 has 0\.5°×0\.5°.*quarter\.grib2 has 0\.25°"
    ):
        load_weather([half, quarter], cache_dir=cache)


def test_box_outside_a_regional_file_is_refused(tmp_path: Path, cache: Path) -> None:
    path = write_marked(tmp_path / "alps", np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5))
    with pytest.raises(WeatherError, match=r"alps covers longitudes 6…8, not the requested 20…25"):
        load_weather([path], bbox=(45.5, 46.5, 20.0, 25.0), cache_dir=cache)
    with pytest.raises(WeatherError, match=r"alps covers latitudes 45…47, not the requested 10…20"):
        load_weather([path], bbox=(10.0, 20.0, 6.5, 7.5), cache_dir=cache)
    with pytest.raises(WeatherError, match="bbox latitudes"):
        load_weather([path], bbox=(46.0, 45.0, 6.5, 7.5), cache_dir=cache)


def test_non_physical_values_are_refused_naming_the_file(tmp_path: Path, cache: Path) -> None:
    shape = (2, 2, 2)
    zero_kelvin = write_gfs_grib2(
        tmp_path / "zero_kelvin.grib2", CYCLE, 0, [1000.0, 500.0], [45.0, 46.0], [6.0, 7.0],
        np.zeros(shape), np.zeros(shape), np.zeros(shape), np.full(shape, 5000.0),
    )  # fmt: skip
    with pytest.raises(WeatherError, match=r"zero_kelvin\.grib2: t = 0 K at 1000 hPa is outside 100…400 K"):
        load_weather([zero_kelvin], cache_dir=cache)
    heights = np.broadcast_to(
        np.array([5.0e6, 6.0e6])[:, None, None], shape
    )  # rising, so only the range sees it
    in_space = write_gfs_grib2(
        tmp_path / "in_space.grib2", CYCLE, 0, [1000.0, 500.0], [45.0, 46.0], [6.0, 7.0],
        np.zeros(shape), np.zeros(shape), np.full(shape, 250.0), heights,
    )  # fmt: skip
    with pytest.raises(
        WeatherError, match=r"in_space\.grib2: gh = 5e\+06 gpm at 1000 hPa is outside -2000…100000 gpm"
    ):
        load_weather([in_space], cache_dir=cache)


def as_ecmwf_geopotential(source: Path, target: Path) -> Path:
    """The file with every gh message rewritten as ECMWF writes height: z, geopotential in m²/s²."""
    with open(source, "rb") as stream, open(target, "wb") as out:
        while (handle := eccodes.codes_grib_new_from_file(stream)) is not None:
            if eccodes.codes_get(handle, "shortName") == "gh":
                values = eccodes.codes_get_values(handle) * 9.80665
                eccodes.codes_set(handle, "parameterNumber", 4)  # discipline 0, category 3, number 4: z
                eccodes.codes_set_values(handle, values)
                assert eccodes.codes_get(handle, "shortName") == "z"
            eccodes.codes_write(handle, out)
            eccodes.codes_release(handle)
    return target


def test_a_set_split_one_variable_per_file_loads_as_the_whole_file_does(tmp_path: Path, cache: Path) -> None:
    lats, lons = np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5)
    full = write_marked(tmp_path / "full.grib2", lats, lons)
    split = [copy_messages(full, tmp_path / f"{name}.grib2", {name}) for name in ("u", "v", "t", "gh")]
    whole, merged = load_weather([full], cache_dir=cache), load_weather(split, cache_dir=cache)
    for name in ("u", "v", "temperature_k", "z_m", "density"):
        np.testing.assert_array_equal(getattr(merged, name), getattr(whole, name))
    assert merged.times.tolist() == whole.times.tolist()


def test_ecmwf_geopotential_z_is_converted_to_geopotential_height(tmp_path: Path, cache: Path) -> None:
    lats, lons = np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5)
    full = write_marked(tmp_path / "full.grib2", lats, lons)
    ecmwf = as_ecmwf_geopotential(full, tmp_path / "ecmwf.grib2")
    whole, converted = load_weather([full], cache_dir=cache), load_weather([ecmwf], cache_dir=cache)
    np.testing.assert_allclose(converted.z_m, whole.z_m, atol=0.01)  # float32 packing of z vs gh


def test_cycles_months_apart_are_refused_with_the_gap_named(tmp_path: Path, cache: Path) -> None:
    lats, lons = np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5)
    summer = write_marked(tmp_path / "summer.grib2", lats, lons)
    winter = write_marked(tmp_path / "winter.grib2", lats, lons, CYCLE + timedelta(days=268))
    with pytest.raises(WeatherError, match=r"268\.0-day gap from 2024-05-01 06:00Z to 2025-01-24 06:00Z"):
        load_weather([summer, winter], cache_dir=cache)


def test_a_missing_forecast_step_is_named_in_a_warning(tmp_path: Path, cache: Path) -> None:
    lats, lons = np.arange(45.0, 47.1, 0.5), np.arange(6.0, 8.1, 0.5)
    files = [write_marked(tmp_path / f"f{s:03d}", lats, lons, CYCLE, s) for s in (0, 3, 9, 12)]
    cube = load_weather(files, cache_dir=cache)
    assert any(
        "6 h gap from 2024-05-01 09:00Z to 2024-05-01 15:00Z (its step is 3 h)" in w for w in cube.warnings
    )


def test_a_level_one_variable_lacks_is_left_out_with_a_warning_not_interpolated_silently(
    tmp_path: Path, cache: Path
) -> None:
    full = write_marked(tmp_path / "full.grib2", np.arange(44.0, 48.5, 0.5), np.arange(4.0, 8.5, 0.5))
    no_gh_at_500 = tmp_path / "no_gh_500.grib2"
    with open(full, "rb") as stream, open(no_gh_at_500, "wb") as out:
        while (handle := eccodes.codes_grib_new_from_file(stream)) is not None:
            if (eccodes.codes_get(handle, "shortName"), eccodes.codes_get(handle, "level")) != ("gh", 500):
                eccodes.codes_write(handle, out)
            eccodes.codes_release(handle)
    cube = load_weather([no_gh_at_500], cache_dir=cache)
    assert 500.0 not in cube.levels_hpa.tolist() and 850.0 in cube.levels_hpa.tolist()
    [warning] = cube.warnings
    assert "left out 500 hPa (no gh)" in warning and "interpolated across them" in warning


def test_heights_that_do_not_rise_with_falling_pressure_are_refused_naming_the_levels(
    tmp_path: Path, cache: Path
) -> None:
    lats, lons = np.arange(44.0, 46.5, 0.5), np.arange(4.0, 6.5, 0.5)
    shape = (LEVELS.size, lats.size, lons.size)
    gh = np.broadcast_to(np.array([110, 1500, 5600, 10400, 16200, 15600, 31000.0])[:, None, None], shape)
    t = np.broadcast_to(np.linspace(288.0, 230.0, LEVELS.size)[:, None, None], shape)
    path = write_gfs_grib2(
        tmp_path / "swapped.grib2", CYCLE, 0, LEVELS, lats, lons, np.ones(shape), np.ones(shape), t, gh
    )
    with pytest.raises(WeatherError, match="gh does not rise from 100 to 50 hPa at 44, 4"):
        load_weather([path], cache_dir=cache)

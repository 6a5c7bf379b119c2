"""The GRIB2 writer: files that eccodes and cfgrib read back exactly as written."""

from __future__ import annotations

from datetime import UTC, datetime
from pathlib import Path

import eccodes
import numpy as np
import pytest
import xarray as xr

from predictor.environment.gribwrite import DEMO_GENERATING_PROCESS, gfs_file_name, write_gfs_grib2

LEVELS = np.array([1000.0, 850.0, 500.0, 250.0, 100.0, 10.0, 1.0])


def random_fields(rng: np.random.Generator, shape: tuple[int, int, int]) -> list[np.ndarray]:
    return [
        rng.normal(0, 15, shape),
        rng.normal(0, 15, shape),
        rng.normal(240, 20, shape),
        rng.normal(9000, 5000, shape),
    ]


def open_isobaric(path: Path) -> xr.Dataset:
    return xr.open_dataset(
        path,
        engine="cfgrib",
        backend_kwargs={"indexpath": "", "filter_by_keys": {"typeOfLevel": "isobaricInhPa"}},
    )


def message_keys(path: Path, *keys: str) -> list[tuple]:
    rows = []
    with open(path, "rb") as stream:
        while (handle := eccodes.codes_grib_new_from_file(stream)) is not None:
            rows.append(tuple(eccodes.codes_get(handle, key) for key in keys))
            eccodes.codes_release(handle)
    return rows


def test_cfgrib_reads_back_exactly_the_float32_values_written(tmp_path: Path) -> None:
    rng = np.random.default_rng(1)
    lats = np.arange(-30.0, -20.0 + 1e-9, 0.5)  # ascending input; the file scans north to south
    lons = np.arange(280.0, 290.0 + 1e-9, 0.25)
    u, v, t, gh = random_fields(rng, (LEVELS.size, lats.size, lons.size))
    path = write_gfs_grib2(
        tmp_path / "f.grib2", datetime(2024, 5, 1, 6, tzinfo=UTC), 9, LEVELS, lats, lons, u, v, t, gh
    )
    ds = open_isobaric(path).sortby("latitude")
    np.testing.assert_array_equal(ds["isobaricInhPa"].values, LEVELS)
    np.testing.assert_allclose(ds["latitude"].values, lats)
    np.testing.assert_allclose(ds["longitude"].values, lons)
    for name, written in (("u", u), ("v", v), ("t", t), ("gh", gh)):
        np.testing.assert_array_equal(ds[name].values, written.astype(np.float32))
    assert ds["time"].values == np.datetime64("2024-05-01T06:00")
    assert ds["valid_time"].values == np.datetime64("2024-05-01T15:00")
    assert ds.attrs["GRIB_centre"] == "kwbc"


def test_one_message_per_variable_and_level_with_gfs_parameter_numbers(tmp_path: Path) -> None:
    shape = (LEVELS.size, 3, 4)
    fields = random_fields(np.random.default_rng(2), shape)
    path = write_gfs_grib2(
        tmp_path / "f", datetime(2024, 1, 1, 18), 0, LEVELS, [50, 51, 52], [0, 1, 2, 3], *fields
    )
    rows = message_keys(path, "shortName", "level", "generatingProcessIdentifier", "edition")
    assert len(rows) == 4 * LEVELS.size
    assert {row[0] for row in rows} == {"u", "v", "t", "gh"}
    assert {row[2] for row in rows} == {96} and {row[3] for row in rows} == {2}


def test_region_crossing_greenwich_is_written_as_a_wrapping_grid(tmp_path: Path) -> None:
    lons = np.arange(350.0, 370.0 + 1e-9, 0.5)
    lats = np.arange(45.0, 55.0 + 1e-9, 0.5)
    fields = random_fields(np.random.default_rng(3), (LEVELS.size, lats.size, lons.size))
    path = write_gfs_grib2(tmp_path / "f", datetime(2024, 1, 1), 3, LEVELS, lats, lons, *fields)
    first, last = message_keys(
        path, "longitudeOfFirstGridPointInDegrees", "longitudeOfLastGridPointInDegrees"
    )[0]
    assert (first, last) == (350.0, 10.0)
    ds = open_isobaric(path).sortby("latitude")
    np.testing.assert_allclose(ds["longitude"].values, lons - 360.0)  # cfgrib shows the run as -10 … 10
    np.testing.assert_array_equal(ds["u"].values, fields[0].astype(np.float32))


def test_demo_files_carry_their_own_generating_process(tmp_path: Path) -> None:
    fields = random_fields(np.random.default_rng(4), (LEVELS.size, 2, 2))
    path = write_gfs_grib2(
        tmp_path / "f",
        datetime(2024, 1, 1),
        0,
        LEVELS,
        [0, 1],
        [0, 1],
        *fields,
        generating_process=DEMO_GENERATING_PROCESS,
    )
    assert {row[0] for row in message_keys(path, "generatingProcessIdentifier")} == {DEMO_GENERATING_PROCESS}


@pytest.mark.parametrize(
    ("change", "message"),
    [
        ({"lats": [0.0, 1.0, 3.0]}, "latitude axis is not evenly spaced"),
        ({"lons": [2.0, 1.0]}, "longitudes must be ascending"),
        ({"levels": [1000.0, 0.4]}, "levels must be whole hPa"),
        ({"u_shape": (2, 3, 3)}, r"u has shape \(2, 3, 3\)"),
    ],
)
def test_malformed_input_is_refused_before_writing(tmp_path: Path, change: dict, message: str) -> None:
    levels = change.get("levels", [1000.0, 500.0])
    lats = change.get("lats", [0.0, 1.0, 2.0])
    lons = change.get("lons", [0.0, 1.0])
    shape = (len(levels), len(lats), len(lons))
    u = np.zeros(change.get("u_shape", shape))
    with pytest.raises(ValueError, match=message):
        write_gfs_grib2(
            tmp_path / "f", datetime(2024, 1, 1), 0, levels, lats, lons, u, *[np.zeros(shape)] * 3
        )
    assert not (tmp_path / "f").exists()


def test_file_names_follow_nomads() -> None:
    assert gfs_file_name(datetime(2024, 5, 1, 6), 3) == "gfs.t06z.pgrb2.0p50.f003"
    assert gfs_file_name(datetime(2024, 5, 1, 18), 120, "0p25") == "gfs.t18z.pgrb2.0p25.f120"

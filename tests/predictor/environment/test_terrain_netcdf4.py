"""NetCDF4 (HDF5) DEMs such as ETOPO 2022 and GEBCO: real files written here, read beside netCDF3 copies."""

from __future__ import annotations

import subprocess
import sys
import textwrap
from pathlib import Path

import h5netcdf
import numpy as np
import pytest
import xarray as xr

from predictor.environment.terrain import Terrain
from predictor.errors import TerrainError

# ETOPO 2022 and GEBCO are cell-centred global grids; 1° keeps the files small.
LATS = np.arange(-89.5, 90.0, 1.0)
LONS = np.arange(-179.5, 180.0, 1.0)


def plane(lat: np.ndarray | float, lon: np.ndarray | float) -> np.ndarray:
    """Heights a bilinear reader reproduces exactly; negative (sea floor) in the far south-west."""
    return 1000.0 + 10.0 * np.asarray(lat) + 2.0 * np.asarray(lon)


# (latitude name, longitude name, elevation name, dtype) of each real product's layout
LAYOUTS = {
    "etopo2022": ("lat", "lon", "z", np.float32),  # ETOPO_2022_v1_60s_N90W180_surface.nc
    "gmt_grid": ("y", "x", "z", np.float32),  # ETOPO1 .grd written by GMT: x/y named, units say degrees
    "gebco": ("lat", "lon", "elevation", np.int16),  # GEBCO_2023.nc
}


def dem_dataset(layout: str) -> xr.Dataset:
    lat_name, lon_name, var_name, dtype = LAYOUTS[layout]
    heights = np.round(plane(LATS[:, None], LONS[None, :])).astype(dtype)
    return xr.Dataset(
        {
            var_name: ((lat_name, lon_name), heights, {"units": "meters", "grid_mapping": "crs"}),
            "crs": ((), np.int32(0), {"grid_mapping_name": "latitude_longitude"}),
        },
        coords={
            lat_name: (lat_name, LATS, {"units": "degrees_north", "standard_name": "latitude"}),
            lon_name: (lon_name, LONS, {"units": "degrees_east", "standard_name": "longitude"}),
        },
    )


def write_netcdf4(path: Path, layout: str = "etopo2022") -> Path:
    """Compressed and chunked, as the real ETOPO 2022 and GEBCO files are."""
    var_name = LAYOUTS[layout][2]
    encoding = {var_name: {"zlib": True, "complevel": 4, "chunksizes": (45, 90)}}
    dem_dataset(layout).to_netcdf(path, engine="h5netcdf", encoding=encoding)
    return path


@pytest.mark.parametrize("layout", sorted(LAYOUTS))
def test_netcdf4_dem_answers_like_its_netcdf3_copy(tmp_path: Path, layout: str) -> None:
    nc4 = write_netcdf4(tmp_path / "dem4.nc", layout)
    assert nc4.read_bytes()[:8] == b"\x89HDF\r\n\x1a\n"  # really HDF5, not netCDF3
    nc3 = tmp_path / "dem3.nc"
    dem_dataset(layout).to_netcdf(nc3, engine="scipy")
    lats = np.array([46.3, -12.25, 0.0, -80.0, 89.9, -17.0])
    lons = np.array([7.7, -76.6, 0.0, -179.0, 10.0, 179.99])
    from_nc4 = Terrain.from_netcdf(nc4).elevation(lats, lons)
    np.testing.assert_array_equal(from_nc4, Terrain.from_netcdf(nc3).elevation(lats, lons))
    assert from_nc4[0] == pytest.approx(plane(46.3, 7.7), abs=0.5)  # values are whole metres in the file
    assert from_nc4[1] == pytest.approx(plane(-12.25, -76.6), abs=0.5)
    assert from_nc4[3] == 0.0  # sea floor (-158 m) clamped to the water surface


def test_netcdf4_dem_is_found_in_a_terrain_directory_beside_srtm_tiles(tmp_path: Path) -> None:
    write_netcdf4(tmp_path / "ETOPO_2022_v1_60s_N90W180_surface.nc")
    np.full((1201, 1201), 777, dtype=">i2").tofile(tmp_path / "N46E006.hgt")
    terrain = Terrain.from_dir(tmp_path)
    assert terrain.elevation(46.5, 6.5) == 777.0
    assert terrain.source_at(46.5, 6.5) == "SRTM3 N46E006"
    assert terrain.elevation(46.5, 8.5) == pytest.approx(plane(46.5, 8.5), abs=0.5)
    assert terrain.source_at(46.5, 8.5) == "coarse DEM ETOPO_2022_v1_60s_N90W180_surface.nc"


def test_hdf5_signature_after_a_user_block_is_recognised(tmp_path: Path) -> None:
    path = tmp_path / "userblock.nc"
    with h5netcdf.File(path, "w", userblock_size=512) as out:
        out.dimensions = {"lat": 3, "lon": 3}
        for name, units in (("lat", "degrees_north"), ("lon", "degrees_east")):
            axis = out.create_variable(name, (name,), float)
            axis[:] = [45.0, 46.0, 47.0] if name == "lat" else [6.0, 7.0, 8.0]
            axis.attrs["units"] = units
        out.create_variable("z", ("lat", "lon"), "f4")[:] = np.full((3, 3), 432.0)
    assert path.read_bytes()[:4] == b"\x00" * 4
    assert Terrain.from_netcdf(path).elevation(46.5, 7.5) == 432.0


def one_line_error(path: Path) -> str:
    with pytest.raises(TerrainError) as caught:
        Terrain.from_netcdf(path)
    message = str(caught.value)
    assert "\n" not in message and str(path) in message
    return message


def test_truncated_netcdf4_dem_is_a_one_line_error_naming_the_file_and_format(tmp_path: Path) -> None:
    whole = write_netcdf4(tmp_path / "whole.nc").read_bytes()
    cut = tmp_path / "cut.nc"
    cut.write_bytes(whole[: len(whole) // 2])  # an interrupted download
    message = one_line_error(cut)
    assert message.startswith(f"cannot read DEM {cut} (netCDF4/HDF5): ") and "truncated" in message


def test_netcdf4_with_a_damaged_superblock_is_a_one_line_error(tmp_path: Path) -> None:
    damaged = tmp_path / "damaged.nc"
    damaged.write_bytes(b"\x89HDF\r\n\x1a\n" + bytes(range(256)) * 4)
    assert one_line_error(damaged).startswith(f"cannot read DEM {damaged} (netCDF4/HDF5): ")


@pytest.mark.parametrize(
    ("content", "expected"),
    [
        (
            b"<html><body>502 Bad Gateway</body></html>",
            "is neither netCDF3 nor netCDF4/HDF5 (it starts with b'<htm'",
        ),
        (b"GRIB" + bytes(200), "is neither netCDF3 nor netCDF4/HDF5 (it starts with b'GRIB'"),
        (b"", "is empty (0 bytes)"),
        (b"CDF\x05" + bytes(100), "is 64-bit-data netCDF (CDF-5), which cannot be read; convert it"),
    ],
)
def test_file_that_is_no_readable_netcdf_is_named_with_what_it_is(
    tmp_path: Path, content: bytes, expected: str
) -> None:
    path = tmp_path / "dem.nc"
    path.write_bytes(content)
    assert expected in one_line_error(path)


def test_netcdf4_dem_without_h5py_says_which_package_to_install(tmp_path: Path) -> None:
    """A real interpreter in which h5py cannot be imported: h5netcdf ≥ 1.8 installed without its extra."""
    dem = write_netcdf4(tmp_path / "etopo.nc")
    script = textwrap.dedent(
        f"""
        import sys
        sys.modules["h5py"] = None  # importing it now raises ImportError, as if it were not installed
        import pyproj  # noqa: F401  (native library order, see predictor/environment/native_libs.py)
        from predictor.errors import TerrainError
        from predictor.environment.terrain import Terrain
        try:
            Terrain.from_netcdf({str(dem)!r})
        except TerrainError as exc:
            print(exc)
        """
    )
    run = subprocess.run(
        [sys.executable, "-c", script],
        capture_output=True,
        text=True,
        timeout=120,
        check=True,
        cwd=Path(__file__).resolve().parents[3],
    )
    assert run.stdout == (
        f"DEM {dem} is netCDF4/HDF5, which needs the h5netcdf and h5py packages (h5py is missing): "
        "pip install 'h5netcdf[h5py]'\n"
    )

"""`drs predict` end to end: GRIB2 written by eccodes, read by load_weather, run through console.commands.main.main."""

from __future__ import annotations

import json
import shutil
import xml.etree.ElementTree as ET
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from predictor import Terrain, load_weather, payload_profile, predict
from predictor.environment.gribwrite import gfs_file_name, write_gfs_grib2
from tests.predictor.predict_helpers import H_ISO, LEVELS_HPA, P0_HPA, T_ISO

CYCLE = datetime(2024, 5, 1, 0, tzinfo=UTC)


@pytest.fixture(scope="module")
def grib_files(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    """Three 0.5° forecast steps over a region that crosses the Greenwich meridian."""
    root = tmp_path_factory.mktemp("gfs")
    lats, lons = np.arange(45.0, 55.01, 0.5), np.arange(-6.0, 6.01, 0.5)
    shape = (LEVELS_HPA.size, lats.size, lons.size)
    gh = np.broadcast_to((-H_ISO * np.log(LEVELS_HPA / P0_HPA))[:, None, None], shape)
    files = []
    for step in (0, 3, 6):
        u = np.full(shape, 12.0 + step) + 0.2 * lons[None, None, :]
        v = np.full(shape, -3.0) + 0.1 * (lats[None, :, None] - 50.0)
        files.append(
            write_gfs_grib2(root / gfs_file_name(CYCLE, step), CYCLE, step, LEVELS_HPA, lats, lons,
                            u, v, np.full(shape, T_ISO), gh)
        )  # fmt: skip
    return files


@pytest.fixture(scope="module")
def cache(tmp_path_factory: pytest.TempPathFactory) -> str:
    return str(tmp_path_factory.mktemp("cache"))


def base_args(files: list[Path], cache: str) -> list[str]:
    return ["predict", "--weather", *map(str, files), "--cache-dir", cache,
            "--lat", "51.0", "--lon", "-0.3", "--alt", "28000", "--time", "2024-05-01T02:00Z"]  # fmt: skip


def test_json_output_matches_the_python_api_on_the_same_files(
    grib_files: list[Path], cache: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*base_args(grib_files, cache), "--json", "--track"]) == 0
    doc = json.loads(capsys.readouterr().out)
    wx = load_weather(grib_files, cache_dir=cache)
    res = predict(
        wx, datetime(2024, 5, 1, 2, tzinfo=UTC), 51.0, -0.3, 28000.0, payload=payload_profile("drs")
    )
    assert doc["landing"]["lat"] == pytest.approx(res.landing.lat, abs=1e-9)
    assert doc["landing"]["lon"] == pytest.approx(res.landing.lon, abs=1e-9)
    assert doc["landing"]["lon"] > 0.0  # crossed the Greenwich meridian eastwards
    assert doc["release"]["time"] == "2024-05-01T02:00:00Z"
    assert doc["t_future_mean_h"] == pytest.approx(2.0 + doc["descent_s"] / 7200.0, abs=0.01)
    assert len(doc["track"]) > 280
    assert doc["weather"]["is_demo"] is False


def test_human_summary_names_landing_ellipse_and_coverages(
    grib_files: list[Path], cache: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*base_args(grib_files, cache), "--payload", "superbit-test", "--probability", "0.95"]) == 0
    out = capsys.readouterr().out
    assert out.startswith("release   2024-05-01T02:00:00Z  51.00000, -0.30000  28000 m")
    assert "landing   " in out and "sea level" in out
    for text in ("39.3 %", "86.5 %", "98.9 %", "95.0 %", "superbit-test: 1.608 kg"):
        assert text in out


def test_overrides_drift_and_step_reach_the_prediction(
    grib_files: list[Path], cache: str, capsys: pytest.CaptureFixture[str]
) -> None:
    args = [*base_args(grib_files, cache), "--mass", "2.5", "--cda", "0.9", "--step", "50",
            "--drift-minutes", "10", "--json"]  # fmt: skip
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["payload"]["mass_kg"] == 2.5 and doc["payload"]["cda_m2"] == 0.9
    assert doc["step_m"] == 50.0
    assert doc["decision"]["time"] == "2024-05-01T02:00:00Z"
    assert doc["release"]["time"] == "2024-05-01T02:10:00Z"


def test_kml_geojson_and_ensemble_from_the_cli(
    grib_files: list[Path], cache: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    kml, geo = tmp_path / "out.kml", tmp_path / "out.geojson"
    args = [
        *base_args(grib_files, cache),
        "--members",
        "200",
        "--kml",
        str(kml),
        "--geojson",
        str(geo),
        "--json",
    ]
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["ensemble"]["members"] == 200
    assert doc["ensemble"]["empirical_ellipse"]["sigma_parallel_km"] > 0.5
    assert ET.parse(kml).getroot().tag.endswith("kml")
    assert json.loads(geo.read_text())["type"] == "FeatureCollection"


def test_terrain_directory_from_the_cli(
    grib_files: list[Path], cache: str, tmp_path: Path, shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Weather over the Alps tile N47E009 (the real SRTM3 tile of the shared data).
    dem = tmp_path / "dem"
    dem.mkdir()
    shutil.copy(shared_data / "dem/srtm3_N47E009_hgt-elevation/137.hgt", dem / "N47E009.hgt")
    lats, lons = np.arange(44.0, 51.01, 0.5), np.arange(5.0, 14.01, 0.5)
    shape = (LEVELS_HPA.size, lats.size, lons.size)
    gh = np.broadcast_to((-H_ISO * np.log(LEVELS_HPA / P0_HPA))[:, None, None], shape)
    files = [
        write_gfs_grib2(tmp_path / gfs_file_name(CYCLE, s), CYCLE, s, LEVELS_HPA, lats, lons,
                        np.full(shape, 3.0), np.zeros(shape), np.full(shape, T_ISO), gh)
        for s in (0, 3)
    ]  # fmt: skip
    args = ["predict", "--weather", *map(str, files), "--cache-dir", cache, "--dem", str(dem),
            "--lat", "47.4", "--lon", "9.3", "--alt", "25000", "--time", "2024-05-01T01:00Z",
            "--json"]  # fmt: skip
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["terrain_source"] == "SRTM3 N47E009"
    terrain = Terrain.from_dir(dem)
    ground = float(terrain.elevation(doc["landing"]["lat"], doc["landing"]["lon"]))
    assert doc["landing"]["alt_m"] == pytest.approx(ground, abs=25.0)
    assert doc["landing"]["alt_m"] > 300.0


@pytest.mark.parametrize(
    ("change", "message", "status"),
    [
        ({"--lat": None}, "drs: error: drs predict needs --lat\n", 2),
        ({"--weather": None}, "drs: error: drs predict needs --weather (or --demo-weather)\n", 2),
        ({"--time": "yesterday"}, "drs: error: --time 'yesterday' is not an ISO 8601 time", 2),
        ({"--time": "2024-05-01T02:00"}, "has no time zone; give UTC explicitly", 2),
        (
            {"--time": "2024-05-03T02:00Z"},
            "drs: error: the release point needs weather at 2024-05-03T02:00:00Z",
            1,
        ),
        ({"--lat": "44.0"}, "is outside the weather region", 1),
        ({"--alt": "-3"}, "drs: error: release altitude must be a positive number", 1),
        ({"--alt": "90000"}, "above the weather's top level", 1),
    ],
)
def test_bad_input_is_one_line_with_its_exit_status(
    grib_files: list[Path],
    cache: str,
    capsys: pytest.CaptureFixture[str],
    change: dict,
    message: str,
    status: int,
) -> None:
    """A command line that cannot mean anything exits 2; one the weather cannot answer failed, 1."""
    args = base_args(grib_files, cache)
    for flag, value in change.items():
        i = args.index(flag)
        if value is None:
            end = next(j for j in range(i + 1, len(args)) if args[j].startswith("--"))
            del args[i:end]
        else:
            args[i + 1] = value
    assert main(args) == status
    err = capsys.readouterr().err
    assert message in err
    assert err.count("\n") == 1 and "Traceback" not in err


def test_missing_weather_file_is_one_line(
    cache: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    args = ["predict", "--weather", str(tmp_path / "nope.grib2"), "--cache-dir", cache,
            "--lat", "1", "--lon", "1", "--alt", "1000", "--time", "2024-05-01T00:00Z"]  # fmt: skip
    assert main(args) == 1
    err = capsys.readouterr().err
    assert err.startswith("drs: error: weather file") and err.count("\n") == 1


def test_unwritable_kml_is_one_line(
    grib_files: list[Path], cache: str, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    assert main([*base_args(grib_files, cache), "--kml", str(tmp_path / "no" / "x.kml")]) == 1
    assert "drs: error: cannot write the KML file" in capsys.readouterr().err


@pytest.mark.parametrize(
    ("name", "lat", "lon", "when"),
    [
        ("gfs.t12z.pgrbf120.2p5deg.grib2", 51.5, -0.1, "2011-01-15T12:00Z"),
        ("gfs.t12z.pgrbf120.2p5deg.grib2", -44.7, 169.1, "2011-01-15T12:00Z"),
        ("gfs.grb", 46.5, 6.6, "2011-10-11T00:00Z"),
    ],
)
def test_real_gfs_sample_files_give_a_plausible_descent(
    shared_data: Path,
    cache: str,
    capsys: pytest.CaptureFixture[str],
    name: str,
    lat: float,
    lon: float,
    when: str,
) -> None:
    path = shared_data / "weather/pygrib_sampledata" / name
    args = ["predict", "--weather", str(path), "--cache-dir", cache, "--lat", str(lat), "--lon", str(lon),
            "--alt", "28000", "--time", when, "--json"]  # fmt: skip
    assert main(args) == 0
    doc = json.loads(capsys.readouterr().out)
    assert 1500.0 < doc["descent_s"] < 5000.0
    assert 0.5 < doc["drift_km"] < 400.0
    assert doc["t_future_mean_h"] >= 72.0
    assert any("held at its nearest valid time" in w for w in doc["warnings"])
    assert -180.0 <= doc["landing"]["lon"] < 180.0


def test_the_bench_ensemble_is_bounded_like_the_real_one(capsys: pytest.CaptureFixture[str]) -> None:
    """A user-sized ensemble everywhere: --members was bounded (10 million grew to 24 GB), --bench-members not."""
    assert main(["predict", "bench", "--bench-members", "10000000", "--skip-compile"]) == 2
    assert "--bench-members 10000000: give 1 to 100,000" in capsys.readouterr().err


def test_bench_prints_every_measured_figure(capsys: pytest.CaptureFixture[str]) -> None:
    args = [
        "predict",
        "bench",
        "--repeats",
        "3",
        "--ensemble-repeats",
        "1",
        "--bench-members",
        "20",
        "--skip-compile",
    ]
    assert main(args) == 0
    out = capsys.readouterr().out
    for text in (
        "load cold",
        "load from cache",
        "one prediction",
        "20-member perturbed ensemble",
        "over 3 runs",
        "whole process: drs --help",
        "whole process: drs predict (cached weather, warm numba cache)",
        "× python -c 'import argparse'",
        "× python -c 'import numpy, scipy.optimize'",
    ):
        assert text in out


def test_demo_weather_prediction_says_demo_everywhere(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    args = ["predict", "--demo-weather", "--lat", "46.5", "--lon", "6.6", "--alt", "28000",
            "--time", "2024-05-01T07:00Z"]  # fmt: skip
    assert main(args) == 0
    out = capsys.readouterr().out
    assert out.startswith("*** DEMO WEATHER")
    assert main([*args, "--json"]) == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["is_demo"] is True and doc["warnings"][0].startswith("DEMO WEATHER")
    assert 20.0 < doc["descent_s"] / 60.0 < 80.0


def test_weather_and_demo_weather_together_is_refused(
    grib_files: list[Path], cache: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*base_args(grib_files, cache), "--demo-weather"]) == 2
    assert "give either --weather or --demo-weather, not both" in capsys.readouterr().err

"""Demo weather: a generated atmosphere that loads like GFS and always says it is DEMO."""

from __future__ import annotations

import json
import subprocess
import sys
import time
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from predictor.environment.cube import WeatherCube
from predictor.environment.demo_weather import demo_weather_files, isa_height_and_temperature
from predictor.environment.weather import DEMO_SOURCE, load_weather
from predictor.errors import WeatherError

START = datetime(2026, 11, 22, 7, 40, tzinfo=UTC)


def test_standard_atmosphere_matches_icao_tables() -> None:
    height, temperature = isa_height_and_temperature(
        np.array([1013.25, 500.0, 226.32, 54.749, 8.6802, 1.109])
    )
    np.testing.assert_allclose(height, [0.0, 5574.0, 11000.0, 20000.0, 32000.0, 47000.0], atol=2.0)
    np.testing.assert_allclose(temperature, [288.15, 251.9, 216.65, 216.65, 228.65, 270.65], atol=0.1)


@pytest.fixture(scope="module")
def geneva_files(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return demo_weather_files(46.5, 6.6, START, tmp_path_factory.mktemp("demo"))


@pytest.fixture(scope="module")
def geneva_cube(geneva_files: list[Path], tmp_path_factory: pytest.TempPathFactory) -> WeatherCube:
    return load_weather(geneva_files, cache_dir=tmp_path_factory.mktemp("cache"))


def test_demo_files_cover_the_release_and_twelve_hours_after(
    geneva_files: list[Path], geneva_cube: WeatherCube
) -> None:
    files = geneva_files
    assert [f.name for f in files] == [f"gfs.t06z.pgrb2.0p50.f{s:03d}" for s in range(0, 16, 3)]
    cube = geneva_cube
    assert cube.is_demo and cube.source == DEMO_SOURCE
    release = np.datetime64(START.replace(tzinfo=None), "s")
    assert cube.times[0] <= release and cube.times[-1] >= release + np.timedelta64(12, "h")
    assert cube.covers(46.5, 6.6) and cube.covers(52.0, 12.0) and cube.covers(41.0, 1.0)


def test_demo_atmosphere_has_a_jet_near_250_hpa_and_reaches_above_45_km(geneva_cube: WeatherCube) -> None:
    cube = geneva_cube
    strongest = cube.levels_hpa[np.argmax(np.abs(cube.u).max(axis=(0, 2, 3)))]
    assert 200.0 <= strongest <= 300.0
    assert 35.0 <= cube.u.max() <= 45.0
    stratosphere = cube.levels_hpa <= 20.0
    assert np.abs(cube.u[:, stratosphere]).max() < 8.0 and np.abs(cube.v).max() < 8.0
    assert (
        cube.z_m[:, -1].min() > 45_000.0 and 30_000.0 < cube.z_m[0, cube.levels_hpa == 10.0].mean() < 32_500.0
    )
    # The jet meanders: it is not the same wind everywhere or at every step.
    jet = cube.u[:, cube.levels_hpa == 250.0]
    assert np.ptp(jet) > 10.0 and np.abs(np.diff(jet, axis=0)).max() > 0.5


def test_second_call_reuses_the_files(geneva_files: list[Path]) -> None:
    first = geneva_files
    stamps = [f.stat().st_mtime_ns for f in first]
    again = demo_weather_files(46.5, 6.6, START + timedelta(minutes=5), first[0].parent.parent)
    assert again == first and [f.stat().st_mtime_ns for f in again] == stamps
    assert not list(first[0].parent.glob("*.partial"))


@pytest.mark.parametrize(("lat", "lon"), [(-33.9, -70.6), (0.2, 179.9), (69.0, -50.8)])
def test_demo_weather_anywhere_on_earth(tmp_path: Path, lat: float, lon: float) -> None:
    start = datetime(2026, 1, 1, 23, 0)  # naive means UTC
    cube = load_weather(
        demo_weather_files(lat, lon, start, tmp_path, hours=1, half_width_deg=2.0),
        cache_dir=tmp_path / "cache",
    )
    assert cube.covers(lat, lon) and cube.is_demo
    assert cube.times[0] == np.datetime64("2026-01-01T18:00") and cube.times[-1] >= np.datetime64(
        "2026-01-02T00:00"
    )
    assert np.isfinite(cube.u).all() and (cube.density > 0).all()


def test_the_demo_atmosphere_is_one_field_whatever_region_or_span_a_call_writes(tmp_path: Path) -> None:
    """`drs serve predictor` and `drs predict` once wrote differently centred files over different spans,
    and the air differed with them (their landings were 857 m apart)."""
    a = load_weather(
        demo_weather_files(52.2, -0.4, START, tmp_path / "a", hours=12), cache_dir=tmp_path / "ca"
    )
    b = load_weather(
        demo_weather_files(
            50.0, 3.0, START + timedelta(hours=5), tmp_path / "b", hours=3, half_width_deg=6.0
        ),
        cache_dir=tmp_path / "cb",
    )
    times = np.intersect1d(a.times, b.times)
    lats, lons = np.intersect1d(a.lats, b.lats), np.intersect1d(a.lons, b.lons)
    assert times.size >= 1 and lats.size > 10 and lons.size > 10

    def part(cube: WeatherCube, field: np.ndarray) -> np.ndarray:
        ti = np.isin(cube.times, times)
        return field[ti][:, :, np.isin(cube.lats, lats)][:, :, :, np.isin(cube.lons, lons)]

    for name in ("u", "v", "z_m", "density"):
        np.testing.assert_array_equal(part(a, getattr(a, name)), part(b, getattr(b, name)), err_msg=name)


@pytest.mark.parametrize(
    ("lat", "lon"), [(-89.7, 10.0), (89.7, -120.0), (-78.0, 166.7), (-85.0, 30.0), (-90.0, 0.0)]
)
def test_releases_near_the_poles_predict_on_demo_weather(
    lat: float,
    lon: float,
    capsys: pytest.CaptureFixture[str],
    monkeypatch: pytest.MonkeyPatch,
    tmp_path: Path,
) -> None:
    """A 16°-wide box once left the descent at ±89.7°: near a pole the weather covers every longitude."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path))
    argv = ["predict", "--demo-weather", "--lat", str(lat), "--lon", str(lon), "--alt", "35000",
            "--time", "2026-12-01T06:00Z", "--json", "--cache-dir", str(tmp_path / "cache")]  # fmt: skip
    assert main(argv) == 0
    landing = json.loads(capsys.readouterr().out)["landing"]
    assert abs(landing["lat"]) <= 90.0 and abs(landing["lat"] - lat) < 1.0


@pytest.mark.parametrize("hours", [float("inf"), 1e300, 73, -1])
def test_a_span_no_flight_needs_is_refused_before_any_file_is_written(tmp_path: Path, hours: float) -> None:
    """#24 item 6: one request asked for 282 files; infinity raised an OverflowError."""
    with pytest.raises(WeatherError, match="demo weather is written for 0 to 72 hours"):
        demo_weather_files(46.0, 6.0, START, tmp_path, hours=hours)  # type: ignore[arg-type]
    assert not any(tmp_path.iterdir())


WRITER = """
import sys, time
from datetime import datetime, UTC
from pathlib import Path
from predictor.environment.demo_weather import demo_weather_files
go = Path(sys.argv[2])
Path(sys.argv[3]).touch()
while not go.exists():
    time.sleep(0.005)
files = demo_weather_files(46.5, 6.6, datetime(2026, 11, 22, 7, 40, tzinfo=UTC), sys.argv[1], hours=3)
print(" ".join(str(f) for f in files))
"""


def test_processes_making_the_same_cold_files_at_once_each_get_whole_files(tmp_path: Path) -> None:
    """Four writers of one cold entry, released together: the suite's workers, or a console and a `drs
    predict`, share one cache. They once wrote one shared ``.partial`` name: a writer's rename then
    found it gone (or renamed another's half-written file)."""
    go = tmp_path / "go"
    ready = [tmp_path / f"ready-{index}" for index in range(4)]
    writers = [
        subprocess.Popen(
            [sys.executable, "-c", WRITER, str(tmp_path / "cache"), str(go), str(mark)],
            stdout=subprocess.PIPE,
            stderr=subprocess.PIPE,
            text=True,
        )  # fmt: skip
        for mark in ready
    ]
    deadline = time.monotonic() + 120
    while not all(mark.exists() for mark in ready) and time.monotonic() < deadline:
        time.sleep(0.01)  # each has imported the writer and waits for the go
    go.touch()
    answers = [writer.communicate(timeout=120) for writer in writers]
    assert [writer.returncode for writer in writers] == [0] * 4, [err for _, err in answers]
    [files] = {out.strip() for out, _ in answers}
    cube = load_weather([Path(f) for f in files.split()], cache_dir=tmp_path / "cubes")
    assert cube.is_demo and np.isfinite(cube.u).all()
    assert not list((tmp_path / "cache").rglob("*.partial"))

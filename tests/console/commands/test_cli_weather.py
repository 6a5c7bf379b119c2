"""`drs weather …` end to end: real local HTTP server, real files, one-line errors."""

from __future__ import annotations

import json
from collections.abc import Iterator
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from predictor.environment.gribwrite import GFS_LEVELS_HPA, write_gfs_grib2
from tests.predictor.environment.grib_server import GribServer


@pytest.fixture(autouse=True)
def private_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> None:
    """`drs weather info` caches cubes under XDG_CACHE_HOME: keep it out of the real home."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg-cache"))


@pytest.fixture
def server() -> Iterator[GribServer]:
    running = GribServer()
    yield running
    running.close()


def serve_cycle(server: GribServer, tmp_path: Path, cycle: datetime, steps: list[int]) -> None:
    levels = np.array(GFS_LEVELS_HPA, dtype=float)
    shape = (levels.size, 3, 3)
    gh = np.broadcast_to(np.linspace(100, 48000, levels.size)[:, None, None], shape)
    for step in steps:
        path = write_gfs_grib2(
            tmp_path / "src" / f"{cycle:%H}{step}",
            cycle,
            step,
            levels,
            [46.0, 46.5, 47.0],
            [6.0, 6.5, 7.0],
            np.zeros(shape),
            np.zeros(shape),
            np.full(shape, 250.0),
            gh,
        )
        server.bodies[f"/{cycle:%Y%m%d}/{cycle:%H}/gfs.t{cycle:%H}z.pgrb2full.0p50.f{step:03d}"] = (
            path.read_bytes()
        )


def test_fetch_downloads_the_available_cycle_and_prints_the_paths(
    server: GribServer, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    serve_cycle(server, tmp_path, datetime(2024, 4, 30, 18, tzinfo=UTC), [9, 12, 15])
    argv = ["weather", "fetch", "--time", "2024-05-01T04:00Z", "--lat", "46.5", "--lon", "6.6"]
    argv += ["--hours", "5", "--dir", str(tmp_path / "gfs"), "--url-template", server.template]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    paths = [Path(line) for line in out.splitlines()]
    assert [p.name for p in paths] == [f"gfs.t18z.pgrb2.0p50.f{s:03d}" for s in (9, 12, 15)]
    assert all(p.is_file() for p in paths)
    assert "cycles 2024-04-30 18Z, 3 files" in err
    assert main(["weather", "info", *map(str, paths)]) == 0
    assert "lead times (h): 9, 12, 15" in capsys.readouterr().out
    assert main(["weather", "info", "--json", *map(str, paths)]) == 0
    info = json.loads(capsys.readouterr().out)
    assert info["lead_h"] == [9.0, 12.0, 15.0] and info["levels_hpa"] == sorted(
        info["levels_hpa"], reverse=True
    )
    assert info["valid_times_utc"] == ["2024-05-01T03:00:00Z", "2024-05-01T06:00:00Z", "2024-05-01T09:00:00Z"]
    assert info["region"] == {"lat_min": 46.0, "lat_max": 47.0, "lon_min": 6.0, "lon_max": 7.0}
    assert info["global"] is False and info["top_altitude_m"] > 40_000


def test_fetch_in_hindsight_mixes_cycles_and_reads_the_template_from_the_environment(
    server: GribServer, tmp_path: Path, capsys: pytest.CaptureFixture[str], monkeypatch: pytest.MonkeyPatch
) -> None:
    serve_cycle(server, tmp_path, datetime(2024, 5, 1, 0, tzinfo=UTC), [3])
    serve_cycle(server, tmp_path, datetime(2024, 5, 1, 6, tzinfo=UTC), [0])
    monkeypatch.setenv("DRS_GFS_URL_TEMPLATE", server.template)
    argv = "weather fetch --time 2024-05-01T04:00Z --lat 46.5 --lon 6.6 --hours 2 --hindsight".split()
    assert main([*argv, "--dir", str(tmp_path / "gfs")]) == 0
    out, err = capsys.readouterr()
    names = [Path(line).name for line in out.splitlines()]
    assert names == ["gfs.t00z.pgrb2.0p50.f003", "gfs.t06z.pgrb2.0p50.f000"]
    assert "hindsight: cycles 2024-05-01 00Z, 2024-05-01 06Z" in err


def test_fetch_of_an_unpublished_cycle_is_a_one_line_error_without_secrets(
    server: GribServer, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    argv = ["weather", "fetch", "--time", "2024-05-01T04:00Z", "--lat", "46.5", "--lon", "6.6"]
    argv += ["--dir", str(tmp_path), "--url-template", server.template]
    assert main(argv) == 1
    err = capsys.readouterr().err
    error_lines = [line for line in err.splitlines() if line.startswith("drs: error:")]
    assert len(error_lines) == 1 and "HTTP 404" in error_lines[0] and "token=REDACTED" in error_lines[0]
    assert "SECRET42" not in err and "Traceback" not in err


def test_info_on_a_truncated_file_names_it(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    cut = tmp_path / "gfs.t06z.pgrb2.0p50.f000"
    levels = [1000.0, 500.0]
    shape = (2, 2, 2)
    full = write_gfs_grib2(
        tmp_path / "full", datetime(2024, 1, 1), 0, levels, [0, 1], [0, 1], *[np.ones(shape)] * 4
    ).read_bytes()
    cut.write_bytes(full[: len(full) - 100])
    assert main(["weather", "info", str(cut)]) == 1
    err = capsys.readouterr().err
    assert "f000: GRIB message" in err and "truncated or corrupt" in err and err.count("\n") == 1


def test_bench_reports_cold_and_cached_loads(capsys: pytest.CaptureFixture[str]) -> None:
    assert main(["weather", "bench", "--files", "2", "--size-deg", "2", "--repeat", "1"]) == 0
    out = capsys.readouterr().out
    assert "weather load (2 files, 0.5° grid, 2°×2°, 33 levels), 1 runs each, load average" in out
    assert "cold (decode + crop + cache write): median" in out and "cached (cube cache hit): median" in out

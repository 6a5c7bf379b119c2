"""GFS fetching: cycle choice at given moments, and downloads from a real HTTP server on 127.0.0.1."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import UTC, datetime, timedelta
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np
import pytest

from predictor.environment.gfs_fetch import (
    DEFAULT_URL_TEMPLATE,
    Downloader,
    ForecastFile,
    Region,
    build_url,
    latest_available_cycle,
    plan_forecast_files,
    redact_url,
)
from predictor.environment.gribwrite import GFS_LEVELS_HPA, write_gfs_grib2
from predictor.environment.weather import load_weather
from predictor.errors import WeatherError
from tests.predictor.environment.grib_server import GribServer


def utc(text: str) -> datetime:
    return datetime.fromisoformat(text).replace(tzinfo=UTC)


# --- which cycle existed when ---


@pytest.mark.parametrize(
    ("moment", "cycle"),
    [
        ("2024-05-01T04:00", "2024-04-30T18:00"),  # 00Z is not complete until 05:00
        ("2024-05-01T04:59", "2024-04-30T18:00"),
        ("2024-05-01T05:00", "2024-05-01T00:00"),
        ("2024-05-01T10:30", "2024-05-01T00:00"),
        ("2024-05-01T11:00", "2024-05-01T06:00"),
        ("2024-05-01T23:59", "2024-05-01T18:00"),
        ("2024-01-01T02:00", "2023-12-31T18:00"),  # across a year boundary
    ],
)
def test_latest_available_cycle_waits_five_hours(moment: str, cycle: str) -> None:
    assert latest_available_cycle(utc(moment)) == utc(cycle)


def test_real_time_plan_uses_one_cycle_and_brackets_the_window() -> None:
    plan = plan_forecast_files(utc("2024-05-01T04:00"), 6)
    assert {item.cycle for item in plan} == {utc("2024-04-30T18:00")}
    assert [item.step_h for item in plan] == [9, 12, 15, 18]  # valid 03:00 … 12:00 brackets 04:00 … 10:00
    assert plan[0].valid <= utc("2024-05-01T04:00") and plan[-1].valid >= utc("2024-05-01T10:00")


def test_hindsight_plan_takes_the_freshest_cycle_for_each_valid_time() -> None:
    plan = plan_forecast_files(utc("2024-05-01T04:00"), 6, hindsight=True)
    valids = [item.valid for item in plan]
    assert valids == [utc("2024-05-01T03:00") + timedelta(hours=3 * k) for k in range(4)]
    cycles = ["2024-05-01T00:00", "2024-05-01T06:00", "2024-05-01T06:00", "2024-05-01T12:00"]
    assert [item.cycle for item in plan] == [utc(text) for text in cycles]
    assert [item.step_h for item in plan] == [3, 0, 3, 0]


def test_plan_needs_a_time_zone() -> None:
    with pytest.raises(WeatherError, match="time zone"):
        plan_forecast_files(datetime(2024, 5, 1, 4), 6)


def test_region_around_a_point_snaps_outward_and_crosses_greenwich() -> None:
    region = Region.around(51.5, -0.1, 300.0)
    assert region.lat_min == 48.5 and region.lat_max == 54.5
    assert region.lon_min < -4.0 and region.lon_max > 4.0 and region.lon_min % 0.5 == 0.0
    url = build_url(DEFAULT_URL_TEMPLATE, ForecastFile(utc("2024-05-01T06:00"), 3), region, "0p50")
    assert url.startswith(
        "https://nomads.ncep.noaa.gov/cgi-bin/filter_gfs_0p50.pl?dir=%2Fgfs.20240501%2F06%2Fatmos"
    )
    assert "file=gfs.t06z.pgrb2full.0p50.f003" in url and "lev_1_mb=on" in url and "var_VGRD=on" in url
    assert f"leftlon={region.lon_min % 360:g}" in url and f"rightlon={region.lon_max:g}" in url
    assert Region.around(89.0, 10.0, 100.0).lon_max - Region.around(89.0, 10.0, 100.0).lon_min >= 359.0


def test_redacted_url_keeps_no_secret() -> None:
    url = "https://user:hunter2@example.org/x.pl?file=a&token=abc123&apikey=zzz&lev=1"
    safe = redact_url(url)
    assert "hunter2" not in safe and "abc123" not in safe and "zzz" not in safe and "user" not in safe
    assert safe.startswith("https://example.org/x.pl?file=a&token=REDACTED")


# --- downloads against a real local server ---


@pytest.fixture
def server() -> Iterator[GribServer]:
    running = GribServer()
    yield running
    running.close()


CYCLE = utc("2024-05-01T06:00")
REGION = Region(45.0, 47.0, 6.0, 8.0)


def grib_bytes(tmp_path: Path, step: int) -> bytes:
    levels = np.array(GFS_LEVELS_HPA, dtype=float)
    shape = (levels.size, 5, 5)
    gh = np.broadcast_to(np.linspace(100, 48000, levels.size)[:, None, None], shape)
    path = write_gfs_grib2(
        tmp_path / f"src{step}",
        CYCLE,
        step,
        levels,
        np.arange(45.0, 47.1, 0.5),
        np.arange(6.0, 8.1, 0.5),
        np.full(shape, 10.0 + step),
        np.zeros(shape),
        np.full(shape, 250.0),
        gh,
    )
    return path.read_bytes()


def serve_steps(server: GribServer, tmp_path: Path, steps: list[int]) -> dict[int, str]:
    paths = {}
    for step in steps:
        paths[step] = f"/20240501/06/gfs.t06z.pgrb2full.0p50.f{step:03d}"
        server.bodies[paths[step]] = grib_bytes(tmp_path, step)
    return paths


def downloader(server: GribServer, tmp_path: Path, **options: object) -> Downloader:
    return Downloader(tmp_path / "gfs", url_template=server.template, backoff_s=0.01, timeout_s=10, **options)


def test_download_writes_complete_files_that_load(server: GribServer, tmp_path: Path) -> None:
    serve_steps(server, tmp_path, [0, 3])
    seen: list[tuple[str, int, int | None]] = []
    fetcher = downloader(server, tmp_path, progress=lambda *update: seen.append(update))
    files = fetcher.fetch_all([ForecastFile(CYCLE, 0), ForecastFile(CYCLE, 3)], REGION)
    assert [f.name for f in files] == ["gfs.t06z.pgrb2.0p50.f000", "gfs.t06z.pgrb2.0p50.f003"]
    assert files[0].parent == tmp_path / "gfs" / "gfs.20240501" / "06" / REGION.tag
    cube = load_weather(files, cache_dir=tmp_path / "cache")
    assert cube.lead_h.tolist() == [0.0, 3.0] and cube.u[1, 0, 0, 0] == 13.0
    assert seen and seen[-1][1] == seen[-1][2] == files[1].stat().st_size
    assert not list(files[0].parent.glob("*.part"))


def test_complete_files_are_not_downloaded_again(server: GribServer, tmp_path: Path) -> None:
    serve_steps(server, tmp_path, [0])
    fetcher = downloader(server, tmp_path)
    first = fetcher.fetch(ForecastFile(CYCLE, 0), REGION)
    assert len(server.requests) == 1
    again = fetcher.fetch(ForecastFile(CYCLE, 0), REGION)
    assert again == first and len(server.requests) == 1


def test_dropped_connection_is_resumed_with_a_range_request(server: GribServer, tmp_path: Path) -> None:
    paths = serve_steps(server, tmp_path, [3])
    server.drop_once.add(paths[3])
    path = downloader(server, tmp_path).fetch(ForecastFile(CYCLE, 3), REGION)
    assert path.read_bytes() == server.bodies[paths[3]]
    assert server.requests[0] == (paths[3], None)
    half = len(server.bodies[paths[3]]) // 2
    assert server.requests[1] == (paths[3], f"bytes={half}-")


def test_truncated_file_fails_the_completeness_check_and_is_fetched_again(
    server: GribServer, tmp_path: Path
) -> None:
    paths = serve_steps(server, tmp_path, [6])
    server.truncate_times[paths[6]] = 2
    path = downloader(server, tmp_path).fetch(ForecastFile(CYCLE, 6), REGION)
    assert path.read_bytes() == server.bodies[paths[6]] and len(server.requests) == 3
    assert all(header is None for _, header in server.requests)  # a corrupt body is never resumed


def test_file_that_stays_truncated_is_an_error_after_the_retries(server: GribServer, tmp_path: Path) -> None:
    paths = serve_steps(server, tmp_path, [6])
    server.truncate_times[paths[6]] = 99
    with pytest.raises(
        WeatherError,
        match=r"could not download gfs\.t06z\.pgrb2\.0p50\.f006 .* after 3 attempts: "
        r"the downloaded file failed the GRIB completeness check",
    ) as caught:
        downloader(server, tmp_path, retries=2).fetch(ForecastFile(CYCLE, 6), REGION)
    assert "SECRET42" not in str(caught.value) and len(server.requests) == 3
    assert not list((tmp_path / "gfs").rglob("gfs.t06z.pgrb2.0p50.f006"))


def test_missing_file_is_a_404_error_naming_the_url_without_secrets(
    server: GribServer, tmp_path: Path
) -> None:
    with pytest.raises(
        WeatherError,
        match=r"HTTP 404 Not Found for http://127\.0\.0\.1:\d+/20240501/06/"
        r"gfs\.t06z\.pgrb2full\.0p50\.f009\?l=6&r=8&token=REDACTED \(not published yet",
    ) as caught:
        downloader(server, tmp_path).fetch(ForecastFile(CYCLE, 9), REGION)
    assert "SECRET42" not in str(caught.value)
    assert len(server.requests) == 1  # a 404 is not retried


def test_unreachable_server_is_retried_then_reported(tmp_path: Path) -> None:
    closed = ThreadingHTTPServer(("127.0.0.1", 0), BaseHTTPRequestHandler)
    port = closed.server_address[1]
    closed.server_close()  # nothing listens on this port any more
    fetcher = Downloader(
        tmp_path, url_template=f"http://127.0.0.1:{port}/{{remote_file}}", retries=1, backoff_s=0.01
    )
    with pytest.raises(WeatherError, match=r"after 2 attempts: cannot connect"):
        fetcher.fetch(ForecastFile(CYCLE, 0), REGION)


def test_unknown_resolution_and_bad_template_are_refused(tmp_path: Path) -> None:
    with pytest.raises(WeatherError, match="resolution '1p00' is not one of 0p50, 0p25"):
        Downloader(tmp_path, resolution="1p00")
    with pytest.raises(WeatherError, match="unknown or malformed placeholder"):
        build_url("http://127.0.0.1/{nonsense}", ForecastFile(CYCLE, 0), REGION, "0p50")

"""`drs weather prune`: a real cache of GRIB files, real cube-cache entries, real fetches on 127.0.0.1."""

from __future__ import annotations

import fcntl
import json
import os
import re
import shutil
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime, timedelta
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from console.commands.weather import default_gfs_dir
from predictor.environment.gfs_cache import LOCK_NAME, free_space_warning, prune
from predictor.environment.gfs_fetch import Downloader, ForecastFile, Region
from predictor.environment.gribwrite import GFS_LEVELS_HPA, write_gfs_grib2
from predictor.environment.weather import load_weather
from predictor.errors import WeatherError
from tests.console.commands.test_cli_weather import serve_cycle
from tests.predictor.environment.grib_server import GribServer

NOW = datetime(2024, 6, 1, 12, tzinfo=UTC)
REGION = Region(45.0, 46.0, 6.0, 7.0)
DAY = timedelta(days=1)


def wait_for(condition: Callable[[], bool], what: str, timeout_s: float = 20.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(0.01)


def set_written(path: Path, when: datetime) -> None:
    """Every file below ``path`` last written at ``when`` (what the download time was)."""
    for file in [path] if path.is_file() else [p for p in path.rglob("*") if p.is_file()]:
        os.utime(file, (when.timestamp(), when.timestamp()))


def cache_cycle(
    root: Path, cycle: datetime, written: datetime, steps: tuple[int, ...] = (0, 3)
) -> list[Path]:
    """Small but real GRIB files where `drs weather fetch` puts them, downloaded at ``written``."""
    layout = Downloader(root)
    files = []
    for step in steps:
        path = layout.local_path(ForecastFile(cycle, step), REGION)
        path.parent.mkdir(parents=True, exist_ok=True)
        files.append(write_grib(path, cycle, step))
        set_written(path, written)
    return files


def write_grib(
    path: Path, cycle: datetime, step: int, levels: tuple[float, ...] = (1000.0, 500.0, 100.0)
) -> Path:
    shape = (len(levels), 3, 3)
    gh = np.broadcast_to(np.linspace(100.0, 16000.0, len(levels))[:, None, None], shape)
    lats, lons = [45.0, 45.5, 46.0], [6.0, 6.5, 7.0]
    return write_gfs_grib2(
        path,
        cycle,
        step,
        np.array(levels),
        lats,
        lons,
        np.full(shape, 5.0 + step),
        np.zeros(shape),
        np.full(shape, 250.0),
        gh,
    )


def tree_bytes(path: Path) -> int:
    return sum(p.stat().st_size for p in path.rglob("*") if p.is_file())


def snapshot(*roots: Path) -> dict[Path, tuple[int, int]]:
    return {
        p: (p.stat().st_size, p.stat().st_mtime_ns) for root in roots for p in root.rglob("*") if p.is_file()
    }


def cycle_dir(root: Path, cycle: datetime) -> Path:
    return root / f"gfs.{cycle:%Y%m%d}" / f"{cycle:%H}"


# --- age limit ---


def test_cycles_older_than_the_keep_window_go_and_the_window_is_kept_to_the_second(tmp_path: Path) -> None:
    root = tmp_path / "gfs"
    keep_from = NOW - 10 * DAY
    old = datetime(2024, 5, 1, 6, tzinfo=UTC)
    older_by_a_second = datetime(2024, 5, 22, 0, tzinfo=UTC)
    on_the_edge = datetime(2024, 5, 22, 6, tzinfo=UTC)
    recent = datetime(2024, 5, 31, 18, tzinfo=UTC)
    hindsight = datetime(2024, 4, 1, 0, tzinfo=UTC)  # an old cycle fetched yesterday for an analysis
    cache_cycle(root, old, old + timedelta(hours=4))
    cache_cycle(root, older_by_a_second, keep_from - timedelta(seconds=1))
    cache_cycle(root, on_the_edge, keep_from)
    cache_cycle(root, recent, recent + timedelta(hours=5))
    cache_cycle(root, hindsight, NOW - DAY)
    sizes = {c: tree_bytes(cycle_dir(root, c)) for c in (old, older_by_a_second)}

    result = prune(root, tmp_path / "cubes", keep_days=10, max_bytes=None, now=NOW)

    assert [c.name for c in result.removed] == ["gfs.20240501/06", "gfs.20240522/00"]
    assert not (root / "gfs.20240501").exists()  # the day's only cycle: its directory goes too
    assert not cycle_dir(root, older_by_a_second).exists() and (root / "gfs.20240522" / "06").is_dir()
    for kept in (on_the_edge, recent, hindsight):
        assert len(list(cycle_dir(root, kept).rglob("gfs.t*"))) == 2
    assert [c.name for c in result.kept] == ["gfs.20240401/00", "gfs.20240522/06", "gfs.20240531/18"]
    assert result.freed_bytes == sum(sizes.values()) and result.bytes_after == tree_bytes(root)
    assert result.keep_from == keep_from and not result.skipped


def test_dry_run_names_what_a_real_run_removes_and_changes_nothing(tmp_path: Path) -> None:
    root, cubes = tmp_path / "gfs", tmp_path / "cubes"
    old_files = cache_cycle(root, datetime(2024, 5, 1, 6, tzinfo=UTC), datetime(2024, 5, 1, 11, tzinfo=UTC))
    cache_cycle(root, datetime(2024, 5, 31, 0, tzinfo=UTC), datetime(2024, 5, 31, 5, tzinfo=UTC))
    load_weather(old_files, cache_dir=cubes)
    before = snapshot(root, cubes)

    dry = prune(root, cubes, keep_days=7, max_bytes=None, dry_run=True, now=NOW)
    assert snapshot(root, cubes) == before
    assert not list(root.rglob(LOCK_NAME))  # not even a lock file is left behind

    real = prune(root, cubes, keep_days=7, max_bytes=None, now=NOW)
    assert [c.name for c in dry.removed] == [c.name for c in real.removed] == ["gfs.20240501/06"]
    assert [e.path for e in dry.removed_entries] == [e.path for e in real.removed_entries]
    assert len(real.removed_entries) == 1 and not list(cubes.glob("*.npz"))
    assert dry.freed_bytes == real.freed_bytes > 0


# --- size limit ---


def test_size_limit_removes_the_oldest_cycles_until_under_it(tmp_path: Path) -> None:
    root = tmp_path / "gfs"
    cycles = [datetime(2024, 5, d, 0, tzinfo=UTC) for d in (3, 9, 12, 20)]
    for cycle in cycles:
        cache_cycle(root, cycle, cycle + timedelta(hours=5))
    total = tree_bytes(root)
    one = tree_bytes(cycle_dir(root, cycles[0]))
    limit = total - one - one // 2  # needs two cycles to go

    result = prune(root, tmp_path / "cubes", keep_days=None, max_bytes=limit, now=NOW)

    assert [c.name for c in result.removed] == ["gfs.20240503/00", "gfs.20240509/00"]
    assert tree_bytes(root) == result.bytes_after <= limit
    assert [c.name for c in result.kept] == ["gfs.20240512/00", "gfs.20240520/00"]


def test_size_limit_never_reaches_into_the_keep_window(tmp_path: Path) -> None:
    root = tmp_path / "gfs"
    old = datetime(2024, 5, 1, 0, tzinfo=UTC)
    launch_day = datetime(2024, 6, 1, 0, tzinfo=UTC)
    cache_cycle(root, old, old + timedelta(hours=5))
    cache_cycle(root, launch_day, launch_day + timedelta(hours=5))

    by_size = prune(root, tmp_path / "cubes", keep_days=None, max_bytes=1, now=NOW)
    assert [c.name for c in by_size.removed] == ["gfs.20240501/00"]
    assert by_size.keep_from == NOW - 2 * DAY  # a prune by size alone keeps the last two days
    assert len(list(cycle_dir(root, launch_day).rglob("gfs.t*"))) == 2 and by_size.bytes_after > 1

    both = prune(root, tmp_path / "cubes", keep_days=0.5, max_bytes=1, now=NOW)
    assert not both.removed and [c.name for c in both.kept] == ["gfs.20240601/00"]


# --- cube-cache entries ---


def test_cubes_built_from_removed_or_vanished_files_go_and_live_cubes_stay(tmp_path: Path) -> None:
    root, cubes = tmp_path / "gfs", tmp_path / "cubes"
    old = cache_cycle(root, datetime(2024, 5, 1, 6, tzinfo=UTC), datetime(2024, 5, 1, 11, tzinfo=UTC))
    recent = cache_cycle(root, datetime(2024, 5, 31, 6, tzinfo=UTC), datetime(2024, 5, 31, 11, tzinfo=UTC))
    own = write_grib(
        tmp_path / "mine" / "analysis.grib2", datetime(2024, 3, 1, tzinfo=UTC), 0
    )  # not in the cache
    gone = write_grib(tmp_path / "mine" / "deleted.grib2", datetime(2024, 3, 2, tzinfo=UTC), 0)
    for files in (old, recent, [own], [gone]):
        load_weather(files, cache_dir=cubes)
    gone.unlink()
    older_format = {"source": "GFS 0.50° cycle 2024-02-01 00Z", "is_demo": False, "warnings": []}
    np.savez(cubes / ("0" * 32 + ".npz"), meta=np.array(json.dumps(older_format)))  # no source record
    (cubes / ("1" * 32 + ".npz")).write_bytes(b"PK\x03\x04 damaged")
    assert len(list(cubes.glob("*.npz"))) == 6

    result = prune(root, cubes, keep_days=7, max_bytes=None, now=NOW)

    assert [c.name for c in result.removed] == ["gfs.20240501/06"]
    assert len(result.removed_entries) == 4  # of the removed cycle, the deleted file, older, damaged
    survivors = sorted(cubes.glob("*.npz"))
    assert len(survivors) == 2
    for files in (recent, [own]):  # both still load from the cache: no new entry appears
        load_weather(files, cache_dir=cubes)
    assert sorted(cubes.glob("*.npz")) == survivors


# --- partial downloads and fetches in progress ---


class StallingServer:
    """A real HTTP server that sends the first ``first_bytes`` of a GRIB body, then waits for ``release``."""

    def __init__(self, body: bytes, first_bytes: int) -> None:
        self.release = threading.Event()
        server = self

        class Handler(BaseHTTPRequestHandler):
            def log_message(self, *args: object) -> None:
                pass

            def do_GET(self) -> None:  # noqa: N802 - http.server's name
                self.send_response(200)
                self.send_header("Content-Length", str(len(body)))
                self.end_headers()
                self.wfile.write(body[:first_bytes])
                self.wfile.flush()
                server.release.wait(timeout=60)
                self.wfile.write(body[first_bytes:])

        self.httpd = ThreadingHTTPServer(("127.0.0.1", 0), Handler)
        self.thread = threading.Thread(target=self.httpd.serve_forever, daemon=True)
        self.thread.start()

    @property
    def template(self) -> str:
        return f"http://127.0.0.1:{self.httpd.server_address[1]}/{{remote_file}}"

    def close(self) -> None:
        self.release.set()
        self.httpd.shutdown()
        self.httpd.server_close()
        self.thread.join()


def full_gfs_body(tmp_path: Path, cycle: datetime) -> bytes:
    """All 33 levels (the completeness check wants 132 messages) on a grid big enough to exceed 64 KiB."""
    levels = np.array(GFS_LEVELS_HPA, dtype=float)
    grid = np.arange(45.0, 52.6, 0.5)
    shape = (levels.size, grid.size, grid.size)
    gh = np.broadcast_to(np.linspace(100.0, 48000.0, levels.size)[:, None, None], shape)
    path = write_gfs_grib2(
        tmp_path / "body.grib2",
        cycle,
        0,
        levels,
        grid,
        grid,
        np.ones(shape),
        np.zeros(shape),
        np.full(shape, 250.0),
        gh,
    )
    return path.read_bytes()


class BackgroundFetch:
    """`Downloader.fetch` of one file in a thread, against a stalling server."""

    def __init__(self, tmp_path: Path, root: Path, cycle: datetime) -> None:
        self.body = full_gfs_body(tmp_path, cycle)
        assert len(self.body) > 2 * 65536
        self.server = StallingServer(self.body, first_bytes=70_000)
        self.downloader = Downloader(root, url_template=self.server.template, retries=0, timeout_s=30)
        self.item = ForecastFile(cycle, 0)
        self.target = self.downloader.local_path(self.item, REGION)
        self.part = self.target.with_name(self.target.name + ".part")
        self.outcome: list[object] = []
        self.thread = threading.Thread(target=self._run, daemon=True)

    def _run(self) -> None:
        try:
            self.outcome.append(self.downloader.fetch(self.item, REGION))
        except Exception as exc:  # reported by finish()
            self.outcome.append(exc)

    def start(self) -> None:
        self.thread.start()

    def finish(self) -> Path:
        self.server.release.set()
        self.thread.join(timeout=60)
        self.server.close()
        assert self.outcome and isinstance(self.outcome[0], Path), self.outcome
        return self.outcome[0]


@pytest.fixture
def old_cycle() -> datetime:
    """A cycle far outside any keep window of these tests, whatever day they run on."""
    return datetime(2020, 1, 1, 6, tzinfo=UTC)


def test_a_cycle_being_fetched_is_left_alone_even_when_its_partial_file_looks_old(
    tmp_path: Path, old_cycle: datetime
) -> None:
    root = tmp_path / "gfs"
    fetch = BackgroundFetch(tmp_path, root, old_cycle)
    fetch.start()
    try:
        wait_for(lambda: fetch.part.exists() and fetch.part.stat().st_size > 0, "the partial download")
        set_written(fetch.part, datetime(2020, 1, 1, 9, tzinfo=UTC))  # only the fetch's lock protects it now
        before = snapshot(root)
        for dry_run in (True, False):
            result = prune(root, tmp_path / "cubes", keep_days=1, max_bytes=None, dry_run=dry_run)
            assert not result.removed
            assert [(c.name, why) for c, why in result.skipped] == [
                ("gfs.20200101/06", "a fetch is in progress")
            ]
        assert snapshot(root) == before
    finally:
        path = fetch.finish()
    assert path.read_bytes() == fetch.body and not fetch.part.exists()


def test_a_fresh_partial_file_keeps_its_cycle_and_an_abandoned_one_goes_with_it(
    tmp_path: Path, old_cycle: datetime
) -> None:
    root = tmp_path / "gfs"
    now = datetime.now(UTC)
    busy_cycle, abandoned_cycle = old_cycle, old_cycle + timedelta(hours=6)
    busy = cache_cycle(root, busy_cycle, datetime(2020, 1, 1, 11, tzinfo=UTC))[0]
    fresh_part = busy.with_name("gfs.t06z.pgrb2.0p50.f006.part")  # a writer that takes no lock
    fresh_part.write_bytes(b"GRIB partial")
    set_written(fresh_part, now - timedelta(minutes=2))
    abandoned = cache_cycle(root, abandoned_cycle, datetime(2020, 1, 1, 17, tzinfo=UTC))[0]
    stale_part = abandoned.with_name("gfs.t12z.pgrb2.0p50.f006.part")
    stale_part.write_bytes(b"GRIB cut off in 2020")
    set_written(stale_part, datetime(2020, 1, 1, 17, tzinfo=UTC))

    # A fresh partial file makes its cycle recent, so only "keep nothing" puts it to the test.
    result = prune(root, tmp_path / "cubes", keep_days=0, max_bytes=None, now=now)

    assert [c.name for c in result.removed] == ["gfs.20200101/12"] and not stale_part.exists()
    ((skipped, why),) = result.skipped
    assert skipped.name == "gfs.20200101/06" and "partial download in it was written to" in why
    assert fresh_part.read_bytes() == b"GRIB partial" and busy.is_file()


@pytest.mark.skipif(not Path("/proc/locks").exists(), reason="needs Linux /proc/locks to see a waiting lock")
def test_a_fetch_that_waited_for_a_removal_starts_again_in_a_fresh_locked_directory(
    tmp_path: Path, old_cycle: datetime
) -> None:
    root = tmp_path / "gfs"
    cycle_path = cycle_dir(root, old_cycle)
    cycle_path.mkdir(parents=True)
    lock_path = cycle_path / LOCK_NAME
    removal = os.open(lock_path, os.O_RDWR | os.O_CREAT)
    fcntl.flock(removal, fcntl.LOCK_EX)  # what a prune holds while it removes the cycle
    inode = os.fstat(removal).st_ino
    fetch = BackgroundFetch(tmp_path, root, old_cycle)
    fetch.start()
    try:
        wait_for(
            lambda: any(
                "->" in line and f":{inode} " in line for line in Path("/proc/locks").read_text().splitlines()
            ),
            "the fetch to wait for the lock",
        )
        shutil.rmtree(cycle_path)
        os.close(removal)
        wait_for(lambda: fetch.part.exists() and fetch.part.stat().st_size > 0, "the partial download")
        set_written(fetch.part, datetime(2020, 1, 1, 9, tzinfo=UTC))
        result = prune(root, tmp_path / "cubes", keep_days=1, max_bytes=None)
        assert [(c.name, why) for c, why in result.skipped] == [("gfs.20200101/06", "a fetch is in progress")]
        assert fetch.part.exists()
    finally:
        path = fetch.finish()
    assert path.read_bytes() == fetch.body


# --- errors ---


@pytest.mark.parametrize(
    ("keep_days", "max_bytes", "message"),
    [
        (None, None, "say what to prune: --keep-days N, --max-gb X, or both"),
        (-1.0, None, "--keep-days must be between 0 and 36500 days, not -1"),
        (float("nan"), None, "--keep-days must be between 0 and 36500 days, not nan"),
        (1e9, None, "--keep-days must be between 0 and 36500 days, not 1e+09"),
        (None, 0, "the size limit must be more than 0 bytes, not 0"),
    ],
)
def test_bad_limits_are_refused_before_anything_is_touched(
    tmp_path: Path, keep_days: float | None, max_bytes: int | None, message: str
) -> None:
    root = tmp_path / "gfs"
    cache_cycle(root, datetime(2024, 5, 1, 6, tzinfo=UTC), datetime(2024, 5, 1, 11, tzinfo=UTC))
    before = snapshot(root)
    with pytest.raises(WeatherError) as caught:
        prune(root, tmp_path / "cubes", keep_days=keep_days, max_bytes=max_bytes, now=NOW)
    assert str(caught.value) == message and snapshot(root) == before


def test_missing_or_wrong_cache_directories_are_refused(tmp_path: Path) -> None:
    with pytest.raises(WeatherError, match=r"GFS cache directory .*nowhere does not exist \(see --dir"):
        prune(tmp_path / "nowhere", tmp_path / "cubes", keep_days=7, max_bytes=None)
    (tmp_path / "file").write_text("not a directory")
    with pytest.raises(WeatherError, match=r"GFS cache directory .*file is not a directory"):
        prune(tmp_path / "file", tmp_path / "cubes", keep_days=7, max_bytes=None)
    (tmp_path / "gfs").mkdir()
    with pytest.raises(
        WeatherError, match=r"weather cache directory .*file is not a directory \(see --cache-dir"
    ):
        prune(tmp_path / "gfs", tmp_path / "file", keep_days=7, max_bytes=None)


def test_other_files_in_the_cache_directory_are_left_alone(tmp_path: Path) -> None:
    root = tmp_path / "gfs"
    cache_cycle(root, datetime(2024, 5, 1, 6, tzinfo=UTC), datetime(2024, 5, 1, 11, tzinfo=UTC))
    notes = root / "notes.txt"
    notes.write_text("flight 7 weather")
    odd = root / "gfs.20240501" / "latest"
    odd.mkdir()
    set_written(notes, datetime(2020, 1, 1, tzinfo=UTC))
    result = prune(root, tmp_path / "cubes", keep_days=1, max_bytes=None, now=NOW)
    assert [c.name for c in result.removed] == ["gfs.20240501/06"]
    assert notes.read_text() == "flight 7 weather" and odd.is_dir()
    assert result.bytes_after == tree_bytes(root) > 0


# --- free space before a fetch ---


def test_free_space_warning_names_the_directory_and_is_silent_with_room(tmp_path: Path) -> None:
    free = shutil.disk_usage(tmp_path).free
    not_yet_made = tmp_path / "not" / "yet" / "gfs"
    warning = free_space_warning(not_yet_made, minimum_bytes=free + 10**12)
    assert warning is not None and str(not_yet_made) in warning and "drs weather prune" in warning
    assert free_space_warning(not_yet_made, minimum_bytes=1) is None


# --- the command ---


@pytest.fixture
def xdg_cache(tmp_path: Path, monkeypatch: pytest.MonkeyPatch) -> Path:
    """The defaults of `drs weather fetch` and of the cube cache, inside the test's directory."""
    monkeypatch.setenv("XDG_CACHE_HOME", str(tmp_path / "xdg"))
    return tmp_path / "xdg"


def test_command_uses_the_fetch_default_directory_and_dry_run_first(
    xdg_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    root = default_gfs_dir()
    assert root == xdg_cache / "drs" / "gfs"
    now = datetime.now(UTC)
    old = (now - 20 * DAY).replace(hour=0, minute=0, second=0, microsecond=0)
    recent = (now - DAY).replace(hour=0, minute=0, second=0, microsecond=0)
    old_files = cache_cycle(root, old, old + timedelta(hours=5))
    cache_cycle(root, recent, recent + timedelta(hours=5))
    load_weather(old_files, cache_dir=xdg_cache / "drs" / "weather")
    before = snapshot(xdg_cache / "drs")

    assert main(["weather", "prune", "--keep-days", "7", "--dry-run"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert re.fullmatch(
        rf"would remove gfs\.{old:%Y%m%d}/00 \(cycle {old:%Y-%m-%d} 00Z, last written {old:%Y-%m-%d} 05:00Z\): "
        r"2 files, \d+\.\d kB",
        out[0],
    )
    assert re.fullmatch(r"would remove 1 cached cube \(\d+\.\d kB\) that no load can use any more", out[1])
    assert re.fullmatch(
        r"would free \d+\.\d kB; would be left: 1 cycle, \d+\.\d kB in both caches "
        r"\(keep window from \d{4}-\d\d-\d\d \d\d:\d\dZ\)",
        out[2],
    )
    assert len(out) == 3
    assert snapshot(xdg_cache / "drs") == before

    assert main(["weather", "prune", "--keep-days", "7"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith(f"removed gfs.{old:%Y%m%d}/00") and out[2].startswith("freed ")
    assert not cycle_dir(root, old).exists() and cycle_dir(root, recent).is_dir()
    assert not list((xdg_cache / "drs" / "weather").glob("*.npz"))


def test_command_says_when_the_size_limit_cannot_be_met(
    xdg_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    today = datetime.now(UTC).replace(minute=0, second=0, microsecond=0)
    cache_cycle(default_gfs_dir(), today, today)
    assert main(["weather", "prune", "--max-gb", "0.000001"]) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0].startswith("freed 0 B; left: 1 cycle, ")
    assert out[1] == (
        "note: the caches stay over the 1.0 kB limit: what is left is inside the keep window, "
        "being fetched, or cubes of weather files still in use"
    )


PRUNE = "drs weather prune: error: argument"


@pytest.mark.parametrize(
    ("argv", "message"),
    [
        (["--max-gb", "0"], f"{PRUNE} --max-gb: 0 is not a positive number of gigabytes"),
        (["--max-gb", "nan"], f"{PRUNE} --max-gb: 'nan' is not a number of gigabytes"),
        (["--max-gb", "-5"], f"{PRUNE} --max-gb: -5 is not a positive number of gigabytes"),
        (["--keep-days", "-2"], f"{PRUNE} --keep-days: -2 is not between 0 and 36500 days"),
        ([], "drs: error: say what to prune: --keep-days N, --max-gb X, or both"),
    ],
)
def test_command_errors_are_one_line_and_exit_2(
    xdg_cache: Path, capsys: pytest.CaptureFixture[str], argv: list[str], message: str
) -> None:
    """Every one is a command-line mistake (#25 item 7): exit status 2, the option named."""
    default_gfs_dir().mkdir(parents=True)
    try:
        status = main(["weather", "prune", *argv])
    except SystemExit as exc:
        status = exc.code
    assert status == 2
    assert capsys.readouterr().err.splitlines()[-1] == message


def test_command_on_a_missing_cache_is_one_line(
    tmp_path: Path, xdg_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["weather", "prune", "--keep-days", "7", "--dir", str(tmp_path / "nothing")]) == 1
    assert capsys.readouterr().err == (
        f"drs: error: GFS cache directory {tmp_path / 'nothing'} does not exist (see --dir; nothing to prune)\n"
    )


def test_a_cycle_fetched_by_the_command_counts_as_new_until_its_download_ages(
    tmp_path: Path, xdg_cache: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    cycle = datetime(2024, 4, 30, 18, tzinfo=UTC)
    server = GribServer()
    try:
        serve_cycle(server, tmp_path, cycle, [9, 12])
        argv = ["weather", "fetch", "--time", "2024-05-01T04:00Z", "--lat", "46.5", "--lon", "6.6"]
        assert main([*argv, "--hours", "2", "--url-template", server.template]) == 0
    finally:
        server.close()
    fetched = [Path(line) for line in capsys.readouterr().out.splitlines()]
    assert len(fetched) == 2 and all(path.is_relative_to(default_gfs_dir()) for path in fetched)

    assert main(["weather", "prune", "--keep-days", "7"]) == 0  # a 2024 cycle, but downloaded just now
    assert capsys.readouterr().out.startswith("freed 0 B; left: 1 cycle, ")
    assert all(path.is_file() for path in fetched)

    set_written(default_gfs_dir(), datetime.now(UTC) - 30 * DAY)
    assert main(["weather", "prune", "--keep-days", "7"]) == 0
    out = capsys.readouterr().out
    assert (
        out.startswith("removed gfs.20240430/18 (cycle 2024-04-30 18Z, last written ")
        and ": 2 files, " in out
    )
    assert not (default_gfs_dir() / "gfs.20240430").exists()

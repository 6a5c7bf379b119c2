"""Getting GFS forecasts: which cycle and steps existed at a moment, and a robust regional download.

Why the cycle choice matters: a prediction made during a flight can only use forecasts already
published, and the error model's t_future depends on how old they are. GFS runs at 00/06/12/18 UTC
and NOMADS publishes a run's files from about 3.5 h after the cycle time until about 5 h after it.
``AVAILABILITY_DELAY`` is the conservative end of that (5 h): a cycle counts as available only when
all of it is. ``--hindsight`` instead takes, for each valid time, the freshest cycle that covers it
(what a post-flight analysis would use).

Why the NOMADS grib filter: it cuts a region and the variables we need (HGT, TMP, UGRD, VGRD on the
1000…1 mb levels) out of a several-hundred-MB global file, leaving a few hundred kB. NOAA moves its
paths from time to time, so the URL is a template (CLI option or ``DRS_GFS_URL_TEMPLATE``).

The download resumes a partial file with an HTTP Range request, retries with exponential backoff,
and accepts a file only when every GRIB message in it decodes and the message count is what was
asked for; a complete file is kept and never fetched again. While it works on a cycle it holds that
cycle against ``drs weather prune`` (``predictor.environment.gfs_cache.fetching``).
"""

from __future__ import annotations

import http.client
import math
import os
import time
import urllib.error
import urllib.parse
import urllib.request
from collections.abc import Callable, Sequence
from contextlib import ExitStack
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path

from predictor.environment.gfs_cache import PART_SUFFIX, cycle_directory, fetching
from predictor.environment.gribwrite import GFS_LEVELS_HPA, gfs_file_name
from predictor.errors import WeatherError

AVAILABILITY_DELAY = timedelta(hours=5)
CYCLE_HOURS = 6
STEP_HOURS = 3
RESOLUTIONS = ("0p50", "0p25")
URL_TEMPLATE_ENV = "DRS_GFS_URL_TEMPLATE"
DEFAULT_URL_TEMPLATE = (
    "https://nomads.ncep.noaa.gov/cgi-bin/filter_gfs_{resolution}.pl?dir=%2Fgfs.{date}%2F{hour}%2Fatmos"
    "&file={remote_file}&{levels}&var_HGT=on&var_TMP=on&var_UGRD=on&var_VGRD=on"
    "&subregion=&leftlon={left}&rightlon={right}&toplat={top}&bottomlat={bottom}"
)
"""Placeholders: resolution, date (YYYYMMDD), hour (HH), step (FFF), remote_file, levels, left, right,
top, bottom. ``left``/``right`` are in 0–360; a region across 0° has left > right, as the filter expects."""

_SECRET_KEYS = ("token", "key", "apikey", "api_key", "password", "passwd", "pass", "secret", "auth", "sig")
_CHUNK = 64 * 1024


@dataclass(frozen=True)
class ForecastFile:
    """One forecast step of one cycle: what to download."""

    cycle: datetime
    step_h: int

    @property
    def valid(self) -> datetime:
        return self.cycle + timedelta(hours=self.step_h)


@dataclass(frozen=True)
class Region:
    """A download region in degrees; lon_min < lon_max, continuous (may cross 0° or 180°)."""

    lat_min: float
    lat_max: float
    lon_min: float
    lon_max: float

    @classmethod
    def around(cls, lat: float, lon: float, radius_km: float, grid_deg: float = 0.5) -> Region:
        """The box of ±radius around a point, widened outward to whole grid cells."""
        if radius_km <= 0:
            raise WeatherError(f"--radius-km must be positive, not {radius_km:g}")
        dlat = radius_km / 111.2
        lat_min = max(-90.0, math.floor((lat - dlat) / grid_deg) * grid_deg)
        lat_max = min(90.0, math.ceil((lat + dlat) / grid_deg) * grid_deg)
        widest = max(abs(lat_min), abs(lat_max))
        dlon = 360.0 if widest >= 89.0 else radius_km / (111.2 * math.cos(math.radians(widest)))
        if dlon >= 180.0:
            return cls(lat_min, lat_max, 0.0, 360.0 - grid_deg)
        lon_min = math.floor((lon - dlon) / grid_deg) * grid_deg
        lon_max = math.ceil((lon + dlon) / grid_deg) * grid_deg
        return cls(lat_min, lat_max, lon_min, lon_max)

    @property
    def tag(self) -> str:
        """A directory name for files of this region, so different regions never share a cache entry."""
        return f"lat{self.lat_min:g}_{self.lat_max:g}_lon{self.lon_min % 360.0:g}_{self.lon_max % 360.0:g}"


def _floor_cycle(moment: datetime) -> datetime:
    moment = moment.astimezone(UTC)
    return moment.replace(hour=moment.hour - moment.hour % CYCLE_HOURS, minute=0, second=0, microsecond=0)


def latest_available_cycle(moment: datetime, delay: timedelta = AVAILABILITY_DELAY) -> datetime:
    """The newest cycle whose files were all published by ``moment``."""
    return _floor_cycle(moment - delay)


def plan_forecast_files(start: datetime, hours: float, *, hindsight: bool = False) -> list[ForecastFile]:
    """The steps whose valid times bracket [start, start + hours], from the cycle(s) the mode allows.

    Real time: one cycle, the latest available at ``start``. Hindsight: for every 3-hourly valid
    time, the freshest cycle at or before it (lead 0 or 3 h).
    """
    if start.tzinfo is None:
        raise WeatherError("the forecast time must carry a time zone (e.g. 2024-05-01T06:00Z)")
    if hours < 0:
        raise WeatherError(f"--hours must not be negative, not {hours:g}")
    start = start.astimezone(UTC)
    end = start + timedelta(hours=hours)
    if hindsight:
        first_valid = _floor_to_step(start)
        files = []
        valid = first_valid
        while True:
            cycle = _floor_cycle(valid)
            files.append(ForecastFile(cycle, int((valid - cycle) / timedelta(hours=1))))
            if valid >= end:
                return files
            valid += timedelta(hours=STEP_HOURS)
    cycle = latest_available_cycle(start)
    first = int((start - cycle) / timedelta(hours=STEP_HOURS)) * STEP_HOURS
    last = math.ceil((end - cycle) / timedelta(hours=STEP_HOURS)) * STEP_HOURS
    return [ForecastFile(cycle, step) for step in range(first, max(last, first) + 1, STEP_HOURS)]


def _floor_to_step(moment: datetime) -> datetime:
    return moment.replace(hour=moment.hour - moment.hour % STEP_HOURS, minute=0, second=0, microsecond=0)


def remote_file_name(item: ForecastFile, resolution: str) -> str:
    """NOMADS' file name: the 0.5° filter serves the ``pgrb2full`` files, the 0.25° one ``pgrb2``."""
    product = "pgrb2full" if resolution == "0p50" else "pgrb2"
    return f"gfs.t{item.cycle.hour:02d}z.{product}.{resolution}.f{item.step_h:03d}"


def build_url(template: str, item: ForecastFile, region: Region, resolution: str) -> str:
    levels = "&".join(f"lev_{level}_mb=on" for level in GFS_LEVELS_HPA)
    try:
        return template.format(
            resolution=resolution,
            date=item.cycle.strftime("%Y%m%d"),
            hour=f"{item.cycle.hour:02d}",
            step=f"{item.step_h:03d}",
            remote_file=remote_file_name(item, resolution),
            levels=levels,
            left=f"{region.lon_min % 360.0:g}",
            right=f"{region.lon_max % 360.0:g}",
            top=f"{region.lat_max:g}",
            bottom=f"{region.lat_min:g}",
        )
    except (KeyError, IndexError, ValueError) as exc:
        raise WeatherError(f"the GFS URL template has an unknown or malformed placeholder: {exc}") from exc


def redact_url(url: str) -> str:
    """The URL without user:password and without the values of secret-looking query parameters."""
    parts = urllib.parse.urlsplit(url)
    netloc = parts.hostname or ""
    if parts.port:
        netloc += f":{parts.port}"
    query = urllib.parse.parse_qsl(parts.query, keep_blank_values=True)
    cleaned = [(k, "REDACTED" if k.lower() in _SECRET_KEYS else v) for k, v in query]
    return urllib.parse.urlunsplit(
        (parts.scheme, netloc, parts.path, urllib.parse.urlencode(cleaned, safe="/%"), "")
    )


class _Retryable(Exception):
    """A failure worth another attempt (connection lost, server error, incomplete or corrupt file)."""


ProgressHook = Callable[[str, int, int | None], None]
"""Called as (file name, bytes so far, total bytes or None) while downloading."""


@dataclass
class Downloader:
    """Downloads forecast files into ``directory``/gfs.YYYYMMDD/HH/<region>/, complete or not at all."""

    directory: Path
    url_template: str = DEFAULT_URL_TEMPLATE
    resolution: str = "0p50"
    retries: int = 4
    backoff_s: float = 2.0
    timeout_s: float = 60.0
    progress: ProgressHook | None = None

    def __post_init__(self) -> None:
        if self.resolution not in RESOLUTIONS:
            raise WeatherError(f"resolution {self.resolution!r} is not one of {', '.join(RESOLUTIONS)}")

    def local_path(self, item: ForecastFile, region: Region) -> Path:
        region_dir = cycle_directory(self.directory, item.cycle) / region.tag
        return region_dir / gfs_file_name(item.cycle, item.step_h, self.resolution)

    def fetch_all(self, items: Sequence[ForecastFile], region: Region) -> list[Path]:
        """Every file, holding all the plan's cycles throughout, so no prune takes a file fetched first."""
        with ExitStack() as held:
            for cycle in sorted({item.cycle for item in items}):
                held.enter_context(fetching(cycle_directory(self.directory, cycle)))
            return [self.fetch(item, region) for item in items]

    def fetch(self, item: ForecastFile, region: Region) -> Path:
        """The complete local file, downloaded unless a complete copy is already there."""
        with fetching(cycle_directory(self.directory, item.cycle)):
            return self._fetch_locked(item, region)

    def _fetch_locked(self, item: ForecastFile, region: Region) -> Path:
        target = self.local_path(item, region)
        expected = 4 * len(GFS_LEVELS_HPA)
        if target.is_file() and self._is_complete(target, expected):
            return target
        url = build_url(self.url_template, item, region, self.resolution)
        partial = target.with_name(target.name + PART_SUFFIX)
        target.parent.mkdir(parents=True, exist_ok=True)
        last_problem = ""
        for attempt in range(self.retries + 1):
            if attempt:
                time.sleep(self.backoff_s * 2 ** (attempt - 1))
            try:
                self._download(url, partial, target.name)
            except _Retryable as exc:
                last_problem = str(exc)
                continue
            if self._is_complete(partial, expected):
                os.replace(partial, target)
                return target
            last_problem = "the downloaded file failed the GRIB completeness check"
            partial.unlink(missing_ok=True)  # a corrupt body cannot be resumed: start again
        raise WeatherError(
            f"could not download {target.name} from {redact_url(url)} after {self.retries + 1} attempts: "
            f"{last_problem}"
        )

    @staticmethod
    def _is_complete(path: Path, expected_messages: int) -> bool:
        from predictor.environment.gribcheck import (
            scan_grib_file,  # eccodes: loaded by a download, not by --help
        )

        try:
            scan = scan_grib_file(path, decode=True)
        except WeatherError:
            return False
        return scan.message_count == expected_messages

    def _download(self, url: str, partial: Path, name: str) -> None:
        """Fetch into ``partial``, continuing from its current size when the server allows it."""
        have = partial.stat().st_size if partial.exists() else 0
        request = urllib.request.Request(url, headers={"User-Agent": "drs-console"})
        if have:
            request.add_header("Range", f"bytes={have}-")
        try:
            response = urllib.request.urlopen(request, timeout=self.timeout_s)
        except urllib.error.HTTPError as exc:
            if exc.code == 416 and have:
                return  # we already hold the whole body; the completeness check decides
            if exc.code >= 500 or exc.code == 429:
                raise _Retryable(f"HTTP {exc.code} {exc.reason}") from exc
            hint = " (not published yet, or the URL template is outdated)" if exc.code == 404 else ""
            raise WeatherError(f"HTTP {exc.code} {exc.reason} for {redact_url(url)}{hint}") from exc
        except (urllib.error.URLError, OSError) as exc:
            raise _Retryable(f"cannot connect: {getattr(exc, 'reason', exc)}") from exc
        with response:
            if have and response.status != 206:
                have = 0  # the server ignored the Range header: start over
            length = response.headers.get("Content-Length")
            total = have + int(length) if length is not None else None
            received = have
            try:
                with open(partial, "ab" if have else "wb") as out:
                    while chunk := response.read(_CHUNK):
                        out.write(chunk)
                        received += len(chunk)
                        if self.progress:
                            self.progress(name, received, total)
            except (http.client.IncompleteRead, OSError) as exc:  # OSError covers resets and timeouts
                raise _Retryable(
                    f"connection lost after {received} bytes ({exc.__class__.__name__})"
                ) from exc
            if total is not None and received < total:
                raise _Retryable(f"connection closed after {received} of {total} bytes")

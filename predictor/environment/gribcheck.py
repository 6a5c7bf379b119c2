"""Message-by-message integrity scan of a GRIB file, before anyone trusts its contents.

Why: cfgrib skips a corrupt or truncated message with a log line and simply returns fewer variables
or levels, so a download cut in the middle would otherwise look like a file that "lacks v". Walking
the messages with eccodes finds the cut and names the file. The scan reads each message's bytes
(cheap); ``decode=True`` also unpacks every field, which the downloader does for its small subsets.
Counts are of fields: a multi-field message (GFS packs u and v together) counts once per field.
"""

from __future__ import annotations

import os
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

import predictor.environment.native_libs  # noqa: F401  (PROJ before eccodes, see there)

# isort: split
import eccodes
import gribapi.errors

from predictor.environment.gribframe import MAX_GRID_POINTS, check_grib_framing
from predictor.errors import WeatherError

YEARS = (1900, 2200)
"""Reference and validity years a weather file can carry; outside, a header is damaged."""


@dataclass(frozen=True)
class GribScan:
    message_count: int
    editions: frozenset[int]
    generating_processes: frozenset[int]


def walk_grib_messages(path: str | Path, visit: Callable[[int], None], *, headers_only: bool = False) -> int:
    """Call ``visit(handle)`` for every field of the file; returns how many there were.

    Every way a file can be bad becomes a WeatherError naming it: unreadable, cut short (the
    message that fails to load), a field that does not decode (an eccodes error inside ``visit``),
    or no GRIB message at all. Multi-field support is on so that GFS's packed u/v count as two.
    """
    file = Path(path)
    check_grib_framing(file)  # lengths and packing, in Python, before eccodes reads a byte of it
    count = 0
    eccodes.codes_grib_multi_support_on()
    try:
        with open(file, "rb") as stream:
            size = os.fstat(stream.fileno()).st_size
            # eccodes keeps unread fields of a multi-field message across files unless told otherwise.
            eccodes.codes_grib_multi_support_reset_file(stream)
            while True:
                try:
                    handle = eccodes.codes_grib_new_from_file(stream, headers_only=headers_only)
                except gribapi.errors.GribInternalError as exc:
                    raise WeatherError(
                        f"{file}: GRIB message {count + 1} is truncated or corrupt ({exc}); "
                        "download the file again"
                    ) from exc
                if handle is None:
                    break
                count += 1
                try:
                    check_header(file, count, handle, size)
                    visit(handle)
                except gribapi.errors.GribInternalError as exc:
                    raise WeatherError(f"{file}: GRIB message {count} does not decode ({exc})") from exc
                except (ValueError, OverflowError) as exc:  # a header value no check above foresaw
                    raise WeatherError(f"{file}: GRIB message {count} is implausible ({exc})") from exc
                finally:
                    eccodes.codes_release(handle)
    except OSError as exc:
        raise WeatherError(f"cannot read weather file {file}: {exc.strerror or exc}") from exc
    if count == 0:
        raise WeatherError(f"{file} is not a GRIB file (no GRIB messages in it)")
    return count


def _integer(handle: int, key: str) -> int | None:
    """A header integer, or None where the message has no such key or says it is missing."""
    if not eccodes.codes_is_defined(handle, key) or eccodes.codes_is_missing(handle, key):
        return None
    return int(eccodes.codes_get(handle, key, ktype=int))


def check_header(file: Path, number: int, handle: int, file_size: int) -> None:
    """Refuse a message whose header no real weather file has, before anything is allocated from it.

    Why: every size and date below was once taken on trust, and a one-byte flip then cost 23 GB of
    memory (the OOM killer may pick the receiver instead), or a ValueError traceback from a date, or a
    minute of 250 read as 08:50. The checks are on the header alone (``headers_only`` scans pass them).
    """
    where = f"{file}: GRIB message {number}"
    length = _integer(handle, "totalLength")
    if length is not None and length > file_size:
        raise WeatherError(f"{where} says it is {length:,} bytes long but the file has {file_size:,}")
    points = _integer(handle, "numberOfDataPoints")
    ni, nj = _integer(handle, "Ni"), _integer(handle, "Nj")
    if ni is not None and nj is not None:
        if ni * nj > MAX_GRID_POINTS:
            raise WeatherError(f"{where}: a grid of {ni:,}×{nj:,} points is implausible "
                               f"(more than {MAX_GRID_POINTS:,}); the header is damaged")  # fmt: skip
        if points is not None and points != ni * nj:
            raise WeatherError(
                f"{where} holds {points:,} points on a {ni:,}×{nj:,} grid; the header is damaged"
            )
    if points is not None and points > MAX_GRID_POINTS:
        raise WeatherError(f"{where}: {points:,} points is implausible (more than {MAX_GRID_POINTS:,})")
    values = _integer(handle, "numberOfValues")
    if values is not None and points is not None and values > points:
        raise WeatherError(f"{where} packs {values:,} values for {points:,} points; the header is damaged")
    parts = [_integer(handle, key) for key in ("year", "month", "day", "hour", "minute", "second")]
    if all(part is not None for part in parts[:5]):
        year, month, day, hour, minute, second = (part or 0 for part in parts)
        try:
            datetime(year, month, day, hour, minute, second)
        except ValueError:
            raise WeatherError(
                f"{where}: reference time {year:04d}-{month:02d}-{day:02d} "
                f"{hour:02d}:{minute:02d}:{second:02d} is not a date; the header is damaged"
            ) from None
        if not YEARS[0] <= year <= YEARS[1]:
            raise WeatherError(f"{where}: reference year {year} is implausible; the header is damaged")


def scan_grib_file(path: str | Path, *, decode: bool = False) -> GribScan:
    """Walk every message; raise WeatherError naming the file if one is cut short or undecodable."""
    editions: set[int] = set()
    processes: set[int] = set()

    def visit(handle: int) -> None:
        editions.add(int(eccodes.codes_get(handle, "edition")))
        if eccodes.codes_is_defined(handle, "generatingProcessIdentifier"):
            processes.add(int(eccodes.codes_get(handle, "generatingProcessIdentifier")))
        if decode:
            eccodes.codes_get_values(handle)

    count = walk_grib_messages(path, visit, headers_only=not decode)
    return GribScan(count, frozenset(editions), frozenset(processes))

"""Message-by-message integrity scan of a GRIB file, before anyone trusts its contents.

Why: cfgrib skips a corrupt or truncated message with a log line and simply returns fewer variables
or levels, so a download cut in the middle would otherwise look like a file that "lacks v". Walking
the messages with eccodes finds the cut and names the file. The scan reads each message's bytes
(cheap); ``decode=True`` also unpacks every field, which the downloader does for its small subsets.
Counts are of fields: a multi-field message (GFS packs u and v together) counts once per field.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass
from pathlib import Path

import predictor.environment.native_libs  # noqa: F401  (PROJ before eccodes, see there)

# isort: split
import eccodes
import gribapi.errors

from predictor.errors import WeatherError


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
    count = 0
    eccodes.codes_grib_multi_support_on()
    try:
        with open(file, "rb") as stream:
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
                    visit(handle)
                except gribapi.errors.GribInternalError as exc:
                    raise WeatherError(f"{file}: GRIB message {count} does not decode ({exc})") from exc
                finally:
                    eccodes.codes_release(handle)
    except OSError as exc:
        raise WeatherError(f"cannot read weather file {file}: {exc.strerror or exc}") from exc
    if count == 0:
        raise WeatherError(f"{file} is not a GRIB file (no GRIB messages in it)")
    return count


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

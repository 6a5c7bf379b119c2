"""Message-by-message integrity scan of a GRIB file, before anyone trusts its contents.

Why: cfgrib skips a corrupt or truncated message with a log line and simply returns fewer variables
or levels, so a download cut in the middle would otherwise look like a file that "lacks v". Walking
the messages with eccodes finds the cut and names the file. The scan reads each message's bytes
(cheap); ``decode=True`` also unpacks every field, which the downloader does for its small subsets.
Counts are of fields: a multi-field message (GFS packs u and v together) counts once per field.
"""

from __future__ import annotations

from dataclasses import dataclass
from pathlib import Path

import predictor.native_libs  # noqa: F401  (PROJ before eccodes, see there)

# isort: split
import eccodes
import gribapi.errors

from predictor.errors import WeatherError


@dataclass(frozen=True)
class GribScan:
    message_count: int
    editions: frozenset[int]
    generating_processes: frozenset[int]


def scan_grib_file(path: str | Path, *, decode: bool = False) -> GribScan:
    """Walk every message; raise WeatherError naming the file if one is cut short or undecodable."""
    file = Path(path)
    count = 0
    editions: set[int] = set()
    processes: set[int] = set()
    eccodes.codes_grib_multi_support_on()  # count fields as the reader sees them (GFS packs u and v)
    try:
        with open(file, "rb") as stream:
            eccodes.codes_grib_multi_support_reset_file(stream)
            while True:
                try:
                    handle = eccodes.codes_grib_new_from_file(stream, headers_only=not decode)
                except gribapi.errors.GribInternalError as exc:
                    raise WeatherError(
                        f"{file}: GRIB message {count + 1} is truncated or corrupt ({exc}); "
                        "download the file again"
                    ) from exc
                if handle is None:
                    break
                try:
                    count += 1
                    editions.add(int(eccodes.codes_get(handle, "edition")))
                    if eccodes.codes_is_defined(handle, "generatingProcessIdentifier"):
                        processes.add(int(eccodes.codes_get(handle, "generatingProcessIdentifier")))
                    if decode:
                        eccodes.codes_get_values(handle)
                except gribapi.errors.GribInternalError as exc:
                    raise WeatherError(f"{file}: GRIB message {count} does not decode ({exc})") from exc
                finally:
                    eccodes.codes_release(handle)
    except OSError as exc:
        raise WeatherError(f"cannot read weather file {file}: {exc.strerror or exc}") from exc
    if count == 0:
        raise WeatherError(f"{file} is not a GRIB file (no GRIB messages in it)")
    return GribScan(count, frozenset(editions), frozenset(processes))

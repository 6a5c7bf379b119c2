"""Measured flight tracks in every format we meet, as one ``Track`` of ``Fix`` es.

Readers only parse: a row that is well formed but physically wrong (a 1970 date, a 0/0 position)
is kept here and removed by a stated rule in ``cleaning``, so that the removal is reported. A row
that cannot be parsed at all is an operator error: it raises ``TrackError`` naming the file and
line, never a bare traceback, because a silently skipped row is a silently changed flight.

Formats:
- canonical CSV ``time,lat,lon,alt_m[,pressure_pa[,speed_mps]]`` with ISO 8601 UTC times (what we write);
- GPX 1.1 (``trkpt`` with ``ele`` and ``time``), read with the standard library;
- the 2018–2019 SuperBIT RockBLOCK gateway logs (no header; rows with and without ``RB`` serials);
- the 1 Hz V4 logger CSV (times of day only, so the flight date must be given);
- the EOSS APRS flight table (Edge of Space Sciences, Colorado): columns ``packettime``, ``altitude``,
  ``latitude``, ``longitude`` (and ``speed_mph``) found by name, local Denver times, feet and mph;
  two or more beacons on one flight train interleaved (they ride the same load line: one track).
"""

from __future__ import annotations

import csv
import io
import math
import re
import xml.sax
import xml.sax.handler
from collections.abc import Iterator, Sequence
from dataclasses import dataclass
from datetime import UTC, date, datetime, timedelta
from pathlib import Path
from xml.sax.xmlreader import AttributesNSImpl, Locator
from zoneinfo import ZoneInfo, ZoneInfoNotFoundError

from predictor.errors import PredictorError

CANONICAL_HEADER: tuple[str, ...] = ("time", "lat", "lon", "alt_m", "pressure_pa", "speed_mps")
"""The optional columns let a track exported from stored reports keep what cleaning needs: the
measured pressure, and the receiver's ground speed that confirms a landing at the last fix."""
V4_HEADER: tuple[str, ...] = (
    "record",
    "time_hhmmss",
    "lat_deg",
    "lon_deg",
    "alt_m",
    "sats",
    "gps_quality",
    "T2_degC",
    "RH_pct",
)
EOSS_COLUMNS: tuple[str, ...] = ("packettime", "altitude", "latitude", "longitude")
"""The columns an EOSS flight table must have, found by name; the archive's others are not positions."""
EOSS_RENAMED = {"altitude_ft": "altitude"}
"""The archive's 2025 layout names the unit (``altitude_ft``, beside a new ``altitude_m``); same feet."""
EOSS_POSITION_FLAG = "position_packet"
"""The 2025 layout keeps status packets too, ``false`` here: they carry no position and are skipped."""
EOSS_ISO_TIME = re.compile(
    r"\d{4}-\d{2}-\d{2}[T ]\d{2}:\d{2}:\d{2}(?:\.\d{1,6})?(?:Z|[+-]\d{2}:\d{2})?", re.ASCII
)
"""The 2025 layout's ``packettime`` (``2026-05-09T07:59:15.000``: local, as before; an offset or ``Z``
when a table gives UTC). A date alone is not a time, so ``fromisoformat``'s other forms are refused."""
EOSS_SPEED_COLUMN = "speed_mph"
"""Optional: the APRS ground speed, which shows the train has stopped at the last row."""
EOSS_TIME_ZONE = "America/Denver"
"""EOSS's ``packettime`` is local time where the team flies: its APRS packets carry the UTC time
(``134545h``) and the table's time is 6 h earlier in July, 7 h in November (MDT/MST)."""
FOOT_M = 0.3048
"""The international foot, exactly; APRS and the EOSS tables give altitude in feet."""
MPH_MS = 0.44704
"""The international mile per hour in m/s, exactly (1609.344 m / 3600 s)."""
SUPERBIT_DATA_FIELDS = 13
"""date, time, lat, lon, alt, speed, course, HDOP, sats, pressure, temperature, battery, sequence."""


class TrackError(PredictorError):
    """A track file cannot be read; the message names the file and, where there is one, the line."""


@dataclass(frozen=True, slots=True)
class Fix:
    """One measured position. Optional fields are None when the format does not carry them."""

    time: datetime
    """UTC, timezone-aware."""
    lat: float
    lon: float
    alt_m: float
    """GNSS altitude, metres (above mean sea level for the formats we read)."""
    pressure_pa: float | None = None
    """Static pressure measured on board, Pa."""
    speed_ms: float | None = None
    """Ground speed reported by the receiver, m/s."""
    course_deg: float | None = None
    sats: int | None = None
    line: int = 0
    """Line of the source file the fix came from, so every cleaning report can point at it."""


@dataclass(frozen=True)
class Track:
    """The fixes of one file in file order, exactly as read (cleaning happens elsewhere)."""

    name: str
    source: str
    """The file the fixes came from."""
    format: str
    fixes: tuple[Fix, ...]


def read_track(path: str | Path, *, day: date | None = None) -> Track:
    """Read any supported format, chosen from the file name and its first line.

    ``day`` is the UTC date of the first fix for formats that store only times of day (V4).
    """
    path = Path(path)
    if path.suffix.lower() == ".gpx":
        return read_gpx(path)
    first = _first_line(path)
    if first.lower().startswith("time,"):
        return read_canonical_csv(path)
    if first.lower().startswith("record,time_hhmmss"):
        if day is None:
            raise TrackError(
                f"{path}: this 1 Hz logger file has times of day but no date; "
                "give the flight date (--date YYYY-MM-DD)"
            )
        return read_v4_csv(path, day)
    if first.startswith("RB") or (first[:2].isdigit() and first[2:3] == "/"):
        return read_superbit_log(path)
    if _is_eoss_header(first):
        return read_eoss_csv(path)
    raise TrackError(
        f"{path}:1: unknown track format (expected a canonical CSV with header "
        f"'time,lat,lon,alt_m[,pressure_pa[,speed_mps]]', a GPX file, a SuperBIT RockBLOCK log, "
        f"a V4 logger CSV or an EOSS flight table with 'packettime,altitude,latitude,longitude')"
    )


def read_canonical_csv(path: str | Path) -> Track:
    path = Path(path)
    rows = _csv_rows(path)
    try:
        line_no, header = next(rows)
    except StopIteration:
        raise TrackError(
            f"{path}: empty file, expected the header 'time,lat,lon,alt_m[,pressure_pa[,speed_mps]]'"
        ) from None
    names = tuple(h.strip() for h in header)
    if names not in (CANONICAL_HEADER[:4], CANONICAL_HEADER[:5], CANONICAL_HEADER):
        raise TrackError(
            f"{path}:{line_no}: header must be 'time,lat,lon,alt_m[,pressure_pa[,speed_mps]]', "
            f"got {','.join(names)!r}"
        )
    fixes = []
    for line_no, row in rows:
        if not any(cell.strip() for cell in row):
            continue
        if len(row) != len(names):
            raise TrackError(f"{path}:{line_no}: expected {len(names)} fields, got {len(row)}")
        where = f"{path}:{line_no}"
        pressure = row[4].strip() if len(row) >= 5 else ""
        speed = row[5].strip() if len(row) == 6 else ""
        fixes.append(
            Fix(
                time=_iso_utc(row[0], where),
                lat=_number(row[1], "lat", where),
                lon=_number(row[2], "lon", where),
                alt_m=_number(row[3], "alt_m", where),
                pressure_pa=_number(pressure, "pressure_pa", where) if pressure else None,
                speed_ms=_number(speed, "speed_mps", where) if speed else None,
                line=line_no,
            )
        )
    return _track(path, "canonical-csv", fixes)


def write_canonical_csv(fixes: Sequence[Fix], path: str | Path) -> None:
    """Write fixes in the canonical format (optional columns always present, empty when unknown)."""
    with Path(path).open("w", newline="", encoding="utf-8") as handle:
        writer = csv.writer(handle, lineterminator="\n")
        writer.writerow(CANONICAL_HEADER)
        for fix in fixes:
            writer.writerow(
                (
                    fix.time.astimezone(UTC).strftime("%Y-%m-%dT%H:%M:%S") + _fraction(fix.time) + "Z",
                    f"{fix.lat:.7f}",
                    f"{fix.lon:.7f}",
                    f"{fix.alt_m:.2f}",
                    "" if fix.pressure_pa is None else f"{fix.pressure_pa:.1f}",
                    "" if fix.speed_ms is None else f"{fix.speed_ms:.2f}",
                )
            )


def read_superbit_log(path: str | Path) -> Track:
    """The RockBLOCK gateway log: each row is decided on its own (RB serials or not, padding or not)."""
    path = Path(path)
    fixes = []
    for line_no, row in _csv_rows(path):
        if not any(cell.strip() for cell in row):
            continue
        where = f"{path}:{line_no}"
        offset = 1 if row[0].strip().startswith("RB") else 0
        data = row[offset:]
        while len(data) > SUPERBIT_DATA_FIELDS and not data[-1].strip():
            data = data[:-1]
        if offset and len(data) > SUPERBIT_DATA_FIELDS and data[-1].strip().startswith("RB"):
            data = data[:-1]
        if len(data) != SUPERBIT_DATA_FIELDS:
            raise TrackError(
                f"{where}: expected {SUPERBIT_DATA_FIELDS} data fields "
                f"(date,time,lat,lon,alt,speed,course,hdop,sats,pressure,temp,batt,seq), got {len(data)}"
            )
        try:
            when = datetime.strptime(f"{data[0].strip()} {data[1].strip()}", "%d/%m/%Y %H:%M:%S")
        except ValueError:
            raise TrackError(
                f"{where}: date/time {data[0]!r} {data[1]!r} is not 'dd/mm/YYYY,HH:MM:SS'"
            ) from None
        pressure = _number(data[9], "pressure", where)
        fixes.append(
            Fix(
                time=when.replace(tzinfo=UTC),
                lat=_number(data[2], "latitude", where),
                lon=_number(data[3], "longitude", where),
                alt_m=_number(data[4], "altitude", where),
                pressure_pa=pressure if pressure > 0 else None,
                speed_ms=_number(data[5], "ground speed", where),
                course_deg=_number(data[6], "course", where),
                sats=int(_number(data[8], "satellites", where)),
                line=line_no,
            )
        )
    return _track(path, "superbit-rockblock", fixes)


def read_v4_csv(path: str | Path, day: date) -> Track:
    """The 1 Hz logger CSV. Times are times of day; a step back of more than 12 h is a new UTC day."""
    path = Path(path)
    line_no, header, rows = _header_and_rows(path)
    if tuple(h.strip() for h in header) != V4_HEADER:
        raise TrackError(f"{path}:{line_no}: header must be {','.join(V4_HEADER)!r}")
    fixes: list[Fix] = []
    current_day = day
    for line_no, row in rows:
        if not any(cell.strip() for cell in row):
            continue
        where = f"{path}:{line_no}"
        if len(row) != len(V4_HEADER):
            raise TrackError(f"{where}: expected {len(V4_HEADER)} fields, got {len(row)}")
        try:
            clock = datetime.strptime(row[1].strip(), "%H:%M:%S").time()
        except ValueError:
            raise TrackError(f"{where}: time {row[1]!r} is not HH:MM:SS") from None
        when = datetime.combine(current_day, clock, tzinfo=UTC)
        if fixes and when < fixes[-1].time - timedelta(hours=12):
            current_day += timedelta(days=1)
            when += timedelta(days=1)
        fixes.append(
            Fix(
                time=when,
                lat=_number(row[2], "lat_deg", where),
                lon=_number(row[3], "lon_deg", where),
                alt_m=_number(row[4], "alt_m", where),
                sats=int(_number(row[5], "sats", where)),
                line=line_no,
            )
        )
    return _track(path, "v4-1hz", fixes)


def read_eoss_csv(path: str | Path) -> Track:
    """An EOSS flight table: local Denver times to UTC, feet to metres, mph to m/s; columns by name.

    Both the archive's own tables (``flightid,callsign,receivetime,packettime,altitude,...``) and the
    trimmed copies that keep only some columns read the same way. Every beacon's rows are kept: two
    beacons on one load line are one track, and ``cleaning`` keeps the first of two fixes in the same
    second (``duplicate-time``). The APRS ground speed lets ``cleaning`` see that the train stopped.
    """
    path = Path(path)
    line_no, header, rows = _header_and_rows(path)
    names = _eoss_names(header)
    missing = [name for name in EOSS_COLUMNS if name not in names]
    if missing:
        raise TrackError(f"{path}:{line_no}: an EOSS flight table needs the columns {', '.join(missing)}")
    wanted = (*EOSS_COLUMNS, EOSS_SPEED_COLUMN, EOSS_POSITION_FLAG)
    column = {name: names.index(name) for name in wanted if name in names}
    try:
        local = ZoneInfo(EOSS_TIME_ZONE)
    except ZoneInfoNotFoundError:
        raise TrackError(f"{path}: the time zone {EOSS_TIME_ZONE} is not installed (tzdata)") from None
    fixes = []
    for line_no, row in rows:
        if not any(cell.strip() for cell in row):
            continue
        where = f"{path}:{line_no}"
        if len(row) != len(names):
            raise TrackError(f"{where}: expected {len(names)} fields, got {len(row)}")
        if EOSS_POSITION_FLAG in column and row[column[EOSS_POSITION_FLAG]].strip().lower() == "false":
            continue
        when = _eoss_time(row[column["packettime"]].strip(), local, where)
        speed = row[column[EOSS_SPEED_COLUMN]].strip() if EOSS_SPEED_COLUMN in column else ""
        fixes.append(
            Fix(
                time=when,
                lat=_number(row[column["latitude"]], "latitude", where),
                lon=_number(row[column["longitude"]], "longitude", where),
                alt_m=_number(row[column["altitude"]], "altitude", where) * FOOT_M,
                speed_ms=_number(speed, EOSS_SPEED_COLUMN, where) * MPH_MS if speed else None,
                line=line_no,
            )
        )
    return _track(path, "eoss-aprs", fixes)


def read_gpx(path: str | Path) -> Track:
    """GPX 1.1 (1.0 is accepted too): every ``trkpt`` of every track segment, in file order."""
    path = Path(path)
    handler = _GpxHandler(str(path))
    parser = xml.sax.make_parser()
    parser.setFeature(xml.sax.handler.feature_namespaces, True)
    parser.setFeature(xml.sax.handler.feature_external_ges, False)
    parser.setFeature(xml.sax.handler.feature_external_pes, False)
    parser.setContentHandler(handler)
    try:
        parser.parse(str(path))
    except xml.sax.SAXParseException as exc:
        raise TrackError(f"{path}:{exc.getLineNumber()}: not well-formed XML ({exc.getMessage()})") from None
    except OSError as exc:
        raise TrackError(f"{path}: cannot read ({exc.strerror or exc})") from None
    if not handler.saw_gpx:
        raise TrackError(f"{path}:1: not a GPX file (no <gpx> root element)")
    return _track(path, "gpx", handler.fixes)


class _GpxHandler(xml.sax.handler.ContentHandler):
    """Collects trkpt elements (camelCase methods are the SAX API); GPX 1.0 and 1.1 namespaces both read."""

    def __init__(self, source: str) -> None:
        super().__init__()
        self.source = source
        self.fixes: list[Fix] = []
        self.saw_gpx = False
        self._point: dict[str, str] | None = None
        self._point_line = 0
        self._text: list[str] = []
        self._locator: Locator | None = None

    def setDocumentLocator(self, locator: Locator) -> None:
        self._locator = locator

    def _line(self) -> int:
        return (self._locator.getLineNumber() or 0) if self._locator else 0

    def startElementNS(
        self, name: tuple[str | None, str], qname: str | None, attrs: AttributesNSImpl
    ) -> None:
        local = name[1]
        if local == "gpx":
            self.saw_gpx = True
        elif local == "trkpt":
            self._point = {key[1]: value for key, value in attrs.items()}
            self._point_line = self._line()
        self._text = []

    def characters(self, content: str) -> None:
        self._text.append(content)

    def endElementNS(self, name: tuple[str | None, str], qname: str | None) -> None:
        local = name[1]
        if self._point is None:
            return
        if local in ("ele", "time", "sat"):
            self._point[local] = "".join(self._text).strip()
        elif local == "trkpt":
            self.fixes.append(self._fix(self._point))
            self._point = None

    def _fix(self, point: dict[str, str]) -> Fix:
        where = f"{self.source}:{self._point_line}"
        for key in ("lat", "lon", "ele", "time"):
            if key not in point:
                raise TrackError(f"{where}: trkpt has no {key}")
        sats = point.get("sat")
        return Fix(
            time=_iso_utc(point["time"], where),
            lat=_number(point["lat"], "lat", where),
            lon=_number(point["lon"], "lon", where),
            alt_m=_number(point["ele"], "ele", where),
            sats=int(_number(sats, "sat", where)) if sats else None,
            line=self._point_line,
        )


def _track(path: Path, fmt: str, fixes: list[Fix]) -> Track:
    if not fixes:
        raise TrackError(f"{path}: no fixes in the file")
    return Track(name=path.stem, source=str(path), format=fmt, fixes=tuple(fixes))


def _header_and_rows(path: Path) -> tuple[int, list[str], Iterator[tuple[int, list[str]]]]:
    """The first line's number and fields, and the lines after it; an empty file is a TrackError."""
    rows = _csv_rows(path)
    try:
        line_no, header = next(rows)
    except StopIteration:
        raise TrackError(f"{path}: empty file") from None
    return line_no, header, rows


def _is_eoss_header(line: str) -> bool:
    names = _eoss_names(line.split(","))
    return all(name in names for name in EOSS_COLUMNS)


def _eoss_names(header: Sequence[str]) -> list[str]:
    names = [h.strip().lower() for h in header]
    return [EOSS_RENAMED[n] if n in EOSS_RENAMED and EOSS_RENAMED[n] not in names else n for n in names]


def _eoss_time(stamp: str, local: ZoneInfo, where: str) -> datetime:
    when: datetime | None
    try:
        when = datetime.strptime(stamp, "%Y-%m-%d %H:%M:%S")
    except ValueError:
        try:  # the pattern's shape with a month 13 still fails in fromisoformat
            when = datetime.fromisoformat(stamp) if EOSS_ISO_TIME.fullmatch(stamp) else None
        except ValueError:
            when = None
    if when is None:
        raise TrackError(f"{where}: packettime {stamp!r} is not 'YYYY-MM-DD HH:MM:SS' or ISO 8601")
    return (when if when.tzinfo is not None else when.replace(tzinfo=local)).astimezone(UTC)


def _first_line(path: Path) -> str:
    for _, row in _csv_rows(path):
        if any(cell.strip() for cell in row):
            return ",".join(row).strip()
    raise TrackError(f"{path}: empty file")


def _csv_rows(path: Path) -> Iterator[tuple[int, list[str]]]:
    """(line number, fields) for each line; undecodable bytes become a TrackError naming the line."""
    try:
        raw = path.read_bytes()
    except OSError as exc:
        raise TrackError(f"{path}: cannot read ({exc.strerror or exc})") from None
    for line_no, line in enumerate(raw.splitlines(), start=1):
        try:
            text = line.decode("utf-8-sig" if line_no == 1 else "utf-8")
        except UnicodeDecodeError:
            raise TrackError(f"{path}:{line_no}: not text (bytes that are not UTF-8)") from None
        if "\x00" in text:
            raise TrackError(f"{path}:{line_no}: not text (NUL byte)")
        try:
            fields = next(csv.reader(io.StringIO(text)), [])
        except csv.Error as exc:
            raise TrackError(f"{path}:{line_no}: not a CSV line ({exc})") from None
        yield line_no, fields


def _number(text: str, what: str, where: str) -> float:
    try:
        value = float(text)
    except (TypeError, ValueError):
        raise TrackError(f"{where}: {what} {text!r} is not a number") from None
    if not math.isfinite(value):
        raise TrackError(f"{where}: {what} {text!r} is not a finite number")
    return value


def _iso_utc(text: str, where: str) -> datetime:
    stripped = text.strip()
    try:
        when = datetime.fromisoformat(stripped)
    except ValueError:
        raise TrackError(f"{where}: time {text!r} is not ISO 8601 (e.g. 2019-03-11T17:50:19Z)") from None
    if when.tzinfo is None:
        raise TrackError(f"{where}: time {text!r} has no time zone; write UTC as ...Z")
    try:
        return when.astimezone(UTC)
    except OverflowError:
        raise TrackError(f"{where}: time {text!r} is out of range") from None


def _fraction(when: datetime) -> str:
    return f".{when.microsecond:06d}".rstrip("0") if when.microsecond else ""

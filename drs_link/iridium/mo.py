"""Parse a capsule's Mobile Originated report (drs_protocol.md 3.7) without ever raising.

Whatever arrives from the gateway is kept: a payload that is not a DRS report becomes a rejected
result with the reason, so the raw bytes are stored and an operator can look at them later.
"""

from __future__ import annotations

import binascii
import re
from dataclasses import asdict, dataclass
from datetime import UTC, datetime
from typing import Any

from drs_link.iridium.firmware import NO_FIX_TIME

MAX_MO_BYTES = 120
ALTITUDE_RANGE_M = (-1_000, 60_000)
"""Below the Dead Sea shore to above any balloon: 999,999 m, which the format allows, is a broken report."""
_RB_PREFIX = re.compile(r"^RB(\d{7}),")
_RB_SUFFIX = re.compile(r",RB(\d{7})$")
_NO_FIX_FIELDS = (NO_FIX_TIME, "0.0", "0.0", "0", "0.0", "0", "0.0", "0")
_FIELDS: tuple[tuple[str, str], ...] = (
    ("time", r"\d{14}"),
    ("lat", r"-?\d{1,2}\.\d{6}"),
    ("lon", r"-?\d{1,3}\.\d{6}"),
    ("alt_m", r"-?\d{1,6}"),
    ("speed_ms", r"\d{1,4}\.\d"),
    ("course_deg", r"\d{1,3}"),
    ("hdop", r"\d{1,3}\.\d"),
    ("sats", r"\d{1,2}"),
    ("pressure", r"\d{1,6}"),
    ("temperature", r"-?\d{1,3}\.\d"),
    ("vbat", r"\d{1,2}\.\d{2}"),
    ("iteration", r"\d{1,9}"),
)


@dataclass(frozen=True)
class Fix:
    time: datetime
    lat: float
    lon: float
    alt_m: int
    speed_ms: float
    course_deg: int
    hdop: float
    sats: int


@dataclass(frozen=True)
class Report:
    """One accepted DRS report; ``fix`` is None when the unit sent ``19700101000000`` (no fix)."""

    fix: Fix | None
    vbat: float
    iteration: int
    pressure: int
    temperature: float
    rb_destination: int | None
    rb_source: int | None

    @property
    def forwarding(self) -> bool:
        return self.rb_destination is not None


@dataclass(frozen=True)
class ParseResult:
    raw: bytes
    report: Report | None
    reason: str | None

    @property
    def accepted(self) -> bool:
        return self.report is not None

    def as_dict(self) -> dict[str, Any]:
        """JSON-ready form for ``drs mo parse --json`` and the store."""
        report = None
        if self.report is not None:
            report = asdict(self.report)
            if self.report.fix is not None:
                report["fix"]["time"] = self.report.fix.time.isoformat().replace("+00:00", "Z")
        return {
            "accepted": self.accepted,
            "reason": self.reason,
            "hex": self.raw.hex().upper(),
            "report": report,
        }


def _rejected(raw: bytes, reason: str) -> ParseResult:
    return ParseResult(raw, None, reason)


def parse_hex(hex_text: str) -> ParseResult:
    """The gateway's hex ``data`` field → a result; bad hex is a rejection, not an exception."""
    cleaned = hex_text.strip()
    try:
        raw = binascii.unhexlify(cleaned)
    except (binascii.Error, ValueError):
        return _rejected(cleaned.encode("utf-8", "replace")[: MAX_MO_BYTES * 4], "data is not valid hex")
    return parse_payload(raw)


def _fix_time(stamp: str) -> datetime | None:
    try:
        return datetime.strptime(stamp, "%Y%m%d%H%M%S").replace(tzinfo=UTC)
    except ValueError:
        return None


def _short_reason(fields: list[str]) -> str:
    """Too few fields: a report cut short, or something that never was a DRS report.

    Only a start that reads as a DRS report (every complete field in the firmware's format) was cut
    short; anything else, a test message typed at the gateway, say, is not a DRS report at all, and
    calling it truncated sends an operator looking for a radio fault that is not there.
    """
    complete = fields[:-1]
    if complete and all(
        re.fullmatch(pattern, value) for value, (_, pattern) in zip(complete, _FIELDS, strict=False)
    ):
        return f"truncated: {len(fields)} fields, a DRS report has {len(_FIELDS)}"
    return f"not a DRS report: {len(fields)} comma-separated field(s), not the firmware's {len(_FIELDS)}"


def parse_payload(raw: bytes) -> ParseResult:
    """Raw MO bytes → an accepted ``Report`` or a rejection naming the first thing that is wrong."""
    if not raw:
        return _rejected(raw, "empty payload")
    if len(raw) > MAX_MO_BYTES:
        return _rejected(
            raw, f"over-long: {len(raw)} bytes, the firmware never sends more than {MAX_MO_BYTES}"
        )
    if any(b < 0x20 or b > 0x7E for b in raw):
        return _rejected(raw, "not printable ASCII: not a DRS report")
    text = raw.decode("ascii")
    rb_destination = rb_source = None
    if prefix := _RB_PREFIX.match(text):
        rb_destination = int(prefix.group(1))
        text = text[prefix.end() :]
    if suffix := _RB_SUFFIX.search(text):
        rb_source = int(suffix.group(1))
        text = text[: suffix.start()]
    fields = text.split(",")
    if len(fields) < len(_FIELDS):
        return _rejected(raw, _short_reason(fields))
    if len(fields) > len(_FIELDS):
        return _rejected(raw, f"{len(fields)} fields, a DRS report has {len(_FIELDS)}")
    no_fix = fields[0] == NO_FIX_TIME
    if no_fix and tuple(fields[:8]) != _NO_FIX_FIELDS:
        return _rejected(raw, "no-fix time 19700101000000 with non-zero fix fields")
    checked = zip(fields, _FIELDS, strict=True)
    for index, (value, (name, pattern)) in enumerate(checked):
        if not (no_fix and index < len(_NO_FIX_FIELDS)) and not re.fullmatch(pattern, value):
            return _rejected(raw, f"field {name} {value!r} is not in the firmware's format")
    values = dict(zip((name for name, _ in _FIELDS), fields, strict=True))
    fix = None
    if not no_fix:
        moment = _fix_time(values["time"])
        if moment is None:
            return _rejected(raw, f"field time {values['time']!r} is not a valid UTC date and time")
        lat, lon = float(values["lat"]), float(values["lon"])
        if not (-90 <= lat <= 90 and -180 <= lon <= 180):
            return _rejected(raw, f"position {lat},{lon} is outside the globe")
        altitude = int(values["alt_m"])
        if not ALTITUDE_RANGE_M[0] <= altitude <= ALTITUDE_RANGE_M[1]:
            return _rejected(raw, f"altitude {altitude:,} m is beyond anywhere a capsule can be")
        fix = Fix(
            moment,
            lat,
            lon,
            altitude,
            float(values["speed_ms"]),
            int(values["course_deg"]),
            float(values["hdop"]),
            int(values["sats"]),
        )
    report = Report(
        fix=fix,
        vbat=float(values["vbat"]),
        iteration=int(values["iteration"]),
        pressure=int(values["pressure"]),
        temperature=float(values["temperature"]),
        rb_destination=rb_destination,
        rb_source=rb_source,
    )
    return ParseResult(raw, report, None)

"""A model of what the DRS firmware does with SBD bytes (``ino`` ``start_9603``, drs_protocol.md 3.7-3.9).

The composer and the parser are tested against this model, and the simulated capsule runs it, so
the rules that lose a command silently on the real unit (substring search, ``String.toInt``, the
100-byte receive buffer) live in exactly one place. Which commands there are, their limits (the
INTERVAL range, the ±14 min PARACHUTE test) and how the firmware reads each from a downloaded MT is
``drs_link.iridium.commands`` (``apply_mt``); this holds the primitives they are read with and the
MO the unit writes.
"""

from __future__ import annotations

import re
from dataclasses import dataclass
from datetime import datetime

MT_BUFFER_BYTES = 100
NO_FIX_TIME = "19700101000000"
NO_FIX_MINUTE_OF_DAY = 99 * 60 + 99
_LEADING_INT = re.compile(r"^[ \t\r\n\v\f]*([+-]?\d+)")


@dataclass(frozen=True)
class GnssFix:
    """One fix as TinyGPS hands it to the firmware (position, UTC time, motion, quality)."""

    time: datetime
    lat: float
    lon: float
    alt_m: float
    speed_ms: float
    course_deg: float
    hdop: float
    sats: int

    @property
    def minute_of_day(self) -> int:
        return self.time.hour * 60 + self.time.minute


def format_mo(
    fix: GnssFix | None, vbat: float, iteration: int, rb_destination: int = 0, rb_source: int = 0
) -> bytes:
    """The MO text exactly as the firmware writes it with ``AT+SBDWT`` (no terminator)."""
    if fix is None:
        core = f"{NO_FIX_TIME},0.0,0.0,0,0.0,0,0.0,0,0,0.0,{vbat:.2f},{iteration}"
    else:
        t = fix.time
        stamp = f"{t.year}{t.month:02d}{t.day:02d}{t.hour:02d}{t.minute:02d}{t.second:02d}"
        core = (
            f"{stamp},{fix.lat:.6f},{fix.lon:.6f},{int(fix.alt_m)},{fix.speed_ms:.1f},"
            f"{int(fix.course_deg)},{fix.hdop:.1f},{fix.sats},0,0.0,{vbat:.2f},{iteration}"
        )
    if rb_destination > 0:
        core = f"RB{rb_destination:07d},{core},RB{rb_source:07d}"
    return core.encode("ascii")


def arduino_to_int(text: str) -> int:
    """Arduino ``String.toInt()`` (``atol``): leading digits count, anything else gives 0."""
    match = _LEADING_INT.match(text)
    return int(match.group(1)) if match else 0


def value_after(text: str, marker: str, stop: str) -> str | None:
    """Text between ``marker`` (first occurrence) and the next ``stop``; to the end when none follows."""
    start = text.find(marker)
    if start < 0:
        return None
    start += len(marker)
    end = text.find(stop, start)
    return text[start:] if end < 0 else text[start:end]

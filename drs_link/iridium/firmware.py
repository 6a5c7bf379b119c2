"""A model of what the DRS firmware does with SBD bytes (``ino`` ``start_9603``, drs_protocol.md 3.7-3.9).

The composer and the parser are tested against this model, and the simulated capsule runs it, so
the rules that lose a command silently on the real unit (substring search, ``String.toInt``, the
±14 min PARACHUTE test, the 100-byte receive buffer) live in exactly one place.
"""

from __future__ import annotations

import re
from dataclasses import dataclass, field
from datetime import datetime

MT_BUFFER_BYTES = 100
NO_FIX_TIME = "19700101000000"
NO_FIX_MINUTE_OF_DAY = 99 * 60 + 99
INTERVAL_MIN, INTERVAL_MAX = 1, 1440
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


def parachute_accepted(p_minute: int, g_minute: int) -> bool:
    """The firmware's own test of ``[PARACHUTE=hh:mm]`` against the fix minute G of the same cycle."""
    return (g_minute - 15 < p_minute < g_minute + 15) or (
        (p_minute > 1425 and g_minute < 15) or (g_minute > 1425 and p_minute < 15)
    )


@dataclass
class MtEffect:
    """What one downloaded MT changed on the unit; ``None`` means "not touched"."""

    discarded: str | None = None
    interval: int | None = None
    rb_source: int | None = None
    rb_destination: int | None = None
    parachute_opens: bool = False
    sounder: bool | None = None
    notes: list[str] = field(default_factory=list)


def _value_after(text: str, marker: str, stop: str) -> str | None:
    """Text between ``marker`` (first occurrence) and the next ``stop``; to the end when none follows."""
    start = text.find(marker)
    if start < 0:
        return None
    start += len(marker)
    end = text.find(stop, start)
    return text[start:] if end < 0 else text[start:end]


def apply_mt(payload: bytes, fix: GnssFix | None) -> MtEffect:
    """Parse one downloaded MT the way ``start_9603`` does; invalid parts are silently ignored."""
    effect = MtEffect()
    if len(payload) > MT_BUFFER_BYTES:
        effect.discarded = (
            f"{len(payload)} bytes overflow the {MT_BUFFER_BYTES}-byte buffer (ISBD_RX_OVERFLOW)"
        )
        return effect
    if len(payload) == MT_BUFFER_BYTES:
        effect.discarded = "100 bytes: the terminating NUL is written past the buffer (undefined)"
        return effect
    text = payload.split(b"\x00", 1)[0].decode("latin-1")
    interval = _value_after(text, "[INTERVAL=", "]")
    if interval is not None:
        n = arduino_to_int(interval)
        if INTERVAL_MIN <= n <= INTERVAL_MAX:
            effect.interval = n
        else:
            effect.notes.append(f"INTERVAL {interval!r} ignored")
    source = _value_after(text, "[RBSOURCE=", "]")
    if source is not None and arduino_to_int(source) >= 0:
        effect.rb_source = arduino_to_int(source)
    destination = _value_after(text, "[RBDESTINATION=", "]")
    if destination is not None and arduino_to_int(destination) >= 0:
        effect.rb_destination = arduino_to_int(destination)
    hours = _value_after(text, "[PARACHUTE=", ":")
    if hours is not None:
        start = text.find("[PARACHUTE=")
        colon = text.find(":", start)
        minutes = _value_after(text[colon:], ":", "]") if colon >= 0 else ""
        hh, mm = arduino_to_int(hours), arduino_to_int(minutes or "")
        g_minute = fix.minute_of_day if fix is not None else NO_FIX_MINUTE_OF_DAY
        if hh >= 0 and mm >= 0 and parachute_accepted(hh * 60 + mm, g_minute):
            effect.parachute_opens = True
        else:
            effect.notes.append(f"PARACHUTE {hh}:{mm} ignored at G={g_minute}")
    if "[SOUNDER_OFF]" in text:
        effect.sounder = False
    if "[SOUNDER_ON]" in text:
        effect.sounder = True
    return effect

"""Compose Mobile Terminated commands the DRS firmware reads exactly as meant (drs_protocol.md 3.8, 6.2).

A malformed MT is downloaded, silently ignored and lost, so nothing but the firmware's canonical
bracket syntax can be built here, and the result is checked locally (ASCII, no spaces, ≤ 99 bytes)
instead of trusting the gateway's 270-byte limit.
"""

from __future__ import annotations

import re
from dataclasses import dataclass

from drs_link.errors import RefusedError
from drs_link.iridium.firmware import INTERVAL_MAX, INTERVAL_MIN, MT_BUFFER_BYTES

MAX_MT_BYTES = MT_BUFFER_BYTES - 1
MAX_RB_SERIAL = 9_999_999
_HHMM = re.compile(r"([0-9]{2}):([0-9]{2})", re.ASCII)


class MtRefusedError(RefusedError):
    """The requested MT would be misread, ignored or lost by the firmware."""


@dataclass(frozen=True)
class MtMessage:
    """One MT ready to queue: the exact ASCII text and the commands it carries."""

    text: str
    commands: tuple[str, ...]

    @property
    def payload(self) -> bytes:
        return self.text.encode("ascii")

    @property
    def hex(self) -> str:
        return self.payload.hex().upper()


class MtComposer:
    """Collects commands, each checked on entry, and builds them into one MT.

    Several commands go into one message because the unit downloads only one MT per cycle. The
    order is the firmware's processing order (INTERVAL, RBSOURCE, RBDESTINATION, PARACHUTE,
    SOUNDER) so the text reads the way the unit acts on it.
    """

    _ORDER = ("INTERVAL", "RBSOURCE", "RBDESTINATION", "PARACHUTE", "SOUNDER")

    def __init__(self) -> None:
        self._commands: dict[str, str] = {}

    def _add(self, key: str, command: str) -> MtComposer:
        if key in self._commands:
            raise MtRefusedError(
                f"{key} is already in this message ({self._commands[key]}); the firmware uses only the first"
            )
        self._commands[key] = command
        return self

    def interval(self, minutes: int) -> MtComposer:
        if isinstance(minutes, bool) or not isinstance(minutes, int):
            raise MtRefusedError(f"INTERVAL must be a whole number of minutes, got {minutes!r}")
        if not INTERVAL_MIN <= minutes <= INTERVAL_MAX:
            raise MtRefusedError(
                f"INTERVAL {minutes} is outside {INTERVAL_MIN}-{INTERVAL_MAX} minutes; "
                "the firmware would ignore it"
            )
        return self._add("INTERVAL", f"[INTERVAL={minutes}]")

    def parachute(self, hour: int, minute: int) -> MtComposer:
        for name, value, top in (("hour", hour, 23), ("minute", minute, 59)):
            if isinstance(value, bool) or not isinstance(value, int) or not 0 <= value <= top:
                raise MtRefusedError(f"PARACHUTE {name} must be 0-{top} (UTC), got {value!r}")
        return self._add("PARACHUTE", f"[PARACHUTE={hour:02d}:{minute:02d}]")

    def sounder(self, on: bool) -> MtComposer:
        if "SOUNDER" in self._commands:
            raise MtRefusedError(
                "the sounder is already switched in this message; "
                "never send SOUNDER_ON and SOUNDER_OFF together"
            )
        return self._add("SOUNDER", "[SOUNDER_ON]" if on else "[SOUNDER_OFF]")

    def _serial(self, key: str, serial: int) -> MtComposer:
        if isinstance(serial, bool) or not isinstance(serial, int) or not 0 <= serial <= MAX_RB_SERIAL:
            raise MtRefusedError(
                f"{key} must be a RockBLOCK serial 0-{MAX_RB_SERIAL} (0 = off), got {serial!r}"
            )
        return self._add(key, f"[{key}={serial}]")

    def rb_destination(self, serial: int) -> MtComposer:
        return self._serial("RBDESTINATION", serial)

    def rb_source(self, serial: int) -> MtComposer:
        return self._serial("RBSOURCE", serial)

    def build(self) -> MtMessage:
        if not self._commands:
            raise MtRefusedError("no command given: an empty MT would cost credit and do nothing")
        commands = tuple(self._commands[key] for key in self._ORDER if key in self._commands)
        text = "".join(commands)
        if not text.isascii() or not text.isprintable() or " " in text or text != text.upper():
            raise MtRefusedError(f"internal: {text!r} is not upper-case printable ASCII without spaces")
        if len(text) > MAX_MT_BYTES:
            raise MtRefusedError(
                f"{len(text)} bytes: the firmware keeps at most {MAX_MT_BYTES}; "
                "split the commands over two cycles"
            )
        return MtMessage(text, commands)


def parse_hhmm(text: str) -> tuple[int, int]:
    """An operator's ``HH:MM`` (UTC) → (hour, minute); only the canonical form is accepted."""
    match = _HHMM.fullmatch(text.strip())
    if match is None:
        raise MtRefusedError(f"PARACHUTE time {text!r} must be HH:MM in UTC, e.g. 14:05")
    hour, minute = int(match.group(1)), int(match.group(2))
    if hour > 23 or minute > 59:
        raise MtRefusedError(f"PARACHUTE time {text!r} is not a time of day (HH 00-23, MM 00-59)")
    return hour, minute

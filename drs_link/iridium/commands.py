"""The one catalogue of MT commands the DRS firmware reads (drs_protocol.md 3.8, 6.2): add a command here.

Why one catalogue: the composer, the lifecycle, the checklist hook, the two-person gate, the status
lines, the firmware model, the CLI and the console all read a command from here, so adding one is one
entry and no second copy (a string prefix, an INTERVAL parser of its own) can drift from it unnoticed.
Each ``MtCommand`` holds everything any of them needs: the
name, the byte-exact text the composer writes (refusing what the firmware would misread or ignore),
reading our own text back, the firmware's own rule for a whole downloaded MT (substring search,
``String.toInt``, the limits), how its effect shows in later reports, the ``drs mt send`` option,
how the console offers it, and the one-line doc. ``CATALOGUE`` is in the firmware's processing
order (INTERVAL → RBSOURCE → RBDESTINATION → PARACHUTE → SOUNDER), which is the order the composer
writes them in, so the text reads the way the unit acts on it; ``LISTED`` is the order operators
meet them in (the most used first).
"""

from __future__ import annotations

import re
from collections.abc import Callable, Mapping, Sequence
from dataclasses import dataclass, field
from enum import StrEnum
from typing import Any

from drs_link.errors import RefusedError
from drs_link.iridium.firmware import (
    MT_BUFFER_BYTES,
    NO_FIX_MINUTE_OF_DAY,
    GnssFix,
    arduino_to_int,
    value_after,
)
from drs_link.iridium.reports import StoredReport

INTERVAL_MIN, INTERVAL_MAX = 1, 1440
"""The minutes ``[INTERVAL=n]`` is accepted within; the alarm handler caps at 1440 too (3.5)."""
PARACHUTE_WINDOW_MIN = 15
"""``[PARACHUTE=hh:mm]`` is accepted when G−15 < P < G+15: within ±14 min of the cycle's fix minute G."""
PARACHUTE_REACH_MIN = PARACHUTE_WINDOW_MIN - 1
"""How far (minutes) a PARACHUTE time may lie from the fix minute and still be accepted: 14."""
MINUTES_PER_DAY = 1440
MAX_RB_SERIAL = 9_999_999
PENDING, SEEN, NEVER_VISIBLE, NOT_SEEN = "pending", "seen", "never visible", "not seen"
"""What the reports say of one command's effect (the lifecycle's ``effects``)."""
EFFECT_REPORTS = 5
"""Reports after delivery within which an INTERVAL/RBDESTINATION change must show, else timed out."""
_HHMM = re.compile(r"([0-9]{2}):([0-9]{2})", re.ASCII)


class MtRefusedError(RefusedError):
    """The requested MT would be misread, ignored or lost by the firmware."""


@dataclass(frozen=True)
class Prompt:
    """What the console asks when the operator types the value: a title, the question, a default."""

    title: str
    question: str
    default: str = ""


@dataclass(frozen=True)
class ConsoleKey:
    """One console key for a command: ``value`` fixed (the sounder's off/on), ``None`` asks (``Prompt``)."""

    key: str
    description: str
    value: Any = None


class Hazard(StrEnum):
    ROUTINE = "routine"
    CRITICAL = "critical"
    """Drops the parachute (irreversible, dangerous in flight): landed evidence and a second operator."""


@dataclass(frozen=True, eq=False)
class MtCommand:
    """One firmware command; every part of ``drs`` that handles it reads it from here.

    Compared by identity: each command is one object of the catalogue, and its functions do not compare.
    """

    name: str
    """The firmware's keyword; at most one per message (the firmware uses only the first)."""
    encode: Callable[[Any], str]
    """The operator's value → the canonical text; raises ``MtRefusedError`` for anything else."""
    decode: Callable[[str], Any]
    """Our own canonical text → its value; ``None`` when the text is not this command."""
    firmware: Callable[[str, int], tuple[Any, str | None]]
    """The firmware's reading of a whole MT text at fix minute G: (value it acts on or None, a note)."""
    doc: str
    """Its line in ``docs/iridium.md``'s list of commands (a test keeps the two equal)."""
    flag: str
    """Its ``drs mt send`` option."""
    option: Mapping[str, Any]
    """The option's argparse keywords (type, choices, metavar, help)."""
    from_option: Callable[[Any], Any] = lambda value: value
    """The parsed option → the value ``encode`` takes."""
    confirm: Callable[[Any, Sequence[StoredReport]], str] | None = None
    """How the effect shows in the reports after delivery (PENDING until known); None: it never shows."""
    read: Callable[[str], Any] | None = None
    """Text an operator typed in the console → the value ``encode`` takes (refuses with the reason)."""
    prompt: Prompt | None = None
    keys: tuple[ConsoleKey, ...] = ()
    """The console's keys for it, the first shown in the footer; none: only ``drs mt send`` sends it."""
    pair_label: str = ""
    """The footer's one entry for all of ``keys`` where the screen is narrow."""
    note: str = ""
    """Said before the operator confirms a send: what to expect of the effect."""
    checklist_step: Callable[[Any], str | None] = lambda value: None
    """The procedure command (``drs_link.ops.checklist.COMMANDS``) a queued send of this value completes."""
    repeat_refusal: str = ""
    """Why a second one in the same message is refused, when it is more than "only the first counts"."""
    hazard: Hazard = field(default_factory=lambda: Hazard.ROUTINE)
    """How dangerous it is: a CRITICAL command passes the landed gate and the two-person rule
    (``drs_link.ops.authorize``), whichever face sends it; both faces read this, never its identity."""

    @property
    def dest(self) -> str:
        """The option's attribute on the parsed arguments."""
        return self.flag[2:].replace("-", "_")


def _whole(value: object) -> bool:
    return not isinstance(value, bool) and isinstance(value, int)


def _encode_interval(minutes: int) -> str:
    if not _whole(minutes):
        raise MtRefusedError(f"INTERVAL must be a whole number of minutes, got {minutes!r}")
    if not INTERVAL_MIN <= minutes <= INTERVAL_MAX:
        raise MtRefusedError(
            f"INTERVAL {minutes} is outside {INTERVAL_MIN}-{INTERVAL_MAX} minutes; the firmware would ignore it"
        )
    return f"[INTERVAL={minutes}]"


def _read_interval(text: str) -> int:
    try:
        return int(text.strip())
    except ValueError:
        raise MtRefusedError(f"INTERVAL {text!r} is not a whole number of minutes") from None


def _firmware_interval(text: str, g_minute: int) -> tuple[int | None, str | None]:
    """Accepted only within 1-1440; ``[INTERVAL=abc]`` is ignored (drs_protocol.md 3.9)."""
    raw = value_after(text, "[INTERVAL=", "]")
    if raw is None:
        return None, None
    minutes = arduino_to_int(raw)
    if INTERVAL_MIN <= minutes <= INTERVAL_MAX:
        return minutes, None
    return None, f"INTERVAL {raw!r} ignored"


def spacing_matches(seconds: float, minutes: int) -> bool:
    """A fix-to-fix spacing equals INTERVAL allowing for fix acquisition jitter (up to about 1 min)."""
    return abs(seconds - minutes * 60) <= max(60.0, 0.05 * minutes * 60)


def _interval_seen(minutes: int, after: Sequence[StoredReport]) -> str:
    """The new INTERVAL shows between the reports after the delivering one (the alarm already armed keeps
    the old spacing), and nothing there contradicts it.

    Why two spacings and no contradiction: the old interval's own spacings, with sessions lost or
    delivered out of order, can land on the new value once (a 2-min capsule missing 14 sessions shows
    a 30-min gap), and a single match was once taken as final while the capsule stayed at 2 min. Two
    adjacent spacings at the new value, and none that is not a whole number of new intervals (missed
    cycles), rule that out; the lifecycle re-reads the verdict as later reports come (``RECHECK_REPORTS``).
    """
    fixes = sorted(r.report.fix.time for r in after if r.report is not None and r.report.fix is not None)
    spacings = [(b - a).total_seconds() for a, b in zip(fixes, fixes[1:], strict=False)]
    spacings = [s for s in spacings if s > 30.0]  # the same fix delivered twice
    for spacing in spacings:
        cycles = max(1, round(spacing / (minutes * 60)))
        if not spacing_matches(spacing, cycles * minutes):
            return NOT_SEEN
    matched = [spacing_matches(spacing, minutes) for spacing in spacings]
    if any(a and b for a, b in zip(matched, matched[1:], strict=False)):
        return SEEN
    return NOT_SEEN if len(after) >= EFFECT_REPORTS else PENDING


def _encode_serial(name: str) -> Callable[[int], str]:
    def encode(serial: int) -> str:
        if not _whole(serial) or not 0 <= serial <= MAX_RB_SERIAL:
            raise MtRefusedError(
                f"{name} must be a RockBLOCK serial 0-{MAX_RB_SERIAL} (0 = off), got {serial!r}"
            )
        return f"[{name}={serial}]"

    return encode


def _firmware_serial(name: str) -> Callable[[str, int], tuple[int | None, str | None]]:
    """Any n ≥ 0 is saved; garbage becomes 0 (``String.toInt``)."""

    def firmware(text: str, g_minute: int) -> tuple[int | None, str | None]:
        raw = value_after(text, f"[{name}=", "]")
        serial = arduino_to_int(raw) if raw is not None else -1
        return (serial, None) if serial >= 0 else (None, None)

    return firmware


def _destination_seen(serial: int, after: Sequence[StoredReport]) -> str:
    """The next report carries the ``RB`` prefix of the new destination (none when 0 turns it off)."""
    if not after or after[0].report is None:
        return PENDING
    return SEEN if (after[0].report.rb_destination or 0) == serial else NOT_SEEN


def _source_seen(serial: int, after: Sequence[StoredReport]) -> str:
    """The next report's ``RB`` suffix, which only a forwarding unit writes."""
    if not after or after[0].report is None:
        return PENDING
    if after[0].report.rb_source is None:
        return NEVER_VISIBLE
    return SEEN if after[0].report.rb_source == serial else NOT_SEEN


def parachute_accepted(p_minute: int, g_minute: int) -> bool:
    """The firmware's own test of ``[PARACHUTE=hh:mm]`` against the fix minute G of the same cycle.

    Near midnight it is loose: P and G each within the window of their side of 00:00 also match.
    """
    window, late = PARACHUTE_WINDOW_MIN, MINUTES_PER_DAY - PARACHUTE_WINDOW_MIN
    return (g_minute - window < p_minute < g_minute + window) or (
        (p_minute > late and g_minute < window) or (g_minute > late and p_minute < window)
    )


def _encode_parachute(hour_minute: tuple[int, int]) -> str:
    hour, minute = hour_minute
    for name, value, top in (("hour", hour, 23), ("minute", minute, 59)):
        if not _whole(value) or not 0 <= value <= top:
            raise MtRefusedError(f"PARACHUTE {name} must be 0-{top} (UTC), got {value!r}")
    return f"[PARACHUTE={hour:02d}:{minute:02d}]"


def parse_hhmm(text: str) -> tuple[int, int]:
    """An operator's ``HH:MM`` (UTC) → (hour, minute); only the canonical form is accepted."""
    match = _HHMM.fullmatch(text.strip())
    if match is None:
        raise MtRefusedError(f"PARACHUTE time {text!r} must be HH:MM in UTC, e.g. 14:05")
    hour, minute = int(match.group(1)), int(match.group(2))
    if hour > 23 or minute > 59:
        raise MtRefusedError(f"PARACHUTE time {text!r} is not a time of day (HH 00-23, MM 00-59)")
    return hour, minute


def _firmware_parachute(text: str, g_minute: int) -> tuple[bool | None, str | None]:
    """hh up to the first ``:``, mm up to the next ``]``, both ≥ 0 and within ±14 min of G (3.8)."""
    hours = value_after(text, "[PARACHUTE=", ":")
    if hours is None:
        return None, None
    colon = text.find(":", text.find("[PARACHUTE="))
    minutes = value_after(text[colon:], ":", "]") if colon >= 0 else ""
    hh, mm = arduino_to_int(hours), arduino_to_int(minutes or "")
    if hh >= 0 and mm >= 0 and parachute_accepted(hh * 60 + mm, g_minute):
        return True, None
    return None, f"PARACHUTE {hh}:{mm} ignored at G={g_minute}"


def _firmware_sounder(text: str, g_minute: int) -> tuple[bool | None, str | None]:
    """OFF then ON are processed in that order, so ON wins when a message has both."""
    if "[SOUNDER_ON]" in text:
        return True, None
    return (False, None) if "[SOUNDER_OFF]" in text else (None, None)


def _decoder(pattern: str, value: Callable[[re.Match[str]], Any]) -> Callable[[str], Any]:
    compiled = re.compile(pattern)

    def decode(text: str) -> Any:
        match = compiled.fullmatch(text)
        return value(match) if match else None

    return decode


def _serial(name: str, flag: str, doc: str, option_help: str) -> MtCommand:
    return MtCommand(
        name=name,
        encode=_encode_serial(name),
        decode=_decoder(rf"\[{name}=([0-9]+)\]", lambda m: int(m.group(1))),
        firmware=_firmware_serial(name),
        doc=doc,
        flag=flag,
        option={"type": int, "metavar": "SERIAL", "help": option_help},
        confirm=_destination_seen if name == "RBDESTINATION" else _source_seen,
    )


INTERVAL = MtCommand(
    name="INTERVAL",
    encode=_encode_interval,
    decode=_decoder(r"\[INTERVAL=([0-9]+)\]", lambda m: int(m.group(1))),
    firmware=_firmware_interval,
    flag="--interval",
    doc=f"`[INTERVAL=n]`: minutes between reports, {INTERVAL_MIN}–{INTERVAL_MAX}; from the cycle after next",
    option={
        "type": int,
        "metavar": "N",
        "help": f"reporting interval, {INTERVAL_MIN}-{INTERVAL_MAX} minutes",
    },
    confirm=_interval_seen,
    read=_read_interval,
    prompt=Prompt("INTERVAL", f"Minutes between reports ({INTERVAL_MIN}-{INTERVAL_MAX}):", "2"),
    keys=(ConsoleKey("n", "INTERVAL"),),
    pair_label="INTERVAL",
    note="The next report keeps the old spacing; the new interval spaces the reports after it.",
    checklist_step=lambda minutes: "mt-interval",
)
RBSOURCE = _serial(
    "RBSOURCE",
    "--rb-source",
    "`[RBSOURCE=n]`: the unit's own RockBLOCK serial, 0–9999999",
    "the unit's own RockBLOCK serial",
)
RBDESTINATION = _serial(
    "RBDESTINATION",
    "--rb-destination",
    "`[RBDESTINATION=n]`: forward reports to that RockBLOCK serial, 0–9999999 (0 = off)",
    "forward reports (0 = off)",
)
PARACHUTE = MtCommand(
    name="PARACHUTE",
    encode=_encode_parachute,
    decode=_decoder(r"\[PARACHUTE=([0-9]{2}):([0-9]{2})\]", lambda m: (int(m.group(1)), int(m.group(2)))),
    firmware=_firmware_parachute,
    flag="--parachute",
    doc=f"`[PARACHUTE=HH:MM]`: open release B at the end of the cycle whose fix is within ±{PARACHUTE_REACH_MIN} min (UTC)",
    option={"metavar": "HH:MM|next", "help": "open release B: a UTC time, or 'next' to compute"},
    read=parse_hhmm,
    prompt=Prompt("PARACHUTE at", "HH:MM (UTC) to check against the window:"),
    keys=(ConsoleKey("c", "Parachute", "next"), ConsoleKey("C", "Parachute at…")),
    pair_label="Parachute",
    checklist_step=lambda hour_minute: "mt-parachute",
    hazard=Hazard.CRITICAL,
)
SOUNDER = MtCommand(
    name="SOUNDER",
    encode=lambda on: "[SOUNDER_ON]" if on else "[SOUNDER_OFF]",
    decode={"[SOUNDER_ON]": True, "[SOUNDER_OFF]": False}.get,
    firmware=_firmware_sounder,
    flag="--sounder",
    doc="`[SOUNDER_ON]` / `[SOUNDER_OFF]`: switch the sounder (never both in one message)",
    option={"choices": ("on", "off"), "help": "switch the sounder"},
    from_option=lambda choice: choice == "on",
    keys=(ConsoleKey("o", "Sounder off", False), ConsoleKey("O", "Sounder on", True)),
    pair_label="Sounder off/on",
    note="The sounder change is never confirmed by telemetry.",
    checklist_step=lambda on: None if on else "mt-sounder-off",
    repeat_refusal=(
        "the sounder is already switched in this message; never send SOUNDER_ON and SOUNDER_OFF together"
    ),
)

CATALOGUE: tuple[MtCommand, ...] = (INTERVAL, RBSOURCE, RBDESTINATION, PARACHUTE, SOUNDER)
"""Every command the firmware reads, in its processing order (drs_protocol.md 3.8)."""
LISTED: tuple[MtCommand, ...] = (INTERVAL, SOUNDER, PARACHUTE, RBDESTINATION, RBSOURCE)
"""The same commands in the order operators meet them: ``drs mt send``'s options, the console's keys."""


def by_name(catalogue: Sequence[MtCommand] = CATALOGUE) -> dict[str, MtCommand]:
    return {command.name: command for command in catalogue}


def read_text(text: str, catalogue: Sequence[MtCommand] = CATALOGUE) -> tuple[MtCommand, Any] | None:
    """One of our own command texts (as the lifecycle keeps them) → its command and value."""
    for command in catalogue:
        value = command.decode(text)
        if value is not None:
            return command, value
    return None


def is_command(text: str, command: MtCommand) -> bool:
    """Whether ``text`` is ``command``'s (whatever its value), e.g. either sounder switch."""
    found = read_text(text)
    return found is not None and found[0] is command


@dataclass
class MtEffect:
    """What one downloaded MT changed on the unit: ``accepted`` by command name; absent = not touched."""

    discarded: str | None = None
    accepted: dict[str, Any] = field(default_factory=dict)
    notes: list[str] = field(default_factory=list)

    @property
    def interval(self) -> int | None:
        return self.accepted.get(INTERVAL.name)

    @property
    def rb_source(self) -> int | None:
        return self.accepted.get(RBSOURCE.name)

    @property
    def rb_destination(self) -> int | None:
        return self.accepted.get(RBDESTINATION.name)

    @property
    def parachute_opens(self) -> bool:
        return PARACHUTE.name in self.accepted

    @property
    def sounder(self) -> bool | None:
        return self.accepted.get(SOUNDER.name)


def apply_mt(payload: bytes, fix: GnssFix | None, catalogue: Sequence[MtCommand] = CATALOGUE) -> MtEffect:
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
    g_minute = fix.minute_of_day if fix is not None else NO_FIX_MINUTE_OF_DAY
    for command in catalogue:
        value, note = command.firmware(text, g_minute)
        if value is not None:
            effect.accepted[command.name] = value
        if note is not None:
            effect.notes.append(note)
    return effect

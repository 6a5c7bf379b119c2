"""Compose Mobile Terminated commands the DRS firmware reads exactly as meant (drs_protocol.md 3.8, 6.2).

A malformed MT is downloaded, silently ignored and lost, so nothing but the firmware's canonical
bracket syntax can be built here, and the result is checked locally (ASCII, no spaces, ≤ 99 bytes)
instead of trusting the gateway's 270-byte limit.
"""

from __future__ import annotations

from dataclasses import dataclass

from drs_link.iridium.commands import CATALOGUE, MtCommand, MtRefusedError, by_name
from drs_link.iridium.firmware import MT_BUFFER_BYTES

MAX_MT_BYTES = MT_BUFFER_BYTES - 1


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
    """Collects commands of the catalogue (``drs_link.iridium.commands``), each checked on entry, into one MT.

    Several commands go into one message because the unit downloads only one MT per cycle. They are
    written in the catalogue's order, the firmware's processing order, so the text reads the way the
    unit acts on it. ``catalogue`` is only ever another one in tests that add a command to a copy.
    """

    def __init__(self, catalogue: tuple[MtCommand, ...] = CATALOGUE) -> None:
        self._catalogue = catalogue
        self._commands: dict[str, str] = {}

    def add(self, name: str, value: object) -> MtComposer:
        """The command ``name`` with the operator's ``value``; refused if the firmware would misread it."""
        command = by_name(self._catalogue)[name]
        if name in self._commands:
            raise MtRefusedError(
                command.repeat_refusal
                or f"{name} is already in this message ({self._commands[name]}); the firmware uses only the first"
            )
        self._commands[name] = command.encode(value)
        return self

    def build(self) -> MtMessage:
        if not self._commands:
            raise MtRefusedError("no command given: an empty MT would cost credit and do nothing")
        commands = tuple(self._commands[c.name] for c in self._catalogue if c.name in self._commands)
        text = "".join(commands)
        if not text.isascii() or not text.isprintable() or " " in text or text != text.upper():
            raise MtRefusedError(f"internal: {text!r} is not upper-case printable ASCII without spaces")
        if len(text) > MAX_MT_BYTES:
            raise MtRefusedError(
                f"{len(text)} bytes: the firmware keeps at most {MAX_MT_BYTES}; "
                "split the commands over two cycles"
            )
        return MtMessage(text, commands)

"""Text an operator types, refused below the UI if it could rewrite another person's terminal.

Why: an override reason holding ``\\r\\033[2K…`` made `drs approve` show "(landed: verified, 0 m/s on the
ground)" where it should have said "OVERRIDE of the landed gate" (issue #29): the approver read what
the requester chose, not what was stored. Reasons, waivers, typed names, notes and take-over reasons are
read by someone else, on a screen or in History, so they are one line of visible characters: any
Unicode control or format character (categories Cc and Cf: escape sequences, carriage returns, tabs,
bidirectional overrides, zero-width joiners) and the line and paragraph separators (Zl, Zp) are
refused, with one error naming the field. Every place that shows another person's text passes it
through ``shown`` too, so a row stored before this rule (or written into the store by hand) still
cannot reach a terminal as anything but visible escapes.
"""

from __future__ import annotations

import unicodedata

from drs_link.errors import RefusedError

REFUSED_CATEGORIES = frozenset({"Cc", "Cf", "Zl", "Zp"})
"""Controls, format characters, and the two Unicode line breaks: nothing a sentence needs."""


def _escape(char: str) -> str:
    code = ord(char)
    return f"\\x{code:02x}" if code < 0x100 else f"\\u{code:04x}" if code < 0x10000 else f"\\U{code:08x}"


def _kind(char: str) -> str:
    """What the character is, for the error: its Unicode name, or its category for the unnamed controls."""
    names = {"Cc": "a control character", "Cf": "a format character", "Zl": "a line separator",
             "Zp": "a paragraph separator"}  # fmt: skip
    return unicodedata.name(char, names[unicodedata.category(char)])


def _hidden(char: str) -> bool:
    return unicodedata.category(char) in REFUSED_CATEGORIES


def typed_text(field: str, value: str) -> str:
    """``value`` unchanged if it is visible text; else RefusedError naming ``field`` and the first
    offending character as an escape (``\\x1b``), so the error itself is safe to print."""
    for position, char in enumerate(value, start=1):
        if _hidden(char):
            raise RefusedError(
                f"{field}: character {position} is the control or format character {_escape(char)} "
                f"({_kind(char)}); type it as one line of visible text"
            )
    return value


def typed_optional(field: str, value: str | None) -> str | None:
    """``typed_text`` for an optional field: None passes as None."""
    return None if value is None else typed_text(field, value)


def shown(value: object) -> str:
    """Another person's text as it may reach a terminal: every control or format character as its
    visible escape (``\\x1b``, ``\\u202e``), the rest unchanged."""
    text = str(value)
    if not any(_hidden(char) for char in text):
        return text
    return "".join(_escape(char) if _hidden(char) else char for char in text)

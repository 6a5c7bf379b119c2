"""The `drs` argument parser: a mistyped option is named, not blamed on the next argument.

argparse sets an option it does not know aside and goes on, so ``drs predict --lattitude 67.89``
handed ``67.89`` to the optional ``bench`` word and said "argument action: invalid choice: '67.89'",
which names neither the mistake nor the fix. Every subparser is made from the root parser's class,
so this one class covers every command.

A word that starts with a minus and a digit is a value, never an option: southern latitudes and
western longitudes written naturally (``--from -44.7,169.1``, ``--lon -120``) reach their option.
argparse's own test takes only a bare number (``-44.7``) and called ``-44.7,169.1`` an unknown option.
No `drs` option is spelled with a digit, so nothing is lost.
"""

from __future__ import annotations

import argparse
import functools
import math
import os
import re
import sys
from collections.abc import Callable, Sequence
from datetime import UTC, date, datetime
from typing import Any, NoReturn

from predictor.errors import UsageError

VALUE_WITH_MINUS = re.compile(r"^-\.?\d")
"""``-44.7``, ``-44.7,169.1``, ``-.5``: what argparse consults to tell a value from an option."""


class DrsArgumentParser(argparse.ArgumentParser):
    """An ArgumentParser whose errors name the first unknown option, with the closest real one."""

    def __init__(self, *args: Any, root: DrsArgumentParser | None = None, **kwargs: Any) -> None:
        super().__init__(*args, **kwargs)
        self._negative_number_matcher = VALUE_WITH_MINUS
        self._argv: list[str] = []
        self._root = root
        """The `drs` parser itself, for a command's parser: `drs mo serve -v` is told where -v goes."""

    def add_subparsers(self, **kwargs: Any) -> Any:
        kwargs.setdefault("parser_class", functools.partial(type(self), root=self._root or self))
        return super().add_subparsers(**kwargs)

    def parse_known_args(  # type: ignore[override]
        self, args: Sequence[str] | None = None, namespace: argparse.Namespace | None = None
    ) -> tuple[argparse.Namespace, list[str]]:
        if args is None:
            return super().parse_known_args(args, namespace)
        if self._root is None:
            _stdin_taken.clear()  # a new command line (tests run several in one process)
        self._argv = list(args)
        parsed, extras = super().parse_known_args(self._argv, namespace)
        if self._unknown_option() is not None:
            self.error("")  # extras that look like options: always a typo, never a value left for later
        return parsed, extras

    def error(self, message: str) -> NoReturn:
        unknown = self._unknown_option()
        if unknown is not None:
            import difflib  # only when there is a mistake to name: `drs --help` stays quick

            message = f"unrecognized option {unknown}"
            close = difflib.get_close_matches(unknown, self._long_options(), n=1, cutoff=0.6)
            if self._root is not None and (
                unknown in self._root._option_string_actions or self._root._short_with_value(unknown)
            ):
                message += f" here: it is an option of drs itself, given before the command (drs {unknown} …)"
            elif close:
                message += f" (did you mean {close[0]}?)"
        super().error(message)

    def _long_options(self) -> list[str]:
        return [option for option in self._option_string_actions if option.startswith("--")]

    def _unknown_option(self) -> str | None:
        """The first word of this parser's own arguments that looks like an option it does not have.

        A subcommand's words are its own parser's business, so the scan stops at the first one.
        """
        commands = {
            name
            for action in self._actions
            if isinstance(action, argparse._SubParsersAction)
            for name in action.choices
        }
        for word in self._argv:
            if word == "--" or word in commands:
                return None
            if not word.startswith("-") or word == "-" or self._negative_number_matcher.match(word):
                continue
            name = word.split("=", 1)[0]
            if name in self._option_string_actions or self._abbreviates(name) or self._short_with_value(word):
                continue
            return name
        return None

    def _abbreviates(self, name: str) -> bool:
        """``--lat`` for ``--latitude``: argparse accepts a unique prefix (and says itself when it is not unique)."""
        return (
            self.allow_abbrev
            and name.startswith("--")
            and any(o.startswith(name) for o in self._long_options())
        )

    def _short_with_value(self, word: str) -> bool:
        """``-n5`` or ``-vv``: a known short option with its value or repeats attached."""
        return not word.startswith("--") and word[:2] in self._option_string_actions


# Value types for options: a value out of range is a command-line mistake, so argparse refuses it
# (exit status 2, the option named) before the command runs.


def _finite(text: str, what: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise argparse.ArgumentTypeError(f"{text!r} is not {what}") from None
    if not math.isfinite(value):
        raise argparse.ArgumentTypeError(f"{text!r} is not {what}")
    return value


def latitude(text: str) -> float:
    """Degrees north, -90…90 (south negative: ``--lat -44.7``)."""
    value = _finite(text, "a latitude in degrees")
    if not -90.0 <= value <= 90.0:
        raise argparse.ArgumentTypeError(f"{text} is not a latitude (-90 to 90 degrees, south negative)")
    return value


def longitude(text: str) -> float:
    """Degrees east, -180…360 (west negative: ``--lon -120.5``, or 0…360)."""
    value = _finite(text, "a longitude in degrees")
    if not -180.0 <= value <= 360.0:
        raise argparse.ArgumentTypeError(f"{text} is not a longitude (-180 to 180 degrees, west negative)")
    return value


def position_or_gpsd(text: str) -> str:
    """``LAT,LON`` in decimal degrees (``-44.7,169.1``, ``51.5,-0.1``), or ``gpsd``; kept as typed."""
    if text == "gpsd":
        return text
    parts = text.replace(" ", "").split(",")
    if len(parts) != 2:
        raise argparse.ArgumentTypeError(f"{text!r} is not LAT,LON (e.g. -44.7,169.1) or gpsd")
    latitude(parts[0])
    value = longitude(parts[1])
    if value > 180.0:
        raise argparse.ArgumentTypeError(f"{text!r}: the longitude must be -180 to 180, west negative")
    return text


def udp_target(text: str) -> str:
    """``HOST:PORT`` with a port 1…65535 (``[::1]:55672`` for IPv6)."""
    host, colon, port = text.strip().rpartition(":")
    if not colon or not host.strip("[]") or any(c.isspace() for c in host):
        raise argparse.ArgumentTypeError(f"{text!r} is not HOST:PORT, e.g. 255.255.255.255:55672")
    if not port.isdigit() or not 1 <= int(port) <= 65535:
        raise argparse.ArgumentTypeError(f"{port!r} in {text!r} is not a UDP port (1-65535)")
    return text


def positive(unit: str) -> Callable[[str], float]:
    """A number above 0, e.g. ``--every-minutes``; ``unit`` names it in the refusal."""

    def check(text: str) -> float:
        value = _finite(text, f"a number of {unit}")
        if value <= 0.0:
            raise argparse.ArgumentTypeError(f"{text} is not a positive number of {unit}")
        return value

    return check


def at_least_zero(unit: str, most: float) -> Callable[[str], float]:
    """A number from 0 to ``most``, e.g. ``--keep-days``."""

    def check(text: str) -> float:
        value = _finite(text, f"a number of {unit}")
        if not 0.0 <= value <= most:
            raise argparse.ArgumentTypeError(f"{text} is not between 0 and {most:g} {unit}")
        return value

    return check


# Times and dates: every command's time option (``drs predict --time``, ``drs weather fetch --time``,
# ``drs plan --from``) and flight date (``--date``) is read by the one rule below, so a form one command
# takes works in all of them. A bad one is refused while the command line is read, as one line that
# names the option (a UsageError, exit status 2), before any weather is loaded or any file written.


class UtcTime:
    """An instant: ISO 8601 with its zone (``2024-05-01T06:30Z``, ``2024-05-01 08:30+02:00``), or ``now``;
    given back in UTC.

    A time without a zone is refused, not guessed: read as the laptop's local time or as UTC by mistake,
    a release time is off by hours, and so is the weather the capsule is flown through. A lowercase
    ``z`` is taken as ``Z`` (RFC 3339 allows it; Python's reader does not).
    """

    def __init__(self, option: str) -> None:
        self.option = option

    def __call__(self, text: str) -> datetime:
        typed = text.strip()
        if typed.lower() == "now":
            return datetime.now(UTC)
        try:
            moment = datetime.fromisoformat(typed[:-1] + "Z" if typed.endswith("z") else typed)
        except ValueError:
            raise UsageError(
                f"{self.option} {text!r} is not an ISO 8601 time such as 2024-05-01T06:30Z, or now"
            ) from None
        if moment.tzinfo is None:
            suggestion = moment.isoformat() + "Z"  # valid even when only a date was typed
            raise UsageError(
                f"{self.option} {text!r} has no time zone; give UTC explicitly, e.g. {suggestion}"
            )
        return moment.astimezone(UTC)


class UtcDate:
    """A UTC day, ``YYYY-MM-DD``: the day of a log that records only times of day (the V4 logger)."""

    def __init__(self, option: str) -> None:
        self.option = option

    def __call__(self, text: str) -> date:
        try:
            return date.fromisoformat(text.strip())
        except ValueError:
            raise UsageError(f"{self.option} {text!r} is not a date YYYY-MM-DD such as 2021-06-01") from None


# Standard input for inputs, as ``-`` is standard output for outputs (``drs predict --geojson - |
# drs recovery DRS1 --predicted -``). Standard input can be read once: a second ``-`` is refused.

STDIN = "-"
MAX_STDIN_BYTES = 2 * 10**9
"""The most standard input spooled for one ``-``: a whole 0.25° GFS file is about 0.5 GB; a pipe that
sends more (``drs predict --weather - < /dev/zero``) is refused rather than filling the disk. Each reader
then applies its own limits to the spooled regular file (a model file at most 1 MB)."""
_CHUNK = 1 << 20
_stdin_taken: list[str] = []


def _claim_stdin(option: str) -> None:
    if _stdin_taken:
        raise argparse.ArgumentTypeError(
            f"standard input is already read for {_stdin_taken[0]}: only one input can be -"
        )
    _stdin_taken.append(option)


def _read_stdin(option: str) -> bytes:
    _claim_stdin(option)
    return sys.stdin.buffer.read()


def input_file(option: str) -> Callable[[str], str]:
    """A path to read, or ``-``: standard input, kept in a private temporary file for the readers that
    want a path (removed at exit), so every input is read by the same reader with the same checks and
    limits whether it came from a file or a pipe. Its name says its kind, for the readers that go by the
    suffix: ``.gpx`` for XML, ``.json`` for JSON, none otherwise (CSV, logs and GRIB are told apart by
    their first bytes)."""

    def check(text: str) -> str:
        if text != STDIN:
            return text
        import atexit
        import shutil
        import tempfile

        _claim_stdin(option)
        folder = tempfile.mkdtemp(prefix="drs-stdin-")
        atexit.register(shutil.rmtree, folder, ignore_errors=True)
        spool = os.path.join(folder, "stdin")
        size = 0
        first = b""
        with open(spool, "wb") as out:
            while chunk := sys.stdin.buffer.read(_CHUNK):
                size += len(chunk)
                if size > MAX_STDIN_BYTES:
                    raise argparse.ArgumentTypeError(
                        f"standard input is over {MAX_STDIN_BYTES:,} bytes; give a file instead"
                    )
                first = first or chunk.lstrip()[:1]
                out.write(chunk)
        suffix = ".gpx" if first == b"<" else ".json" if first in (b"{", b"[") else ""
        os.replace(spool, spool + suffix)
        return spool + suffix

    return check


def text_or_stdin(option: str) -> Callable[[str], str]:
    """A value given on the command line, or ``-``: the text of standard input, stripped."""

    def check(text: str) -> str:
        if text != STDIN:
            return text
        try:
            return _read_stdin(option).decode("utf-8").strip()
        except UnicodeDecodeError:
            raise argparse.ArgumentTypeError("standard input is not UTF-8 text") from None

    return check


def add_two_person_options(parser: argparse.ArgumentParser, when: str, waiting_for: str) -> None:
    """The two-person rule's three ways through, the same on every hazardous command (Go, authority
    take-over, a PARACHUTE MT): a second person from ``[console] crew``, a logged waiver, or another
    login's approval. ``when`` says which use of the command they are for ("" when it is every use)."""
    prefix = f"{when}: " if when else ""
    parser.add_argument(
        "--second-operator",
        metavar="NAME",
        help=f"{prefix}a second person from [console] crew, not the operator",
    )
    parser.add_argument(
        "--single-operator-waiver", metavar="REASON", help=f"{prefix}why one person does it alone (logged)"
    )
    parser.add_argument(
        "--await-approval",
        action="store_true",
        help=f"{prefix}wait until another login approves it (drs approve ID){waiting_for}",
    )

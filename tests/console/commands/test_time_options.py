"""Every `drs` option that takes a time or a flight date reads it by the same rule: the same forms work
in every command, and the same mistake is refused in the same words, naming the option, before the
command runs."""

from __future__ import annotations

import argparse
import ast
from collections.abc import Iterator
from datetime import UTC, date, datetime
from pathlib import Path

import pytest

from console.commands.argparser import UtcDate, UtcTime
from console.commands.main import build_parser, main

COMMANDS = Path(__file__).resolve().parents[3] / "console" / "commands"

TIME_OPTIONS: dict[tuple[str, str], list[str]] = {
    ("drs predict", "--time"): ["predict"],
    ("drs weather fetch", "--time"): ["weather", "fetch", "--lat", "46.5", "--lon", "6.6"],
    ("drs plan", "--from"): ["plan"],
}
"""Each time option, by command and option, with the rest of a command line that parses."""

DATE_OPTIONS: dict[tuple[str, str], list[str]] = {
    ("drs tracks summary", "--date"): ["tracks", "summary", "flight.csv"],
    ("drs tracks bench", "--date"): ["tracks", "bench", "flight.csv"],
    ("drs live", "--date"): ["live"],
    ("drs calibrate", "--date"): ["calibrate"],
    ("drs calibrate bench", "--date"): ["calibrate", "bench", "--tracks", "flight.csv"],
    ("drs calibrate vertical", "--date"): ["calibrate", "vertical", "--tracks", "a.csv", "--model", "m.json"],
}

HALF_PAST_SIX = datetime(2024, 5, 1, 6, 30, tzinfo=UTC)
TIME_FORMS = {
    "2024-05-01T06:30Z": HALF_PAST_SIX,
    "2024-05-01T06:30:00+00:00": HALF_PAST_SIX,
    "2024-05-01T08:30+02:00": HALF_PAST_SIX,
    "2024-04-30T23:30-07:00": HALF_PAST_SIX,
    "2024-05-01 06:30Z": HALF_PAST_SIX,
    "2024-05-01T06:30z": HALF_PAST_SIX,
    "20240501T0630Z": HALF_PAST_SIX,
    "2024-05-01T06:30:00.000Z": HALF_PAST_SIX,
}


def _typed_options(kind: type) -> Iterator[tuple[str, str, str]]:
    """(command, option, dest) of every option in every `drs` command whose value type is ``kind``."""

    def walk(parser: argparse.ArgumentParser) -> Iterator[tuple[str, str, str]]:
        for action in parser._actions:
            if isinstance(action, argparse._SubParsersAction):
                for sub in dict.fromkeys(action.choices.values()):
                    yield from walk(sub)
            elif isinstance(action.type, kind):
                yield parser.prog, action.option_strings[0], action.dest

    yield from walk(build_parser(every_module=True))


def _dest(kind: type, command: str, option: str) -> str:
    return next(d for c, o, d in _typed_options(kind) if (c, o) == (command, option))


def test_every_time_and_date_option_is_read_by_the_one_rule() -> None:
    """The lists above are every such option: a new one must be added here to be tested."""
    assert {(c, o) for c, o, _ in _typed_options(UtcTime)} == set(TIME_OPTIONS)
    assert {(c, o) for c, o, _ in _typed_options(UtcDate)} == set(DATE_OPTIONS)


def test_no_command_reads_a_time_its_own_way() -> None:
    """Only the argument parser calls Python's time readers: a command's own would drift from the rule."""
    readers = {"fromisoformat", "strptime"}
    own = [
        f"{path.name}:{node.lineno} {node.attr}"
        for path in sorted(COMMANDS.glob("*.py"))
        if path.name != "argparser.py"
        for node in ast.walk(ast.parse(path.read_text()))
        if isinstance(node, ast.Attribute) and node.attr in readers
    ]
    assert own == []


@pytest.mark.parametrize(("command", "option"), list(TIME_OPTIONS))
@pytest.mark.parametrize("text", list(TIME_FORMS))
def test_each_time_option_takes_the_same_forms(command: str, option: str, text: str) -> None:
    argv = [*TIME_OPTIONS[command, option], option, text]
    parsed = getattr(build_parser(argv[0]).parse_args(argv), _dest(UtcTime, command, option))
    assert parsed == TIME_FORMS[text] and parsed.utcoffset() is not None and parsed.tzinfo == UTC


@pytest.mark.parametrize(("command", "option"), list(TIME_OPTIONS))
@pytest.mark.parametrize("text", ["now", "NOW", " now "])
def test_each_time_option_takes_now_as_the_moment_it_is_read(command: str, option: str, text: str) -> None:
    argv = [*TIME_OPTIONS[command, option], option, text]
    before = datetime.now(UTC)
    parsed = getattr(build_parser(argv[0]).parse_args(argv), _dest(UtcTime, command, option))
    assert before <= parsed <= datetime.now(UTC) and parsed.tzinfo == UTC


NOT_ISO = "is not an ISO 8601 time such as 2024-05-01T06:30Z, or now"
NO_ZONE = "has no time zone; give UTC explicitly, e.g."
BAD_TIMES = {
    "yesterday": f"{{option}} 'yesterday' {NOT_ISO}",
    "2024-13-01T06:30Z": f"{{option}} '2024-13-01T06:30Z' {NOT_ISO}",
    "": f"{{option}} '' {NOT_ISO}",
    "06:30Z": f"{{option}} '06:30Z' {NOT_ISO}",
    "2024-05-01T06:30": f"{{option}} '2024-05-01T06:30' {NO_ZONE} 2024-05-01T06:30:00Z",
    "2024-05-01": f"{{option}} '2024-05-01' {NO_ZONE} 2024-05-01T00:00:00Z",
}
"""Each bad value and the whole line it is refused with (after ``drs: error: ``), for any option."""


@pytest.mark.parametrize(("command", "option"), list(TIME_OPTIONS))
@pytest.mark.parametrize("text", list(BAD_TIMES))
def test_each_time_option_refuses_the_same_bad_input_in_the_same_words(
    command: str, option: str, text: str, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """One line naming the option, exit status 2, and the command never ran (it wrote nothing)."""
    argv = [*TIME_OPTIONS[command, option], option, text, "--json"]
    if command == "drs weather fetch":
        argv += ["--dir", str(tmp_path / "gfs")]
    with pytest.MonkeyPatch.context() as patch:
        patch.chdir(tmp_path)
        assert main(argv) == 2
    out, err = capsys.readouterr()
    assert err == "drs: error: " + BAD_TIMES[text].format(option=option) + "\n" and out == ""
    assert list(tmp_path.iterdir()) == []


@pytest.mark.parametrize(("command", "option"), list(DATE_OPTIONS))
def test_each_date_option_takes_a_utc_day(command: str, option: str) -> None:
    argv = [*DATE_OPTIONS[command, option], option, "2021-06-01"]
    parsed = getattr(build_parser(argv[0]).parse_args(argv), _dest(UtcDate, command, option))
    assert parsed == date(2021, 6, 1)


@pytest.mark.parametrize(("command", "option"), list(DATE_OPTIONS))
@pytest.mark.parametrize("text", ["01/06/2021", "2021-06-31", "2021-06-01T00:00Z", "june"])
def test_each_date_option_refuses_the_same_bad_input_in_the_same_words(
    command: str, option: str, text: str, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main([*DATE_OPTIONS[command, option], option, text]) == 2
    out, err = capsys.readouterr()
    assert err == f"drs: error: {option} {text!r} is not a date YYYY-MM-DD such as 2021-06-01\n" and out == ""

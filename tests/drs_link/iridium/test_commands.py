"""The MT command catalogue: everything that handles a command reads it, so a new one is one entry.

Every command the real firmware accepts (drs_protocol.md 3.8: INTERVAL, RBSOURCE, RBDESTINATION,
PARACHUTE, SOUNDER_OFF/ON) is already in the catalogue, so the count is shown on a copy: one entry
added to it reaches the composer, the firmware model, the reading-back, ``drs mt send`` (its option,
its help and its text) and the console's keys, with no other file edited.
"""

from __future__ import annotations

import argparse
import re
from datetime import UTC, datetime
from pathlib import Path

import pytest

import console.commands.main as entry
from console.commands import iridium as iridium_cli
from console.screens.commanding import command_bindings
from drs_link.iridium.commands import (
    CATALOGUE,
    LISTED,
    ConsoleKey,
    MtCommand,
    MtRefusedError,
    apply_mt,
    by_name,
    read_text,
)
from drs_link.iridium.firmware import GnssFix, arduino_to_int, value_after
from drs_link.iridium.mt import MtComposer
from drs_link.server import iridium as server_iridium

DOCS = Path(__file__).parents[3] / "docs" / "iridium.md"
SAMPLES = {"INTERVAL": 5, "RBSOURCE": 11800, "RBDESTINATION": 16366, "PARACHUTE": (12, 5), "SOUNDER": False}
FIX = GnssFix(datetime(2026, 1, 1, 12, 0, tzinfo=UTC), 0, 0, 0, 0, 0, 1, 5)


@pytest.fixture(autouse=True)
def _private_server_in_this_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """`drs` acts through its private operations server; here in a thread of this process, so what these
    tests watch or patch in the operations layer is what the server runs (drs_link.server.private)."""
    monkeypatch.setenv("DRS_PRIVATE_SERVER", "thread")


def _mt_send_parser() -> argparse.ArgumentParser:
    subparsers = argparse.ArgumentParser().add_subparsers()
    iridium_cli.register(subparsers)
    mt = subparsers.choices["mt"]
    return next(
        action.choices["send"]
        for action in mt._actions
        if isinstance(action, argparse._SubParsersAction)  # noqa: SLF001
    )


def _options(parser: argparse.ArgumentParser) -> list[str]:
    return [action.option_strings[0] for action in parser._actions if action.option_strings]  # noqa: SLF001


def test_the_firmware_commands_are_the_catalogue_in_its_processing_order() -> None:
    assert [c.name for c in CATALOGUE] == ["INTERVAL", "RBSOURCE", "RBDESTINATION", "PARACHUTE", "SOUNDER"]
    assert sorted(LISTED, key=CATALOGUE.index) == list(CATALOGUE) and len({c.name for c in LISTED}) == len(
        LISTED
    )


def test_the_cli_offers_exactly_the_catalogue() -> None:
    options = _options(_mt_send_parser())
    assert [o for o in options if o in {c.flag for c in CATALOGUE}] == [c.flag for c in LISTED]
    assert {"--interval", "--sounder", "--parachute", "--rb-destination", "--rb-source"} == {
        c.flag for c in CATALOGUE
    }


def test_the_console_keys_are_the_catalogue_commands_that_have_keys() -> None:
    for paired in (False, True):
        actions = [b.action for b in command_bindings(paired)]
        named = [re.match(r"command\('([A-Z_]+)'", a).group(1) for a in actions]  # type: ignore[union-attr]
        assert sorted(set(named)) == sorted(c.name for c in CATALOGUE if c.keys)
        assert named == [c.name for c in LISTED for _ in c.keys]


def test_the_docs_list_exactly_the_catalogue() -> None:
    listed = [line[2:] for line in DOCS.read_text().splitlines() if line.startswith("- `[")]
    assert listed == [c.doc for c in CATALOGUE]


@pytest.mark.parametrize("command", CATALOGUE, ids=lambda c: c.name)
def test_each_command_round_trips_through_composer_firmware_and_reading_back(command: MtCommand) -> None:
    message = MtComposer().add(command.name, SAMPLES[command.name]).build()
    (text,) = message.commands
    assert read_text(text) == (command, SAMPLES[command.name])
    effect = apply_mt(message.payload, FIX)
    assert effect.notes == [] and list(effect.accepted) == [command.name]


EXAMPLE = MtCommand(
    name="EXAMPLE",
    encode=lambda n: f"[EXAMPLE={n}]",
    decode=lambda text: int(text[9:-1]) if re.fullmatch(r"\[EXAMPLE=[0-9]+\]", text) else None,
    firmware=lambda text, g: (
        (None, None) if (raw := value_after(text, "[EXAMPLE=", "]")) is None else (arduino_to_int(raw), None)
    ),
    flag="--example",
    doc="`[EXAMPLE=n]`: a command the firmware does not have, added to a copy of the catalogue",
    option={"type": int, "metavar": "N", "help": "an example added to a copy of the catalogue"},
    keys=(ConsoleKey("x", "Example", 7),),
)
"""One entry, as a new command would be: nothing else is edited for it below."""


def test_a_command_added_to_a_copy_of_the_catalogue_reaches_everything(
    monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str], tmp_path: Path
) -> None:
    extended = (*CATALOGUE[:3], EXAMPLE, *CATALOGUE[3:])
    message = MtComposer(extended).add("SOUNDER", True).add("EXAMPLE", 7).add("INTERVAL", 5).build()
    assert message.text == "[INTERVAL=5][EXAMPLE=7][SOUNDER_ON]"
    with pytest.raises(MtRefusedError, match="EXAMPLE is already in this message"):
        MtComposer(extended).add("EXAMPLE", 1).add("EXAMPLE", 2)
    assert read_text("[EXAMPLE=7]", extended) == (EXAMPLE, 7)
    assert apply_mt(message.payload, FIX, extended).accepted == {"INTERVAL": 5, "EXAMPLE": 7, "SOUNDER": True}
    assert by_name(extended)["EXAMPLE"] is EXAMPLE
    listed = (*LISTED, EXAMPLE)
    assert [b.key for b in command_bindings(False, listed)] == ["n", "o", "O", "c", "C", "x"]

    monkeypatch.setattr(iridium_cli, "LISTED", listed)  # the options of `drs mt send`
    monkeypatch.setattr(server_iridium, "CATALOGUE", extended)  # the server composes what they say
    monkeypatch.setattr(server_iridium, "LISTED", listed)
    assert "--example N" in _mt_send_parser().format_help()
    config = tmp_path / "drs.toml"
    config.write_text('[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nimei = "300234010753370"\n')
    assert entry.main(["--config", str(config), "mt", "send", "DRS1", "--example", "7", "--dry-run"]) == 0
    assert "text: [EXAMPLE=7]" in capsys.readouterr().out

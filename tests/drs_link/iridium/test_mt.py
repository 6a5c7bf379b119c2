"""The MT composer: byte-exact against drs_protocol.md 3.8, and read by the firmware model as meant."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest
from hypothesis import given, strategies as st

from drs_link.errors import RefusedError
from drs_link.iridium.commands import apply_mt, parse_hhmm
from drs_link.iridium.firmware import GnssFix
from drs_link.iridium.mt import MtComposer, MtRefusedError


@pytest.mark.parametrize(
    ("composer", "hex_text"),
    [
        (MtComposer().add("INTERVAL", 5), "5B494E54455256414C3D355D"),
        (MtComposer().add("PARACHUTE", (14, 5)), "5B5041524143485554453D31343A30355D"),
        (MtComposer().add("SOUNDER", False), "5B534F554E4445525F4F46465D"),
    ],
)
def test_protocol_examples_are_byte_exact(composer: MtComposer, hex_text: str) -> None:
    assert composer.build().hex == hex_text


def test_several_commands_go_into_one_message_in_firmware_order() -> None:
    message = (
        MtComposer()
        .add("SOUNDER", True)
        .add("PARACHUTE", (0, 7))
        .add("INTERVAL", 1440)
        .add("RBDESTINATION", 0)
        .add("RBSOURCE", 11800)
        .build()
    )
    assert message.text == "[INTERVAL=1440][RBSOURCE=11800][RBDESTINATION=0][PARACHUTE=00:07][SOUNDER_ON]"


def test_sounder_on_and_off_together_are_refused() -> None:
    with pytest.raises(MtRefusedError, match="never send SOUNDER_ON and SOUNDER_OFF together"):
        MtComposer().add("SOUNDER", True).add("SOUNDER", False)


@pytest.mark.parametrize("minutes", [0, 1441, -1, 2.5, True, "5"])
def test_interval_outside_the_firmware_range_is_refused(minutes: object) -> None:
    with pytest.raises(MtRefusedError):
        MtComposer().add("INTERVAL", minutes)  # type: ignore[arg-type]


@pytest.mark.parametrize(("hour", "minute"), [(24, 0), (0, 60), (-1, 5), (0, 845)])
def test_parachute_outside_canonical_time_is_refused(hour: int, minute: int) -> None:
    with pytest.raises(MtRefusedError, match="PARACHUTE"):
        MtComposer().add("PARACHUTE", (hour, minute))


def test_repeated_command_empty_message_and_bad_serial_are_refused_as_refused_errors() -> None:
    with pytest.raises(MtRefusedError, match="already in this message"):
        MtComposer().add("INTERVAL", 5).add("INTERVAL", 6)
    with pytest.raises(RefusedError, match="no command given"):
        MtComposer().build()
    with pytest.raises(MtRefusedError, match="RockBLOCK serial"):
        MtComposer().add("RBDESTINATION", 10_000_000)


@pytest.mark.parametrize("text", ["1405", "14:5", "24:00", "14:60", " 14 :05", "0:845", "１４:05"])
def test_operator_time_must_be_canonical_hhmm(text: str) -> None:
    with pytest.raises(MtRefusedError):
        parse_hhmm(text)


def test_operator_time_canonical_is_accepted() -> None:
    assert parse_hhmm("00:07") == (0, 7)


@given(
    interval=st.none() | st.integers(-5, 1500),
    parachute=st.none() | st.tuples(st.integers(-2, 30), st.integers(-2, 70)),
    sounder=st.none() | st.booleans(),
    destination=st.none() | st.integers(-5, 10_000_001),
    source=st.none() | st.integers(-5, 10_000_001),
)
def test_no_input_makes_the_composer_emit_something_the_firmware_misreads(
    interval, parachute, sounder, destination, source
) -> None:
    composer = MtComposer()
    try:
        if interval is not None:
            composer.add("INTERVAL", interval)
        if parachute is not None:
            composer.add("PARACHUTE", parachute)
        if sounder is not None:
            composer.add("SOUNDER", sounder)
        if destination is not None:
            composer.add("RBDESTINATION", destination)
        if source is not None:
            composer.add("RBSOURCE", source)
        message = composer.build()
    except MtRefusedError:
        return
    payload = message.payload
    assert len(payload) <= 99 and payload.isascii() and b" " not in payload and b"\x00" not in payload
    assert payload == payload.upper()
    fix_minute = parachute[0] * 60 + parachute[1] if parachute else 12 * 60
    fix = GnssFix(datetime(2026, 1, 1, fix_minute // 60, fix_minute % 60, tzinfo=UTC), 0, 0, 0, 0, 0, 1, 5)
    effect = apply_mt(payload, fix)
    assert effect.discarded is None and effect.notes == []
    assert effect.interval == interval
    assert effect.sounder == sounder
    assert effect.rb_destination == destination
    assert effect.rb_source == source
    assert effect.parachute_opens == (parachute is not None)

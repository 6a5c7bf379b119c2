"""The simulated microcontroller and GPIO follow drs_protocol.md, so tests against them mean something."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from drs_link.link.nmea import summarise
from drs_link.sim.firmware import Firmware, GnssSky
from drs_link.sim.gpio import ENABLE_LOW, SET_INPUT, SUPPLY, FakeGpio
from tests.clock import ManualClock

T0 = datetime(2026, 6, 1, 12, 0, 0, tzinfo=UTC)


def at(seconds: float) -> datetime:
    return T0 + timedelta(seconds=seconds)


def _pulse(gpio: FakeGpio, clock: ManualClock, order: list[tuple[int, int]], hold_s: float) -> None:
    for pin, level in order:
        gpio.output(pin, level)
    clock.now += timedelta(seconds=hold_s)
    gpio.output(ENABLE_LOW, 1)
    gpio.output(SET_INPUT, 0)
    gpio.cleanup()


def test_drs_on_sequence_latches_the_relay_and_boots_the_firmware() -> None:
    clock, firmware = ManualClock(T0), Firmware()
    gpio = FakeGpio(firmware, clock)
    _pulse(gpio, clock, [(SUPPLY, 1), (SET_INPUT, 1), (ENABLE_LOW, 0)], 2.0)
    assert gpio.relay_latched and firmware.powered_at == T0 and not gpio.outputs


def test_missing_nor_gate_supply_does_not_latch() -> None:
    clock, firmware = ManualClock(T0), Firmware()
    gpio = FakeGpio(firmware, clock)
    _pulse(gpio, clock, [(SET_INPUT, 1), (ENABLE_LOW, 0)], 2.0)
    assert not gpio.relay_latched and firmware.powered_at is None


def test_gpio2_left_high_does_not_latch() -> None:
    clock, firmware = ManualClock(T0), Firmware()
    gpio = FakeGpio(firmware, clock)
    _pulse(gpio, clock, [(SUPPLY, 1), (SET_INPUT, 1), (ENABLE_LOW, 1)], 2.0)
    assert not gpio.relay_latched


def test_a_glitch_shorter_than_the_coil_pulse_does_not_latch() -> None:
    clock, firmware = ManualClock(T0), Firmware()
    gpio = FakeGpio(firmware, clock)
    _pulse(gpio, clock, [(SUPPLY, 1), (SET_INPUT, 1), (ENABLE_LOW, 0)], 0.1)
    assert not gpio.relay_latched


def test_nmea_only_after_about_23_seconds_of_boot_one_gga_rmc_pair_per_second() -> None:
    firmware = Firmware()
    firmware.relay_latched(T0)
    assert firmware.output_between(at(0), at(23)) == []
    lines = firmware.output_between(at(23), at(26))
    assert len(lines) == 6 and lines[0].startswith("$GPGGA") and lines[1].startswith("$GPRMC")
    assert summarise(lines, at(26)).has_fix


def test_go_is_a_substring_match_on_a_complete_line_while_waiting() -> None:
    firmware = Firmware()
    firmware.relay_latched(T0)
    firmware.receive_from_pi(b"xxGoGoGo", at(30))
    assert firmware.go_at is None
    firmware.receive_from_pi(b"yy\r\n", at(30.5))
    assert firmware.go_at == at(30.5)


def test_go_during_boot_is_ignored() -> None:
    firmware = Firmware()
    firmware.relay_latched(T0)
    firmware.receive_from_pi(b"GoGoGo\n", at(10))
    assert firmware.go_at is None and firmware.state_at(at(30)) == "pi_echo"


def test_go_beyond_the_31_character_buffer_is_garbled_and_ignored() -> None:
    firmware = Firmware()
    firmware.relay_latched(T0)
    firmware.receive_from_pi(b"x" * 40 + b"GoGoGo\n", at(30))
    assert firmware.go_at is None


def test_countdown_is_31_lines_then_gone_mode_and_silence() -> None:
    firmware = Firmware()
    firmware.relay_latched(T0)
    firmware.receive_from_pi(b"GoGoGo\n", at(30))
    countdown = [line for line in firmware.output_between(at(30), at(70)) if line.startswith("Dropping")]
    assert countdown[0] == "Dropping in 30 seconds!" and countdown[-1] == "Dropping in 0 seconds!"
    assert len(countdown) == 31
    assert firmware.state_at(at(63)) == "gone"
    assert [line for line in firmware.output_between(at(63), at(90)) if line.startswith("$")] == []


def test_after_a_drop_the_unit_stays_in_gone_mode_across_a_relay_cycle() -> None:
    firmware = Firmware()
    firmware.relay_latched(T0)
    firmware.receive_from_pi(b"GoGoGo\n", at(30))
    firmware.relay_reset(at(100))
    firmware.relay_latched(at(200))
    assert firmware.output_between(at(200), at(260)) == []


def test_no_fix_sky_sends_time_without_position() -> None:
    firmware = Firmware(GnssSky(fix=False))
    firmware.relay_latched(T0)
    status = summarise(firmware.output_between(at(23), at(25)), at(25))
    assert status.nmea_seen and not status.has_fix and status.latitude is None

"""The firmware model's handling of the quirks in drs_protocol.md 3.8-3.9, and the simulated capsule."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from drs_link.iridium.commands import apply_mt, parachute_accepted
from drs_link.iridium.firmware import NO_FIX_MINUTE_OF_DAY, arduino_to_int, format_mo
from drs_link.iridium.mo import parse_payload
from drs_link.iridium.recovery import detect_landing, distance_bearing, track_from_reports
from drs_link.iridium.reports import Delivery, StoredReport
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedDescent, SimulatedRockblock

from .helpers import IMEI, fix_at

AT_1405 = fix_at(datetime(2026, 7, 1, 14, 5, 30, tzinfo=UTC))


def test_arduino_to_int_reads_leading_digits_and_gives_zero_for_garbage() -> None:
    assert [arduino_to_int(t) for t in ("5", "5abc", "abc", " 7", "-3", "")] == [5, 5, 0, 7, -3, 0]


def test_unchecked_parachute_fields_and_no_fix_quirks_are_modelled() -> None:
    assert apply_mt(b"[PARACHUTE=0:845]", AT_1405).parachute_opens
    assert not apply_mt(b"[PARACHUTE=14:05]", None).parachute_opens
    assert NO_FIX_MINUTE_OF_DAY == 6039 and apply_mt(b"[PARACHUTE=100:39]", None).parachute_opens


def test_midnight_rule_is_loose_as_documented() -> None:
    assert parachute_accepted(14, 1426)
    assert parachute_accepted(1426, 14)
    assert not parachute_accepted(1439, 15)


def test_invalid_commands_are_ignored_and_garbage_serials_become_zero() -> None:
    effect = apply_mt(b"[INTERVAL=abc][RBDESTINATION=abc][RBSOURCE=x]", AT_1405)
    assert effect.interval is None and effect.rb_destination == 0 and effect.rb_source == 0
    assert apply_mt(b"[INTERVAL=1441]", AT_1405).interval is None
    assert apply_mt(b"[SOUNDER_OFF][SOUNDER_ON]", AT_1405).sounder is True


def test_oversized_messages_are_discarded_and_nul_cuts_the_text() -> None:
    assert apply_mt(b"[SOUNDER_OFF]" + b"x" * 88, AT_1405).discarded is not None
    assert apply_mt(b"[SOUNDER_OFF]" + b"x" * 87, AT_1405).discarded is not None
    assert apply_mt(b"[SOUNDER_OFF]" + b"x" * 86, AT_1405).sounder is False
    assert apply_mt(b"[INTERVAL=5]\x00[SOUNDER_OFF]", AT_1405).sounder is None


def test_simulated_capsule_downloads_one_mt_per_session_and_loses_bad_ones() -> None:
    gateway = SimulatedRockblock(imeis=(IMEI,))
    try:
        for text in (b"[PARACHUTE=13:30]", b"[interval=5]", b"[INTERVAL=5]"):
            gateway.queue_mt(
                {"username": gateway.username, "password": gateway.password, "imei": IMEI, "data": text.hex()}
            )
        capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
        first = capsule.session(gateway, AT_1405, AT_1405.time)
        assert first.momsn == 0 and not capsule.parachute_open and len(gateway.queues[IMEI]) == 2
        capsule.session(gateway, AT_1405, AT_1405.time)
        assert capsule.interval_min == 2
        capsule.session(gateway, AT_1405, AT_1405.time)
        assert capsule.interval_min == 5 and capsule.iteration == 3 and not gateway.queues[IMEI]
    finally:
        gateway.stop()


def test_simulated_descent_falls_like_the_real_flights_and_lands_where_recovery_finds_it() -> None:
    release = datetime(2026, 7, 1, 10, 0, tzinfo=UTC)
    descent = SimulatedDescent(release, 46.5, 6.6)
    minutes = (descent.landing_time - release).total_seconds() / 60
    assert 30 <= minutes <= 70, minutes
    reports = []
    for i in range(40):
        moment = release + timedelta(minutes=2 * i, seconds=25)
        payload = format_mo(descent.fix(moment), 8.9, i)
        reports.append(
            StoredReport(i, Delivery(IMEI, i, payload.hex(), "sim", moment), parse_payload(payload))
        )
    landing = detect_landing(track_from_reports(reports))
    assert landing is not None
    ground = descent.fix(descent.landing_time + timedelta(hours=1))
    assert distance_bearing(ground.lat, ground.lon, landing.lat, landing.lon)[0] < 1
    assert abs((landing.landed_at - descent.landing_time).total_seconds()) <= 120

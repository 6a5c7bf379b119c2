"""The MO parser against the firmware's exact formats (drs_protocol.md 3.7) and against garbage."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest
from hypothesis import given, strategies as st

from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.mo import parse_hex, parse_payload

NO_FIX_EXAMPLE = "19700101000000,0.0,0.0,0,0.0,0,0.0,0,0,0.0,8.95,4"


def test_protocol_no_fix_example_is_a_report_without_a_fix() -> None:
    result = parse_hex(NO_FIX_EXAMPLE.encode().hex())
    assert result.accepted, result.reason
    assert result.report is not None
    assert result.report.fix is None
    assert result.report.vbat == 8.95
    assert result.report.iteration == 4
    assert not result.report.forwarding


def test_fix_report_fields_are_read_with_their_units() -> None:
    raw = b"20190922143005,47.492120,-80.561200,28734,12.3,47,1.1,9,0,0.0,8.71,17"
    report = parse_payload(raw).report
    assert report is not None and report.fix is not None
    assert report.fix.time == datetime(2019, 9, 22, 14, 30, 5, tzinfo=UTC)
    assert (report.fix.lat, report.fix.lon, report.fix.alt_m) == (47.49212, -80.5612, 28734)
    assert (report.fix.speed_ms, report.fix.course_deg, report.fix.hdop, report.fix.sats) == (
        12.3,
        47,
        1.1,
        9,
    )
    assert (report.vbat, report.iteration) == (8.71, 17)


def test_forwarding_prefix_and_suffix_are_recorded_and_stripped() -> None:
    raw = b"RB0016366,20190922143005,47.492120,-80.561200,28734,12.3,47,1.1,9,0,0.0,8.71,17,RB0011800"
    report = parse_payload(raw).report
    assert report is not None
    assert (report.rb_destination, report.rb_source) == (16366, 11800)
    assert report.fix is not None and report.fix.lat == 47.49212


def test_firmware_formatted_reports_round_trip_byte_exact() -> None:
    fix = GnssFix(datetime(2026, 1, 2, 3, 4, 5, tzinfo=UTC), -45.1, 170.25, 1234.9, 3.04, 359.7, 0.9, 11)
    raw = format_mo(fix, 8.956, 123, rb_destination=16366, rb_source=11800)
    assert (
        raw == b"RB0016366,20260102030405,-45.100000,170.250000,1234,3.0,359,0.9,11,0,0.0,8.96,123,RB0011800"
    )
    report = parse_payload(raw).report
    assert report is not None and report.fix is not None
    assert report.fix.alt_m == 1234 and report.fix.course_deg == 359
    assert format_mo(None, 8.95, 4) == NO_FIX_EXAMPLE.encode()


def test_truncated_report_is_rejected_with_the_field_count() -> None:
    result = parse_payload(b"20190922143005,47.492120,-80.561200,28734,12.3")
    assert not result.accepted
    assert result.reason == "truncated: 5 fields, a DRS report has 12"


@pytest.mark.parametrize("text", [b"hello from the gateway test page", b"OK,ready", b"[INTERVAL=5]"])
def test_a_message_that_never_was_a_drs_report_is_not_called_truncated(text: bytes) -> None:
    result = parse_payload(text)
    assert not result.accepted and (result.reason or "").startswith("not a DRS report:")


def test_over_long_payload_is_rejected() -> None:
    result = parse_payload(b"1" * 121)
    assert not result.accepted and "over-long: 121 bytes" in (result.reason or "")


def test_bad_hex_and_binary_and_bad_dates_are_rejected_not_raised() -> None:
    assert parse_hex("5B49G").reason == "data is not valid hex"
    assert parse_hex("").reason == "empty payload"
    assert "not printable ASCII" in (parse_payload(b"\x00\xff,1,2").reason or "")
    bad_date = parse_payload(b"20191322143005,47.492120,-80.561200,28734,12.3,47,1.1,9,0,0.0,8.71,17")
    assert "not a valid UTC date" in (bad_date.reason or "")
    bad_nofix = parse_payload(b"19700101000000,1.0,0.0,0,0.0,0,0.0,0,0,0.0,8.95,4")
    assert "non-zero fix fields" in (bad_nofix.reason or "")
    bad_lat = parse_payload(b"20190922143005,47.4921,-80.561200,28734,12.3,47,1.1,9,0,0.0,8.71,17")
    assert bad_lat.reason == "field lat '47.4921' is not in the firmware's format"


@given(st.binary(max_size=200))
def test_parser_never_raises_on_arbitrary_bytes(raw: bytes) -> None:
    result = parse_payload(raw)
    assert result.accepted == (result.reason is None)


@given(st.text(max_size=300))
def test_hex_parser_never_raises_on_arbitrary_text(text: str) -> None:
    result = parse_hex(text)
    assert result.accepted == (result.reason is None)


@given(
    st.datetimes(min_value=datetime(2000, 1, 1), max_value=datetime(2099, 12, 31)),
    st.floats(-90, 90),
    st.floats(-180, 180),
    st.floats(-500, 45000),
    st.floats(0, 300),
    st.floats(0, 359.99),
    st.floats(0, 99.9),
    st.integers(0, 40),
    st.floats(0, 12),
    st.integers(0, 10**6),
    st.integers(0, 9_999_999),
    st.integers(0, 9_999_999),
)
def test_every_firmware_report_parses_back_to_its_values(
    moment, lat, lon, alt, speed, course, hdop, sats, vbat, iteration, dest, source
) -> None:
    fix = GnssFix(moment.replace(microsecond=0, tzinfo=UTC), lat, lon, alt, speed, course, hdop, sats)
    result = parse_payload(format_mo(fix, vbat, iteration, dest, source))
    assert result.accepted, result.reason
    report = result.report
    assert report is not None and report.fix is not None
    assert report.fix.time == fix.time
    assert abs(report.fix.lat - lat) <= 5e-7 and abs(report.fix.lon - lon) <= 5e-7
    assert report.iteration == iteration
    assert report.rb_destination == (dest if dest > 0 else None)


@pytest.mark.parametrize("altitude", ["999999", "-99999", "60001"])
def test_an_altitude_no_capsule_can_have_is_rejected_naming_it(altitude: str) -> None:
    """#24 item 12: the format's six digits let 999,999 m through as the capsule's fix."""
    result = parse_payload(
        f"20190922143005,47.492120,-80.561200,{altitude},12.3,47,1.1,9,0,0.0,8.71,17".encode()
    )
    assert (
        not result.accepted
        and result.reason is not None
        and "m is beyond anywhere a capsule can be" in result.reason
    )

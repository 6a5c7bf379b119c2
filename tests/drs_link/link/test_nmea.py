"""NMEA parsing: the fields an operator reads before Go, and garbage never being fatal."""

from __future__ import annotations

from datetime import UTC, datetime

import pytest
from hypothesis import given, settings, strategies as st

from drs_link.link.nmea import (
    GgaSentence,
    RmcSentence,
    date_problem,
    format_gga,
    format_rmc,
    nmea_checksum,
    parse_sentence,
    summarise,
)

# A real u-blox sentence pair (checksums computed by the receiver, not by this code).
REAL_GGA = "$GPGGA,092750.000,5321.6802,N,00630.3372,W,1,8,1.03,61.7,M,55.2,M,,*76"
REAL_RMC = "$GPRMC,092750.000,A,5321.6802,N,00630.3372,W,0.02,31.66,280511,,,A*43"
NOW = datetime(2011, 5, 28, 9, 28, 0, tzinfo=UTC)


def test_real_gga_gives_position_fix_quality_satellites_and_hdop() -> None:
    gga = parse_sentence(REAL_GGA)
    assert isinstance(gga, GgaSentence)
    assert gga.latitude == pytest.approx(53 + 21.6802 / 60)
    assert gga.longitude == pytest.approx(-(6 + 30.3372 / 60))
    assert (gga.fix_quality, gga.satellites, gga.hdop, gga.altitude_m) == (1, 8, 1.03, 61.7)
    assert gga.time_utc is not None and gga.time_utc.hour == 9 and gga.time_utc.second == 50


def test_real_rmc_gives_date_and_validity() -> None:
    rmc = parse_sentence(REAL_RMC)
    assert isinstance(rmc, RmcSentence)
    assert rmc.valid and rmc.date_utc is not None and rmc.date_utc.isoformat() == "2011-05-28"


def test_gn_talker_is_accepted_like_gp() -> None:
    line = format_gga(NOW, 10.5, -20.25, 1, 7, 1.2, 100.0, talker="GN")
    gga = parse_sentence(line)
    assert isinstance(gga, GgaSentence) and gga.talker == "GN" and gga.latitude == pytest.approx(10.5)


def test_flipped_character_is_a_checksum_failure_not_an_exception() -> None:
    assert parse_sentence(REAL_GGA.replace("5321", "5322")) == "bad_checksum"


@pytest.mark.parametrize(
    "line",
    [
        "$GPGGA,092750.000,5321.6802,N",
        "GoGoGo",
        "$GPGGA,xx,5321.6802,N,00630.3372,W,1,8,1.03,61.7,M,55.2,M,,*",
        "$GPGGA,092750.000,9921.6802,N,00630.3372,W,1,8,1.03,61.7,M,55.2,M,,*00",
        "\x00\x00$GPRMC,,Z,,,,,,,,,,*00",
    ],
)
def test_truncated_or_garbled_lines_are_reported_malformed(line: str) -> None:
    assert parse_sentence(line) in ("malformed", "bad_checksum")


def test_sentences_other_than_gga_and_rmc_are_ignored_not_counted_as_errors() -> None:
    body = "GPGSV,1,1,00"
    assert parse_sentence(f"${body}*{nmea_checksum(body):02X}") is None


def test_summary_counts_good_bad_and_garbled_and_keeps_the_latest_fix() -> None:
    lines = [
        "",
        "Dropping in 30 seconds!",
        REAL_GGA.replace("5321", "5322"),
        REAL_GGA,
        REAL_RMC,
        "$GPGGA,0927",
    ]
    status = summarise(lines, NOW)
    assert status.nmea_seen and status.has_fix
    assert (status.counts.parsed, status.counts.malformed, status.counts.bad_checksum) == (2, 2, 1)
    assert status.fix_time_utc == datetime(2011, 5, 28, 9, 27, 50, tzinfo=UTC)
    assert status.age_s == pytest.approx(10.0)


def test_time_without_position_means_tracking_but_no_fix() -> None:
    lines = [format_gga(NOW, None, None, 0, 3, None, None), format_rmc(NOW, None, None)]
    status = summarise(lines, NOW)
    assert status.nmea_seen and not status.has_fix and status.fix_quality == 0
    assert status.fix_quality_name == "no fix" and status.satellites == 3


def test_empty_log_means_no_nmea_seen() -> None:
    status = summarise([], NOW)
    assert not status.nmea_seen and status.fix_quality is None and status.age_s is None


def test_gga_without_rmc_takes_the_date_before_now_across_midnight() -> None:
    late = datetime(2026, 1, 1, 23, 59, 50, tzinfo=UTC)
    status = summarise(
        [format_gga(late, 1.0, 2.0, 1, 5, 1.0, 10.0)], datetime(2026, 1, 2, 0, 0, 5, tzinfo=UTC)
    )
    assert status.fix_time_utc == late and status.age_s == pytest.approx(15.0)


def _rmc_dated(ddmmyy: str, hhmmss: str = "095959") -> str:
    body = f"GPRMC,{hhmmss}.00,A,5321.6802,N,00630.3372,W,0.02,31.66,{ddmmyy},,,A"
    return f"${body}*{nmea_checksum(body):02X}"


def test_a_gps_week_rollover_date_is_named_and_left_out_of_the_fix_time() -> None:
    """2019-04-07 was a 1024-week rollover: an unpatched receiver then said 1999-08-22 (`220899`)."""
    now = datetime(2019, 4, 8, 10, 0, 0, tzinfo=UTC)
    gga = format_gga(datetime(2019, 4, 8, 9, 59, 59, tzinfo=UTC), 53.36, -6.5, 1, 8, 1.0, 61.7)
    status = summarise([_rmc_dated("220899"), gga], now)
    assert status.date_problem is not None and "GPS week rollover" in status.date_problem
    assert "1999-08-22" in status.date_problem
    assert status.fix_time_utc == datetime(2019, 4, 8, 9, 59, 59, tzinfo=UTC)
    assert status.age_s == pytest.approx(1.0)
    assert status.as_dict()["date_problem"] == status.date_problem


def test_a_two_digit_year_in_the_nineties_is_read_as_the_nineteen_nineties_not_2099() -> None:
    rmc = parse_sentence(_rmc_dated("220899"))
    assert isinstance(rmc, RmcSentence) and rmc.date_utc is not None and rmc.date_utc.year == 1999


def test_a_date_far_from_the_clock_is_left_out_and_never_gives_a_negative_age() -> None:
    now = datetime(2026, 11, 24, 10, 0, 0, tzinfo=UTC)
    gga = format_gga(datetime(2026, 11, 24, 9, 59, 50, tzinfo=UTC), 53.36, -6.5, 1, 8, 1.0, 61.7)
    status = summarise([_rmc_dated("220899"), gga], now)
    assert status.date_problem is not None and "behind the clock" in status.date_problem
    assert status.age_s == pytest.approx(10.0)
    ahead = summarise([_rmc_dated("241236"), gga], now)
    assert ahead.date_problem is not None and "ahead of the clock" in ahead.date_problem
    assert ahead.age_s == pytest.approx(10.0)


def test_todays_date_and_a_fix_just_after_midnight_are_plausible() -> None:
    now = datetime(2026, 11, 25, 0, 0, 30, tzinfo=UTC)
    assert date_problem(datetime(2026, 11, 24).date(), now) is None
    assert date_problem(datetime(2026, 11, 25).date(), now) is None
    assert date_problem(datetime(2026, 11, 21).date(), now) is not None


def test_binary_bytes_before_the_dollar_do_not_hide_the_sentence() -> None:
    noisy = "\xb5b\x01\x07\x5c\x00" + REAL_GGA
    status = summarise([noisy, REAL_RMC], NOW)
    assert status.has_fix and status.counts.parsed == 2 and status.counts.malformed == 0


@settings(max_examples=300, deadline=None)
@given(st.text(max_size=120))
def test_arbitrary_text_never_raises(text: str) -> None:
    assert parse_sentence(text) in ("malformed", "bad_checksum", None) or isinstance(
        parse_sentence(text), GgaSentence | RmcSentence
    )
    summarise(text.splitlines(), NOW)


@settings(max_examples=300, deadline=None)
@given(st.binary(max_size=200))
def test_arbitrary_serial_bytes_never_raise(data: bytes) -> None:
    summarise(data.decode("ascii", errors="replace").splitlines(), NOW)


coordinates = st.tuples(
    st.floats(min_value=-89.9, max_value=89.9, allow_nan=False),
    st.floats(min_value=-179.9, max_value=179.9, allow_nan=False),
)


@settings(max_examples=200, deadline=None)
@given(
    coordinates,
    st.integers(0, 8),
    st.integers(0, 40),
    st.floats(min_value=0.5, max_value=50, allow_nan=False),
    st.sampled_from(["GP", "GN"]),
)
def test_formatted_gga_round_trips(
    position: tuple[float, float], quality: int, sats: int, hdop: float, talker: str
) -> None:
    lat, lon = position
    gga = parse_sentence(format_gga(NOW, lat, lon, quality, sats, hdop, 1234.5, talker=talker))
    assert isinstance(gga, GgaSentence)
    assert gga.latitude == pytest.approx(lat, abs=1e-6) and gga.longitude == pytest.approx(lon, abs=1e-6)
    assert (gga.fix_quality, gga.satellites, gga.talker) == (quality, sats, talker)


@settings(max_examples=300, deadline=None)
@given(st.integers(0, len(REAL_GGA) - 1), st.characters(min_codepoint=32, max_codepoint=126))
def test_any_single_character_corruption_is_rejected(position: int, char: str) -> None:
    mutated = REAL_GGA[:position] + char + REAL_GGA[position + 1 :]
    if mutated != REAL_GGA:
        assert parse_sentence(mutated) in ("malformed", "bad_checksum")


def test_the_in_talker_is_read_like_gp_and_gn() -> None:
    """#25 item 9: an integrated-navigation receiver's $INGGA/$INRMC were ignored, so no fix was shown."""
    gga = parse_sentence(format_gga(NOW, 10.5, -20.25, 1, 7, 1.2, 100.0, talker="IN"))
    rmc = parse_sentence(format_rmc(NOW, 10.5, -20.25, talker="IN"))
    assert isinstance(gga, GgaSentence) and gga.talker == "IN" and gga.altitude_m == 100.0
    assert isinstance(rmc, RmcSentence) and rmc.talker == "IN" and rmc.valid


@pytest.mark.parametrize(
    ("satellites", "altitude"), [(7, "1e308"), (28000, "100.0"), (7, "999999.0"), (7, "-5000.0")]
)
def test_impossible_altitudes_and_satellite_counts_are_malformed(satellites: int, altitude: str) -> None:
    """#24 item 12: GGA altitudes of 1e308 and 28,000 satellites were shown as the capsule's fix."""
    body = f"GPGGA,092750.000,5321.6802,N,00630.3372,W,1,{satellites},1.03,{altitude},M,55.2,M,,"
    assert parse_sentence(f"${body}*{nmea_checksum(body):02X}") == "malformed"

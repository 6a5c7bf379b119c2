"""The balloon feed (issue #5): every format and rejection, and real UDP, TCP and files end to end."""

from __future__ import annotations

import json
import socket
import threading
import time
import tomllib
from collections.abc import Callable, Iterator
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest
from hypothesis import given, settings, strategies as st

from console.commands.main import main
from drs_link.config import BalloonFeedConfig, Config, parse_config
from drs_link.errors import ConfigError, LinkError
from drs_link.feeds.balloon_feed import (
    ALTITUDE_ABSURD,
    BAD_CHECKSUM,
    FUTURE_TIME,
    LATITUDE_RANGE,
    LONGITUDE_RANGE,
    MALFORMED,
    MISSING_ALTITUDE,
    MISSING_TIME,
    NO_FIX,
    NON_FINITE,
    PARTIAL,
    TOO_LONG,
    UNRECOGNISED,
    BalloonFeed,
    BalloonFix,
    FeedListener,
    Rejection,
    format_ozimux,
    parse_feed_line,
    reconnect_delay_s,
)
from drs_link.link.nmea import format_gga, format_rmc, nmea_checksum
from drs_link.ops.fleet import FleetState
from drs_link.ops.telemetry import BalloonSample, TelemetryRecord
from tests.clock import ManualClock
from tests.ports import free_port

NOW = datetime(2026, 6, 20, 12, 0, 0, tzinfo=UTC)
# A real u-blox sentence (checksum computed by the receiver, not by this code), 2011-05-28 09:27:50.
REAL_GGA = "$GPGGA,092750.000,5321.6802,N,00630.3372,W,1,8,1.03,61.7,M,55.2,M,,*76"
# The example of OziPlotter's input documentation and a radiosonde_auto_rx payload summary.
OZIPLOTTER_EXAMPLE = "TELEMETRY,01:05:20,-34.12345,138.12345,10123\n"
AUTO_RX_SUMMARY = {
    "type": "PAYLOAD_SUMMARY",
    "callsign": "R3330018",
    "latitude": 55.6,
    "longitude": 12.3,
    "altitude": 24117,
    "speed": 31.2,
    "heading": 88.0,
    "time": "11:59:40",
    "comment": "Radiosonde",
    "model": "RS41",
    "station": "OZ1SKY_AUTO_RX",
}


def ozimux(moment: datetime, lat: float = 67.89, lon: float = 21.1, alt: float = 30_000.0) -> bytes:
    return format_ozimux(moment, lat, lon, alt).encode()


def with_checksum(body: str) -> str:
    return f"${body}*{nmea_checksum(body):02X}"


def wait_for(condition: Callable[[], bool], what: str, timeout_s: float = 15.0) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            pytest.fail(f"timed out after {timeout_s} s waiting for {what}")
        time.sleep(0.01)


@pytest.fixture
def feeds() -> Iterator[Callable[..., BalloonFeed]]:
    started: list[BalloonFeed] = []

    def start(
        config: BalloonFeedConfig, clock: ManualClock, listener: FeedListener | None = None
    ) -> BalloonFeed:
        feed = BalloonFeed(config, clock, listener)
        feed.start()
        started.append(feed)
        return feed

    yield start
    for feed in started:
        feed.stop()


# --- the line parser ------------------------------------------------------------------------


def test_real_gga_is_a_fix_at_its_time_of_day() -> None:
    fix = parse_feed_line(REAL_GGA, datetime(2011, 5, 28, 9, 28, 0, tzinfo=UTC))
    assert isinstance(fix, BalloonFix)
    assert fix.time == datetime(2011, 5, 28, 9, 27, 50, tzinfo=UTC)
    assert (fix.lat, fix.lon) == (pytest.approx(53 + 21.6802 / 60), pytest.approx(-(6 + 30.3372 / 60)))
    assert (fix.alt_m, fix.format) == (61.7, "nmea-gga")


@pytest.mark.parametrize("talker", ["GP", "GN"])
def test_gga_of_every_talker_nmea_accepts(talker: str) -> None:
    line = format_gga(NOW - timedelta(seconds=3), 67.5, -21.25, 2, 9, 0.9, 31_250.0, talker=talker)
    fix = parse_feed_line(line, NOW)
    assert isinstance(fix, BalloonFix)
    assert (fix.lat, fix.lon, fix.alt_m) == (pytest.approx(67.5), pytest.approx(-21.25), 31_250.0)
    assert fix.time == NOW - timedelta(seconds=3)


@pytest.mark.parametrize(
    "line",
    [OZIPLOTTER_EXAMPLE, OZIPLOTTER_EXAMPLE.strip(), "TELEMETRY,01:05:20,-34.12345,138.12345,10123.4\r\n"],
)
def test_ozimux_telemetry_with_or_without_line_end(line: str) -> None:
    fix = parse_feed_line(line, datetime(2026, 6, 20, 1, 6, 0, tzinfo=UTC))
    assert isinstance(fix, BalloonFix) and fix.format == "ozimux"
    assert (fix.lat, fix.lon, round(fix.alt_m)) == (-34.12345, 138.12345, 10123)
    assert fix.time == datetime(2026, 6, 20, 1, 5, 20, tzinfo=UTC)


def test_horus_payload_summary_keeps_the_callsign() -> None:
    fix = parse_feed_line(json.dumps(AUTO_RX_SUMMARY), NOW)
    assert fix == BalloonFix(
        datetime(2026, 6, 20, 11, 59, 40, tzinfo=UTC), 55.6, 12.3, 24117.0, "horus", "R3330018"
    )


@pytest.mark.parametrize(
    ("times", "expected"),
    [
        ({"time_string": "11:59:45", "time": 1781956785}, datetime(2026, 6, 20, 11, 59, 45, tzinfo=UTC)),
        ({"time": "11:59:50"}, datetime(2026, 6, 20, 11, 59, 50, tzinfo=UTC)),
    ],
)
def test_horus_payload_telemetry_is_a_fix_timed_by_its_time_string_as_chasemapper_reads_it(
    times: dict[str, object], expected: datetime
) -> None:
    packet = {k: v for k, v in AUTO_RX_SUMMARY.items() if k != "time"} | {
        "type": "PAYLOAD_TELEMETRY",
        **times,
    }
    fix = parse_feed_line(json.dumps(packet), NOW)
    assert fix == BalloonFix(expected, 55.6, 12.3, 24117.0, "horus", "R3330018")


@pytest.mark.parametrize(
    ("stamp", "expected"),
    [
        ("2026-06-20T11:59:30Z", datetime(2026, 6, 20, 11, 59, 30, tzinfo=UTC)),
        ("2026-06-20T11:59:30.250+00:00", datetime(2026, 6, 20, 11, 59, 30, 250_000, tzinfo=UTC)),
        ("2026-06-20T13:59:30+02:00", datetime(2026, 6, 20, 11, 59, 30, tzinfo=UTC)),
    ],
)
def test_plain_json_with_an_iso_time(stamp: str, expected: datetime) -> None:
    line = json.dumps(
        {"lat": 67.9, "lon": 21.0, "alt_m": 29_000.5, "time": stamp, "note": "extra keys are fine"}
    )
    assert parse_feed_line(line, NOW) == BalloonFix(expected, 67.9, 21.0, 29_000.5, "json")


@pytest.mark.parametrize(
    "line",
    [
        format_rmc(NOW, 67.0, 21.0),
        with_checksum("GPGSV,1,1,00"),
        "WAYPOINT,VK5QI-9,-34.12345,138.1234,QSY 439.900",
        json.dumps({"type": "MODEM_STATS", "snr": 12.0}),
        "   ",
    ],
)
def test_lines_without_a_balloon_position_are_ignored_not_rejected(line: str) -> None:
    assert parse_feed_line(line, NOW) is None


def _summary(**changes: object) -> str:
    document = {**AUTO_RX_SUMMARY, **changes}
    return json.dumps({k: v for k, v in document.items() if v is not None}, allow_nan=True)


def _plain(**changes: object) -> str:
    document = {"lat": 67.9, "lon": 21.0, "alt_m": 29_000.0, "time": "2026-06-20T11:59:00Z", **changes}
    return json.dumps({k: v for k, v in document.items() if v is not None}, allow_nan=True)


@pytest.mark.parametrize(
    ("line", "reason", "detail"),
    [
        (REAL_GGA.replace("5321", "5322"), BAD_CHECKSUM, "bad checksum"),
        (format_gga(NOW, 67.0, 21.0, 0, 3, 9.9, 30_000.0), NO_FIX, "fix quality 0"),
        (format_gga(NOW, None, None, 1, 3, 9.9, 30_000.0), NO_FIX, "without a position"),
        (format_gga(NOW, 67.0, 21.0, 1, 8, 1.0, None), MISSING_ALTITUDE, "GGA without an altitude"),
        (
            with_checksum("GPGGA,,6700.000,N,02100.000,E,1,08,1.0,30000.0,M,,,,"),
            MISSING_TIME,
            "GGA without a time",
        ),
        (with_checksum("GPGGA,120000.00,6700.000,N"), MALFORMED, "malformed NMEA"),
        ("TELEMETRY,11:59:00,91.5,21.0,30000", LATITUDE_RANGE, "latitude out of range: 91.5"),
        ("TELEMETRY,11:59:00,-90.01,21.0,30000", LATITUDE_RANGE, "-90.01"),
        ("TELEMETRY,11:59:00,67.0,180.5,30000", LONGITUDE_RANGE, "longitude out of range: 180.5"),
        (_summary(longitude=-181), LONGITUDE_RANGE, "-181"),
        ("TELEMETRY,11:59:00,nan,21.0,30000", NON_FINITE, "latitude is 'nan'"),
        ("TELEMETRY,11:59:00,67.0,21.0,inf", NON_FINITE, "altitude is 'inf'"),
        (_plain(lon=float("inf")), NON_FINITE, "lon is inf"),
        (_summary(latitude=float("nan")), NON_FINITE, "latitude is nan"),
        ('{"lat": 1e999, "lon": 21.0, "alt_m": 1, "time": "2026-06-20T11:59:00Z"}', NON_FINITE, "lat is inf"),
        (
            '{"lat": ' + "9" * 400 + ', "lon": 2, "alt_m": 1, "time": "2026-06-20T11:59:00Z"}',
            NON_FINITE,
            "too large",
        ),
        ("TELEMETRY,11:59:00,67.0,21.0", MISSING_ALTITUDE, "ends after the longitude"),
        ("TELEMETRY,11:59:00,67.0,21.0,", MISSING_ALTITUDE, "altitude is empty"),
        (_summary(altitude=None), MISSING_ALTITUDE, "PAYLOAD_SUMMARY without an altitude"),
        (_plain(alt_m=None), MISSING_ALTITUDE, "no alt_m"),
        ("TELEMETRY,11:59:00,67.0,21.0,60001", ALTITUDE_ABSURD, "60001 m"),
        ("TELEMETRY,11:59:00,67.0,21.0,-501", ALTITUDE_ABSURD, "-501 m"),
        (_summary(altitude=123456), ALTITUDE_ABSURD, "123456 m"),
        ("TELEMETRY,12:05:01,67.0,21.0,30000", FUTURE_TIME, "301 s ahead"),
        (_summary(time="12:10:00"), FUTURE_TIME, "600 s ahead"),
        (_plain(time="2026-06-21T12:00:00Z"), FUTURE_TIME, "86400 s ahead"),
        ("TELEMETRY,11:59:00,0.0,0.0,30000", NO_FIX, "position 0, 0"),
        (_summary(time=None), MISSING_TIME, "PAYLOAD_SUMMARY without a time"),
        (_plain(time=None), MISSING_TIME, "no time"),
        ("GGA,120000,6700.000,N", UNRECOGNISED, "not NMEA, OziMux TELEMETRY or a JSON object"),
        ('{"speed": 3}', UNRECOGNISED, "neither type nor lat/lon"),
        ("TELEMETRY," + "9" * 5000, TOO_LONG, "over 4096 bytes"),
        ("TELEMETRY,11:59:00,67.0,21.0,30000,extra", MALFORMED, "6 fields, expected 5"),
        ("TELEMETRY,11:59,67.0,21.0,30000", MALFORMED, "expected HH:MM:SS"),
        ("TELEMETRY,25:00:00,67.0,21.0,30000", MALFORMED, "not a time of day"),
        ("TELEMETRY,11:59:00,north,21.0,30000", MALFORMED, "malformed latitude 'north'"),
        (_summary(latitude="55.6"), MALFORMED, "malformed latitude '55.6': not a number"),
        (_plain(lat=True), MALFORMED, "malformed lat True"),
        (_plain(lon=None), MALFORMED, "no lon"),
        (_plain(time="2026-06-20T11:59:00"), MALFORMED, "no UTC offset"),
        (_plain(time="yesterday"), MALFORMED, "not ISO 8601"),
        (_plain(time=1750420740), MALFORMED, "expected an ISO 8601 UTC string"),
        (_plain(time="0001-01-01T00:00:00+01:00"), MALFORMED, "out of range"),
        (_summary(time=42), MALFORMED, "expected HH:MM:SS"),
        ('{"lat": 67.9, "lon": ', MALFORMED, "malformed JSON"),
        ('{"a": ' + "[" * 3000, MALFORMED, "malformed JSON"),
    ],
)
def test_every_rejection_names_its_reason(line: str, reason: str, detail: str) -> None:
    outcome = parse_feed_line(line, NOW)
    assert isinstance(outcome, Rejection), outcome
    assert outcome.reason == reason and detail in outcome.detail
    assert outcome.line and len(outcome.line) <= 60 and "\n" not in outcome.line


def test_a_fix_up_to_300_s_ahead_of_the_clock_is_accepted() -> None:
    assert isinstance(parse_feed_line("TELEMETRY,12:05:00,67.0,21.0,30000", NOW), BalloonFix)


@pytest.mark.parametrize(
    ("now", "line", "expected"),
    [
        # Just after midnight, a fix from just before it is yesterday's.
        (
            datetime(2026, 1, 2, 0, 0, 5, tzinfo=UTC),
            "TELEMETRY,23:59:58,67.0,21.0,30000",
            datetime(2026, 1, 1, 23, 59, 58, tzinfo=UTC),
        ),
        # Just before midnight, a sender whose clock is a little ahead is already in tomorrow.
        (
            datetime(2026, 1, 1, 23, 59, 58, tzinfo=UTC),
            format_gga(datetime(2026, 1, 2, 0, 0, 3, tzinfo=UTC), 67.0, 21.0, 1, 8, 1.0, 30_000.0),
            datetime(2026, 1, 2, 0, 0, 3, tzinfo=UTC),
        ),
        (
            datetime(2026, 12, 31, 23, 59, 59, tzinfo=UTC),
            _summary(time="00:01:00"),
            datetime(2027, 1, 1, 0, 1, 0, tzinfo=UTC),
        ),
    ],
)
def test_time_of_day_resolves_to_the_instant_nearest_the_clock_across_midnight(
    now: datetime, line: str, expected: datetime
) -> None:
    fix = parse_feed_line(line, now)
    assert isinstance(fix, BalloonFix) and fix.time == expected


def test_record_is_a_balloon_record_the_console_folds_and_the_recorder_round_trips() -> None:
    fix = parse_feed_line(json.dumps(AUTO_RX_SUMMARY), NOW)
    assert isinstance(fix, BalloonFix)
    record = fix.record("udp 0.0.0.0:8942", NOW)
    assert (record.kind, record.capsule, record.time) == ("balloon", None, fix.time)
    assert record.data == BalloonSample(
        lat=55.6,
        lon=12.3,
        alt_m=24117.0,
        format="horus",
        source="udp 0.0.0.0:8942",
        received_at=datetime(2026, 6, 20, 12, 0, tzinfo=UTC),
        callsign="R3330018",
    )
    assert TelemetryRecord.from_json(record.to_json(), "test") == record
    fleet = FleetState.for_capsules(["DRS1"])
    fleet.apply(record)
    assert fleet.balloon.is_fresh(NOW) and fleet.balloon.value == record.data
    assert not fleet.balloon.is_fresh(fix.time + timedelta(seconds=121))


feed_like = st.one_of(
    st.text(max_size=200),
    st.builds(lambda s: "TELEMETRY," + s, st.text(alphabet="0123456789:.,-+eEinfa N", max_size=60)),
    st.builds(lambda s: "$GPGGA," + s, st.text(max_size=80)),
    st.builds(lambda s: "{" + s, st.text(max_size=80)),
    st.binary(max_size=200).map(lambda b: b.decode("utf-8", errors="replace")),
)
json_values = st.recursive(
    st.none()
    | st.booleans()
    | st.integers()
    | st.floats(allow_nan=True, allow_infinity=True)
    | st.text(max_size=30)
    | st.sampled_from(["12:00:00", "23:59:60", "2026-06-20T11:59:00Z", "PAYLOAD_SUMMARY"]),
    lambda children: (
        st.lists(children, max_size=3) | st.dictionaries(st.text(max_size=5), children, max_size=3)
    ),
    max_leaves=8,
)
json_objects = st.dictionaries(
    st.sampled_from(["type", "lat", "lon", "alt_m", "time", "latitude", "longitude", "altitude", "callsign"]),
    json_values,
).map(lambda d: json.dumps(d, allow_nan=True))
clocks = st.datetimes(min_value=datetime(2000, 1, 1), max_value=datetime(2100, 1, 1), timezones=st.just(UTC))


@settings(max_examples=500, deadline=None)
@given(line=st.one_of(feed_like, json_objects), now=clocks)
def test_any_line_gives_a_fix_a_rejection_or_nothing_and_never_raises(line: str, now: datetime) -> None:
    outcome = parse_feed_line(line, now)
    assert outcome is None or isinstance(outcome, BalloonFix | Rejection)
    if isinstance(outcome, BalloonFix):
        assert -90 <= outcome.lat <= 90 and -180 <= outcome.lon <= 180 and -500 <= outcome.alt_m <= 60_000
        assert (outcome.time - now).total_seconds() <= 300
    if isinstance(outcome, Rejection):
        assert outcome.detail.startswith(outcome.reason)


@settings(max_examples=200, deadline=None)
@given(
    lat=st.floats(-90, 90),
    lon=st.floats(-180, 180),
    alt=st.floats(-500, 60_000),
    age_s=st.integers(0, 11 * 3600),
    now=clocks,
)
def test_format_ozimux_round_trips(lat: float, lon: float, alt: float, age_s: int, now: datetime) -> None:
    moment = (now - timedelta(seconds=age_s)).replace(microsecond=0)
    outcome = parse_feed_line(format_ozimux(moment, lat, lon, alt), now)
    if round(lat, 5) == 0 and round(lon, 5) == 0:
        assert isinstance(outcome, Rejection) and outcome.reason == NO_FIX
        return
    assert isinstance(outcome, BalloonFix) and outcome.time == moment
    assert outcome.lat == pytest.approx(lat, abs=6e-6) and outcome.lon == pytest.approx(lon, abs=6e-6)
    assert outcome.alt_m == pytest.approx(alt, abs=0.5)


def test_format_ozimux_refuses_a_naive_time() -> None:
    with pytest.raises(ValueError, match="naive"):
        format_ozimux(datetime(2026, 1, 1), 1.0, 2.0, 3.0)


def test_reconnect_backoff_doubles_to_30_s() -> None:
    assert [reconnect_delay_s(n) for n in range(8)] == [1, 2, 4, 8, 16, 30, 30, 30]


# --- UDP ------------------------------------------------------------------------------------


def test_udp_datagrams_with_several_lines_each_line_judged(feeds: Callable[..., BalloonFeed]) -> None:
    port = free_port(socket.SOCK_DGRAM)
    clock = ManualClock(NOW)
    feed = feeds(BalloonFeedConfig(kind="udp", port=port), clock)
    assert feed.status().state == "listening" and feed.status().source == f"udp 127.0.0.1:{port}"
    first = format_gga(NOW - timedelta(seconds=20), 67.0, 21.0, 1, 8, 1.0, 29_000.0) + "\r\n"
    datagram = (first + format_rmc(NOW, 67.0, 21.0) + "\n" + "TELEMETRY,11:59:50,67.1,21.1,95000\n").encode()
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        sender.sendto(datagram, ("127.0.0.1", port))
        sender.sendto(
            ozimux(NOW - timedelta(seconds=5), lat=67.2) + b"\xff\xfe\x00 garbage\n", ("127.0.0.1", port)
        )
        wait_for(lambda: feed.status().rejected == 2, "the altitude and the garbage rejected")
    status = feed.status()
    assert (status.accepted, status.ignored, status.out_of_order) == (2, 1, 0)
    assert dict(status.reasons) == {ALTITUDE_ABSURD: 1, UNRECOGNISED: 1}
    assert status.last_rejection is not None and status.last_rejection.startswith("unrecognised format")
    assert status.last_rejected_line is not None and "garbage" in status.last_rejected_line
    record = feed.latest()
    assert record is not None and record.data.lat == 67.2 and record.time == NOW - timedelta(seconds=5)
    assert record.data.source == f"udp 127.0.0.1:{port}" and record.data.format == "ozimux"
    assert feed.latest() is None


def test_udp_reordered_and_repeated_fixes_are_dropped_and_midnight_is_not_a_reorder(
    feeds: Callable[..., BalloonFeed],
) -> None:
    port = free_port(socket.SOCK_DGRAM)
    clock = ManualClock(datetime(2026, 1, 1, 23, 59, 59, 500_000, tzinfo=UTC))
    feed = feeds(BalloonFeedConfig(kind="udp", port=port), clock)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:

        def send(line: bytes, seen: int) -> None:
            sender.sendto(line, ("127.0.0.1", port))
            wait_for(lambda: feed.status().accepted + feed.status().out_of_order == seen, f"line {seen}")

        send(b"TELEMETRY,23:59:59,67.0,21.0,30000", 1)
        send(b"TELEMETRY,23:59:50,67.0,21.0,30000", 2)
        send(b"TELEMETRY,23:59:59,67.0,21.0,30000", 3)
        clock.now = datetime(2026, 1, 2, 0, 0, 1, 500_000, tzinfo=UTC)
        send(b"TELEMETRY,00:00:01,67.5,21.5,30010", 4)
        send(b"TELEMETRY,23:59:59,67.0,21.0,30000", 5)
    status = feed.status()
    assert (status.accepted, status.out_of_order, status.rejected) == (2, 3, 0)
    record = feed.latest()
    assert record is not None and record.time == datetime(2026, 1, 2, 0, 0, 1, tzinfo=UTC)
    assert record.data.received_at == datetime(2026, 1, 2, 0, 0, 1, 500_000, tzinfo=UTC)


def test_udp_port_in_use_fails_at_start_with_the_address_and_reason() -> None:
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as holder:
        holder.bind(("127.0.0.1", 0))
        port = holder.getsockname()[1]
        feed = BalloonFeed(BalloonFeedConfig(kind="udp", port=port), lambda: NOW)
        with pytest.raises(LinkError, match=f"udp 127.0.0.1:{port}: Address already in use"):
            feed.start()
        feed.stop()


def test_udp_address_not_on_this_machine_fails_at_start() -> None:
    feed = BalloonFeed(BalloonFeedConfig(kind="udp", host="192.0.2.1", port=8942), lambda: NOW)
    with pytest.raises(LinkError, match="udp 192.0.2.1:8942: Cannot assign requested address"):
        feed.start()
    feed.stop()


def test_a_failing_listener_does_not_stop_the_feed_and_stop_ends_the_thread(
    feeds: Callable[..., BalloonFeed],
) -> None:
    port = free_port(socket.SOCK_DGRAM)
    seen: list[BalloonFix | Rejection] = []

    def listener(outcome: BalloonFix | Rejection) -> None:
        seen.append(outcome)
        raise RuntimeError("a buggy listener")

    feed = feeds(BalloonFeedConfig(kind="udp", port=port), ManualClock(NOW), listener=listener)
    with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
        sender.sendto(b"nonsense", ("127.0.0.1", port))
        sender.sendto(ozimux(NOW), ("127.0.0.1", port))
        wait_for(lambda: feed.status().accepted == 1, "the fix after a listener failure")
    assert [type(o) for o in seen] == [Rejection, BalloonFix]
    feed.stop()
    assert feed.status().state == "stopped"
    assert not [t for t in threading.enumerate() if t.name == f"balloon feed {feed.source}"]


# --- TCP ------------------------------------------------------------------------------------


class GroundStation:
    """A real TCP server on loopback, as a ground station forwarding its positions."""

    def __init__(self, port: int = 0) -> None:
        self.listener = socket.socket(socket.AF_INET, socket.SOCK_STREAM)
        self.listener.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
        self.listener.bind(("127.0.0.1", port))
        self.listener.listen()
        self.port: int = self.listener.getsockname()[1]
        self.client: socket.socket | None = None

    def accept(self, timeout_s: float = 15.0) -> None:
        self.listener.settimeout(timeout_s)
        self.client, _ = self.listener.accept()

    def send(self, data: bytes) -> None:
        assert self.client is not None
        self.client.sendall(data)

    def drop(self) -> None:
        assert self.client is not None
        self.client.close()
        self.client = None

    def close(self) -> None:
        if self.client is not None:
            self.drop()
        self.listener.close()


def test_tcp_client_survives_drops_mid_line_refusal_and_a_restarted_server(
    feeds: Callable[..., BalloonFeed],
) -> None:
    station = GroundStation()
    port = station.port
    outcomes: list[BalloonFix | Rejection] = []
    feed = feeds(BalloonFeedConfig(kind="tcp", port=port), ManualClock(NOW), listener=outcomes.append)
    try:
        station.accept()
        wait_for(lambda: feed.status().state == "connected", "connected")
        station.send(ozimux(NOW - timedelta(seconds=30))[:20])
        station.send(ozimux(NOW - timedelta(seconds=30))[20:] + b"TELEMETRY,11:59:31,67.0,")
        wait_for(lambda: feed.status().accepted == 1, "a fix sent in two pieces")
        station.drop()
        wait_for(lambda: feed.status().rejected == 1, "the partial line counted")
        assert feed.status().reasons == ((PARTIAL, 1),)
        assert feed.status().last_rejected_line == "TELEMETRY,11:59:31,67.0,"
        assert "closed by 127.0.0.1" in (feed.status().last_error or "")

        station.accept()
        station.send(b"x" * 3000)
        station.send(b"y" * 3000)
        station.send(b"z" * 3000 + b"\n" + ozimux(NOW - timedelta(seconds=20)))
        wait_for(lambda: feed.status().accepted == 2, "a fix after a runaway line, on the new connection")
        assert dict(feed.status().reasons) == {PARTIAL: 1, TOO_LONG: 1}

        station.close()
        wait_for(
            lambda: (
                "Connection refused" in (feed.status().last_error or "")
                and feed.status().state.startswith("reconnecting in ")
            ),
            "the refusal reported and a reconnection planned",
        )
        station = GroundStation(port)
        station.accept(timeout_s=40.0)
        station.send(ozimux(NOW - timedelta(seconds=10), lat=68.0))
        wait_for(lambda: feed.status().accepted == 3, "a fix from the restarted server")
    finally:
        station.close()
    record = feed.latest()
    assert record is not None and record.data.lat == 68.0 and record.data.source == f"tcp 127.0.0.1:{port}"
    assert [o.reason if isinstance(o, Rejection) else o.format for o in outcomes] == [
        "ozimux",
        PARTIAL,
        TOO_LONG,
        "ozimux",
        "ozimux",
    ]


def test_tcp_stop_while_waiting_to_reconnect_ends_the_thread() -> None:
    station = GroundStation()
    station.close()  # nothing listens on its port any more
    port = station.port
    feed = BalloonFeed(BalloonFeedConfig(kind="tcp", port=port), lambda: NOW)
    feed.start()
    wait_for(lambda: feed.status().state.startswith("reconnecting in"), "the first refusal")
    feed.stop()
    assert not [t for t in threading.enumerate() if t.name == f"balloon feed {feed.source}"]


# --- file -----------------------------------------------------------------------------------


def test_file_feed_follows_appends_truncation_rotation_and_removal(
    tmp_path: Path, feeds: Callable[..., BalloonFeed]
) -> None:
    path = tmp_path / "groundstation.log"
    base = NOW - timedelta(minutes=10)
    lines = [ozimux(base + timedelta(seconds=s)) for s in range(3)]
    path.write_bytes(b"".join(lines) + ozimux(base + timedelta(seconds=3))[:15])
    feed = feeds(BalloonFeedConfig(kind="file", path=path), ManualClock(NOW))
    wait_for(lambda: feed.status().accepted == 1, "the last complete line at start")
    first = feed.latest()
    assert first is not None and first.time == base + timedelta(seconds=2)
    assert feed.status().state == f"following {path}" and feed.status().source == f"file {path}"

    with path.open("ab") as log:
        log.write(ozimux(base + timedelta(seconds=3))[15:])
        log.flush()
        wait_for(lambda: feed.status().accepted == 2, "the line finished by the writer")
        log.write(ozimux(base + timedelta(seconds=4)) + b"TELEMETRY,11:50:05,")
    wait_for(lambda: feed.status().accepted == 3, "an appended line")

    path.write_bytes(ozimux(base + timedelta(seconds=6)))
    wait_for(lambda: feed.status().accepted == 4, "a line after truncation")
    assert feed.status().reasons == ((PARTIAL, 1),)

    with path.open("ab") as log:
        log.write(ozimux(base + timedelta(seconds=7)) + b"TELEMETRY,")
    wait_for(lambda: feed.status().accepted == 5, "a line before rotation")
    path.rename(tmp_path / "groundstation.log.1")
    path.write_bytes(ozimux(base + timedelta(seconds=8)))
    wait_for(lambda: feed.status().accepted == 6, "the first line of the new file")
    assert dict(feed.status().reasons) == {PARTIAL: 2}

    path.unlink()
    wait_for(lambda: feed.status().state == f"waiting for {path}", "waiting for the removed log")
    path.write_bytes(ozimux(base + timedelta(seconds=9), lat=66.0))
    wait_for(lambda: feed.status().accepted == 7, "a line from the recreated log")
    record = feed.latest()
    assert record is not None and record.data.lat == 66.0 and record.time == base + timedelta(seconds=9)
    assert (feed.status().rejected, feed.status().out_of_order) == (2, 0)


def test_a_fix_taken_from_a_log_at_start_is_never_seen_beside_the_state_not_started(
    tmp_path: Path, feeds: Callable[..., BalloonFeed]
) -> None:
    """The console shows count and state together: a fix under "not started" reads as a feed that lies."""
    path = tmp_path / "groundstation.log"
    path.write_bytes(ozimux(NOW - timedelta(seconds=5)))
    seen: list[tuple[int, str]] = []
    feed: BalloonFeed | None = None
    started = threading.Event()

    def listener(outcome: BalloonFix | Rejection) -> None:
        started.wait(60.0)  # until ``feed`` is assigned below: a loaded machine can take seconds
        assert feed is not None
        seen.append((feed.status().accepted, feed.status().state))

    feed = feeds(BalloonFeedConfig(kind="file", path=path), ManualClock(NOW), listener=listener)
    started.set()
    wait_for(lambda: bool(seen), "the listener told of the last line")
    assert seen == [(1, f"following {path}")]


def test_file_missing_at_start_is_waited_for_then_read_from_its_start(
    tmp_path: Path, feeds: Callable[..., BalloonFeed]
) -> None:
    path = tmp_path / "later.log"
    feed = feeds(BalloonFeedConfig(kind="file", path=path), ManualClock(NOW))
    wait_for(lambda: feed.status().state == f"waiting for {path}", "waiting")
    path.write_bytes(ozimux(NOW - timedelta(seconds=2)) + b"\xff\xff\n" + ozimux(NOW - timedelta(seconds=1)))
    wait_for(lambda: feed.status().accepted == 2, "both lines of the new file")
    assert feed.status().rejected == 1


def test_file_whose_end_is_one_runaway_line_gives_no_position_until_a_new_line(
    tmp_path: Path, feeds: Callable[..., BalloonFeed]
) -> None:
    path = tmp_path / "noise.log"
    path.write_bytes(ozimux(NOW - timedelta(seconds=9)) + b"n" * 20_000)
    feed = feeds(BalloonFeedConfig(kind="file", path=path), ManualClock(NOW))
    wait_for(lambda: feed.status().state == f"following {path}", "following")
    with path.open("ab") as log:
        log.write(b"\n" + ozimux(NOW - timedelta(seconds=1)))
    wait_for(lambda: feed.status().accepted == 1, "the line after the noise")
    record = feed.latest()
    assert record is not None and record.time == NOW - timedelta(seconds=1)
    assert feed.status().rejected == 0


# --- configuration --------------------------------------------------------------------------


def test_no_balloon_feed_by_default_and_network_defaults_are_ozimux_on_loopback() -> None:
    assert Config().balloon_feed.kind == "" and parse_config({}).balloon_feed == BalloonFeedConfig()
    feed = parse_config({"balloon_feed": {"kind": "udp"}}).balloon_feed
    assert (feed.host, feed.port, feed.path) == ("127.0.0.1", 8942, None)
    with pytest.raises(ConfigError, match="no balloon feed configured"):
        BalloonFeed(parse_config({}).balloon_feed, lambda: NOW)


def test_file_feed_path_is_expanded(monkeypatch: pytest.MonkeyPatch, tmp_path: Path) -> None:
    monkeypatch.setenv("DRS_FEED_DIR", str(tmp_path))
    feed = parse_config({"balloon_feed": {"kind": "file", "path": "$DRS_FEED_DIR/gs.log"}}).balloon_feed
    assert feed.path == tmp_path / "gs.log"


@pytest.mark.parametrize(
    ("table", "message"),
    [
        ({"kind": "serial"}, r"balloon_feed.kind: 'serial' is not one of 'udp', 'tcp', 'file'"),
        ({"kind": 1}, "balloon_feed.kind: expected a string"),
        ({"host": "gs.local"}, "balloon_feed.kind: required when"),
        ({"kind": "udp", "port": 0}, "balloon_feed.port: 0 is not a UDP port"),
        ({"kind": "tcp", "port": 70000}, "balloon_feed.port: 70000 is not a TCP port"),
        ({"kind": "udp", "port": "8942"}, "balloon_feed.port: expected a whole number"),
        ({"kind": "udp", "host": ""}, "balloon_feed.host"),
        ({"kind": "tcp", "host": "ground station"}, "balloon_feed.host"),
        ({"kind": "file"}, "balloon_feed.path: a file feed needs the path"),
        ({"kind": "file", "path": ""}, "balloon_feed.path: expected a path"),
        ({"kind": "udp", "path": "/var/log/gs.log"}, "balloon_feed.path: only a file feed reads a path"),
        ({"kind": "tcp", "path": "/var/log/gs.log"}, "balloon_feed.path: only a file feed"),
        ({"kind": "file", "path": "/x.log", "host": "gs"}, "balloon_feed.host: a file feed reads"),
        ({"kind": "file", "path": "/x.log", "port": 1}, "balloon_feed.port: a file feed reads"),
        ({"kind": "udp", "prot": 8942}, "balloon_feed.prot: unknown key"),
    ],
)
def test_bad_balloon_feed_settings_name_the_key(table: dict[str, object], message: str) -> None:
    with pytest.raises(ConfigError, match=message):
        parse_config({"balloon_feed": table})


def test_balloon_feed_section_must_be_a_table() -> None:
    with pytest.raises(ConfigError, match="balloon_feed: expected a table"):
        parse_config({"balloon_feed": "udp"})


def test_docs_example_is_a_valid_balloon_feed() -> None:
    text = (Path(__file__).resolve().parents[3] / "docs" / "console.md").read_text()
    section = text[text.index("## Balloon feed") :]
    start = section.index("```toml\n") + len("```toml\n")
    feed = parse_config(tomllib.loads(section[start : section.index("```", start)])).balloon_feed
    assert (feed.kind, feed.host, feed.port) == ("udp", "0.0.0.0", 8942)


# --- drs balloon watch ----------------------------------------------------------------------


@pytest.fixture
def udp_config(tmp_path: Path) -> tuple[Path, int]:
    port = free_port(socket.SOCK_DGRAM)
    path = tmp_path / "drs.toml"
    path.write_text(f'[balloon_feed]\nkind = "udp"\nhost = "127.0.0.1"\nport = {port}\n')
    return path, port


def _sender(port: int, lines: Callable[[int], bytes]) -> tuple[threading.Thread, threading.Event]:
    """Sends until told to stop: the command binds its port at some moment this thread cannot see."""
    stop = threading.Event()

    def run() -> None:
        with socket.socket(socket.AF_INET, socket.SOCK_DGRAM) as sender:
            n = 0
            while not stop.is_set():
                sender.sendto(lines(n), ("127.0.0.1", port))
                n += 1
                stop.wait(0.02)

    thread = threading.Thread(target=run, daemon=True)
    thread.start()
    return thread, stop


def test_watch_prints_fixes_and_rejections_and_exits_0_after_count(
    udp_config: tuple[Path, int], capsys: pytest.CaptureFixture[str]
) -> None:
    path, port = udp_config
    start = datetime.now(UTC) - timedelta(hours=1)

    def lines(n: int) -> bytes:
        if n % 2:
            return b"$GPGGA,bad*00"
        return format_ozimux(start + timedelta(seconds=n), 67.5, 21.25, 30_000.0).encode()

    thread, stop = _sender(port, lines)
    try:
        code = main(["--config", str(path), "balloon", "watch", "--count", "3", "--timeout", "30"])
    finally:
        stop.set()
        thread.join()
    out = capsys.readouterr().out.splitlines()
    assert code == 0
    assert out[0] == f"watching the balloon feed from udp 127.0.0.1:{port}"
    fixes = [line for line in out if line.endswith("ozimux")]
    assert len(fixes) == 3 and all(" 67.50000   21.25000    30000 m  ozimux" in line for line in fixes)
    assert any(line.startswith("rejected: bad checksum") and "[$GPGGA,bad*00]" in line for line in out)


def test_watch_json_is_one_object_per_line_as_it_happens(
    udp_config: tuple[Path, int], capsys: pytest.CaptureFixture[str]
) -> None:
    path, port = udp_config
    start = datetime.now(UTC).replace(microsecond=0) - timedelta(hours=1)

    def lines(n: int) -> bytes:
        if n % 2:
            return b"$GPGGA,bad*00"
        return format_ozimux(start + timedelta(seconds=n), 67.5, 21.25, 30_000.0).encode()

    thread, stop = _sender(port, lines)
    try:
        code = main(["--config", str(path), "balloon", "watch", "--count", "2", "--json"])
    finally:
        stop.set()
        thread.join()
    events = [json.loads(line) for line in capsys.readouterr().out.splitlines()]
    assert code == 0 and events[0] == {"event": "watching", "source": f"udp 127.0.0.1:{port}"}
    fixes = [e for e in events if e["event"] == "fix"]
    assert len(fixes) == 2 and all((f["lat"], f["lon"], f["alt_m"], f["format"]) == (67.5, 21.25, 30000.0, "ozimux")
                                   for f in fixes)  # fmt: skip
    assert datetime.fromisoformat(fixes[0]["time_utc"].replace("Z", "+00:00")) >= start
    rejected = [e for e in events if e["event"] == "rejected"]
    assert rejected and rejected[0]["line"] == "$GPGGA,bad*00" and "checksum" in rejected[0]["detail"]


def test_watch_times_out_saying_what_was_rejected(
    udp_config: tuple[Path, int], capsys: pytest.CaptureFixture[str]
) -> None:
    path, port = udp_config
    thread, stop = _sender(port, lambda n: REAL_GGA.replace("5321", "5322").encode())
    try:
        code = main(["--config", str(path), "balloon", "watch", "--timeout", "1.5"])
    finally:
        stop.set()
        thread.join()
    captured = capsys.readouterr()
    assert code == 1
    assert captured.err.startswith(f"drs: error: no balloon position from udp 127.0.0.1:{port} in 1.5 s (")
    assert captured.err.rstrip().endswith("rejected: bad checksum)")
    assert "rejected: bad checksum" in captured.out


def test_watch_without_a_feed_configured_is_a_clear_error(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = tmp_path / "drs.toml"
    path.write_text('[operator]\nname = "EL"\n')
    assert main(["--config", str(path), "balloon", "watch"]) == 1
    assert "no balloon feed configured" in capsys.readouterr().err


def test_watch_refuses_a_count_of_zero(
    udp_config: tuple[Path, int], capsys: pytest.CaptureFixture[str]
) -> None:
    with pytest.raises(SystemExit) as exit_info:
        main(["--config", str(udp_config[0]), "balloon", "watch", "--count", "0"])
    assert exit_info.value.code == 2 and "--count: 0 must be at least 1" in capsys.readouterr().err


def test_a_gga_line_with_ublox_binary_before_the_dollar_is_read_as_the_capsule_log_reads_it() -> None:
    """A u-blox receiver in mixed UBX/NMEA mode puts binary bytes before the `$` of a sentence."""
    line = "\xb5b\x01\x07\x5c\x00" + REAL_GGA
    fix = parse_feed_line(line, datetime(2011, 5, 28, 9, 28, 0, tzinfo=UTC))
    assert isinstance(fix, BalloonFix)
    assert (round(fix.lat, 4), round(fix.lon, 4), fix.alt_m) == (53.3613, -6.5056, 61.7)
    garbage = parse_feed_line("\xb5b\x01\x07" + REAL_GGA[:-1] + "0", NOW)
    assert isinstance(garbage, Rejection) and garbage.reason == BAD_CHECKSUM

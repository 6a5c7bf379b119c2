"""The balloon's position from a ground station on the LAN, before any capsule's GNSS is on.

A capsule's own GNSS exists only minutes before a drop, but "release now" needs the balloon's
position all flight. Flight teams get it from the launch provider's or their own ground station,
which forwards it as NMEA GGA, OziMux ``TELEMETRY`` text (horus-gui, radiosonde_auto_rx) or Horus
``PAYLOAD_SUMMARY`` / ``PAYLOAD_TELEMETRY`` JSON, over UDP, a TCP server, or a log file. Every line
is judged on its own: a bad one is counted and shown with its reason, never fatal, and never taken
as a position. UDP reorders datagrams, so a fix not newer than the newest accepted one is dropped.
Time comes from the injected clock only (the demo runs a fast one).
"""

from __future__ import annotations

import errno
import json
import logging
import math
import os
import re
import selectors
import socket
import threading
from collections import Counter
from collections.abc import Callable
from dataclasses import dataclass
from datetime import UTC, datetime, time
from pathlib import Path
from typing import BinaryIO

from drs_link.config import BalloonFeedConfig
from drs_link.errors import ConfigError, LinkError
from drs_link.link import GgaSentence, find_sentence, nearest_datetime, parse_sentence
from drs_link.ops import BalloonSample, TelemetryRecord
from drs_link.store import iso_utc

log = logging.getLogger(__name__)

MAX_LINE_BYTES = 4096
FUTURE_LIMIT_S = 300.0
"""A fix further ahead of our clock than this is a wrong clock somewhere, not a position to trust."""
ALTITUDE_RANGE_M = (-500.0, 60_000.0)
BACKOFF_S = (1, 2, 4, 8, 16, 30)
CONNECT_TIMEOUT_S = 10.0
FILE_POLL_S = 0.2
TAIL_BYTES = 2 * (MAX_LINE_BYTES + 1)
"""Enough of a file's end to hold its last complete line and an unfinished one after it."""
SHOWN_LINE_CHARS = 60

FORMATS = ("nmea-gga", "ozimux", "horus", "json")
HORUS_POSITION_TYPES = ("PAYLOAD_SUMMARY", "PAYLOAD_TELEMETRY")
"""Horus UDP packets that carry a position (chasemapper reads both; the second names its time ``time_string``)."""
OWN_COMMENT = "drs-console"
"""How our chase feed's packets begin their comment (``drs_link.feeds.chase``): capsules, never the balloon."""

BAD_CHECKSUM = "bad checksum"
MALFORMED = "malformed"
NO_FIX = "no fix"
LATITUDE_RANGE = "latitude out of range"
LONGITUDE_RANGE = "longitude out of range"
NON_FINITE = "non-finite number"
MISSING_ALTITUDE = "missing altitude"
MISSING_TIME = "missing time"
ALTITUDE_ABSURD = "altitude absurd"
FUTURE_TIME = "time in the future"
UNRECOGNISED = "unrecognised format"
TOO_LONG = "line too long"
PARTIAL = "partial line"

_CLOCK_RE = re.compile(r"(\d{2}):(\d{2}):(\d{2})(?:\.(\d{1,6}))?", re.ASCII)


@dataclass(frozen=True)
class BalloonFix:
    time: datetime
    lat: float
    lon: float
    alt_m: float
    format: str
    callsign: str | None = None

    def record(self, source: str, received_at: datetime) -> TelemetryRecord:
        """The console's balloon record: timed by the fix, so a late line ages as it should."""
        sample = BalloonSample(
            self.lat, self.lon, self.alt_m, self.format, source, received_at, self.callsign
        )
        return TelemetryRecord(self.time, None, sample)


@dataclass(frozen=True)
class Rejection:
    """A line that carried no usable position: ``reason`` groups them, ``detail`` says what was wrong."""

    reason: str
    detail: str
    line: str


class _Reject(Exception):
    """Internal: the line under parse is rejected (never escapes ``parse_feed_line``)."""

    def __init__(self, reason: str, detail: str | None = None) -> None:
        super().__init__(detail or reason)
        self.reason = reason
        self.detail = detail or reason


def shorten(text: str, limit: int = SHOWN_LINE_CHARS) -> str:
    """A line fit to show an operator: control characters made visible, long ones cut."""
    visible = "".join(c if c.isprintable() else "?" for c in text)
    return visible if len(visible) <= limit else visible[: limit - 1] + "…"


def parse_feed_line(line: str, now: datetime) -> BalloonFix | Rejection | None:
    """One line of a feed → a fix, a rejection with its reason, or ``None`` for a line without a position.

    ``None`` is a well-formed line of a kind that carries no balloon position (RMC, OziMux
    WAYPOINT, other Horus packet types, a blank line): counted as ignored, not as an error.
    Never raises: a feed is untrusted network input.
    """
    text = line.strip()
    if len(line) > MAX_LINE_BYTES:
        return _too_long(line)
    fix: BalloonFix | None
    try:
        if not text:
            return None
        if text.startswith("TELEMETRY,"):
            fix = _from_ozimux(text, now)
        elif text.startswith("WAYPOINT,"):
            return None
        elif text.startswith("{"):
            fix = _from_json(text, now)
        elif (sentence := find_sentence(text)) is not None:
            fix = _from_nmea(sentence, now)
        else:
            raise _Reject(UNRECOGNISED, "unrecognised format: not NMEA, OziMux TELEMETRY or a JSON object")
        if fix is not None:
            _check(fix, now)
        return fix
    except _Reject as reject:
        return Rejection(reject.reason, reject.detail, shorten(text))


def format_ozimux(moment: datetime, lat: float, lon: float, alt_m: float) -> str:
    """An OziMux TELEMETRY line as horus-gui sends it (UTC time of day, decimal degrees, whole metres)."""
    if moment.tzinfo is None:
        raise ValueError("naive datetime: OziMux times are UTC and must say so")
    return f"TELEMETRY,{moment.astimezone(UTC):%H:%M:%S},{lat:.5f},{lon:.5f},{alt_m:.0f}\n"


def _too_long(line: str) -> Rejection:
    return Rejection(TOO_LONG, f"line too long (over {MAX_LINE_BYTES} bytes)", shorten(line))


def _from_nmea(text: str, now: datetime) -> BalloonFix | None:
    sentence = parse_sentence(text)
    if isinstance(sentence, str):
        if sentence == "bad_checksum":
            raise _Reject(BAD_CHECKSUM, "bad checksum: the sentence does not match its *hh")
        raise _Reject(MALFORMED, "malformed NMEA sentence")
    if not isinstance(sentence, GgaSentence):
        return None
    if sentence.fix_quality == 0:
        raise _Reject(NO_FIX, "no fix: GGA fix quality 0")
    if sentence.latitude is None or sentence.longitude is None:
        raise _Reject(NO_FIX, "no fix: GGA without a position")
    if sentence.altitude_m is None:
        raise _Reject(MISSING_ALTITUDE, "missing altitude: GGA without an altitude")
    if sentence.time_utc is None:
        raise _Reject(MISSING_TIME, "missing time: GGA without a time")
    moment = nearest_datetime(sentence.time_utc, now)
    return BalloonFix(moment, sentence.latitude, sentence.longitude, sentence.altitude_m, "nmea-gga")


def _from_ozimux(text: str, now: datetime) -> BalloonFix:
    fields = text.split(",")
    if len(fields) == 4:
        raise _Reject(MISSING_ALTITUDE, "missing altitude: the OziMux line ends after the longitude")
    if len(fields) != 5:
        raise _Reject(
            MALFORMED, f"malformed OziMux line: {len(fields)} fields, expected 5 (TELEMETRY,time,lat,lon,alt)"
        )
    _, clock, lat, lon, alt = fields
    if not alt.strip():
        raise _Reject(MISSING_ALTITUDE, "missing altitude: the OziMux line's altitude is empty")
    return BalloonFix(
        nearest_datetime(_time_of_day(clock), now),
        _text_number("latitude", lat),
        _text_number("longitude", lon),
        _text_number("altitude", alt),
        "ozimux",
    )


def _from_json(text: str, now: datetime) -> BalloonFix | None:
    try:
        document = json.loads(text)
    except (ValueError, RecursionError):
        raise _Reject(MALFORMED, "malformed JSON") from None
    if not isinstance(document, dict):
        raise _Reject(MALFORMED, "malformed JSON: not an object")
    if "type" in document:
        if document["type"] not in HORUS_POSITION_TYPES:
            return None
        if str(document.get("comment", "")).startswith(OWN_COMMENT):
            return None  # a capsule our chase feed sent to the same port, not the balloon
        return _from_horus(document, now)
    if "lat" in document or "lon" in document:
        return _from_plain_json(document)
    raise _Reject(UNRECOGNISED, "unrecognised format: a JSON object with neither type nor lat/lon")


def _from_horus(document: dict[str, object], now: datetime) -> BalloonFix:
    kind = document["type"]
    lat, lon = _json_number(document, "latitude"), _json_number(document, "longitude")
    if document.get("altitude") is None:
        raise _Reject(MISSING_ALTITUDE, f"missing altitude: {kind} without an altitude")
    alt = _json_number(document, "altitude")
    clock = document.get("time_string") if kind == "PAYLOAD_TELEMETRY" else None
    clock = document.get("time") if clock is None else clock
    if clock is None:
        raise _Reject(MISSING_TIME, f"missing time: {kind} without a time (an older sender?)")
    if not isinstance(clock, str):
        raise _Reject(MALFORMED, f"malformed time {shorten(repr(clock), 30)}: expected HH:MM:SS")
    callsign = document.get("callsign")
    moment = nearest_datetime(_time_of_day(clock), now)
    return BalloonFix(moment, lat, lon, alt, "horus", callsign if isinstance(callsign, str) else None)


def _from_plain_json(document: dict[str, object]) -> BalloonFix:
    lat, lon = _json_number(document, "lat"), _json_number(document, "lon")
    if document.get("alt_m") is None:
        raise _Reject(MISSING_ALTITUDE, "missing altitude: no alt_m")
    alt = _json_number(document, "alt_m")
    if document.get("time") is None:
        raise _Reject(MISSING_TIME, "missing time: no time")
    return BalloonFix(_iso_time(document["time"]), lat, lon, alt, "json")


def _time_of_day(text: str) -> time:
    match = _CLOCK_RE.fullmatch(text.strip())
    if match is None:
        raise _Reject(MALFORMED, f"malformed time {shorten(repr(text), 30)}: expected HH:MM:SS")
    hour, minute, second = int(match[1]), int(match[2]), int(match[3])
    if hour > 23 or minute > 59 or second > 60:
        raise _Reject(MALFORMED, f"malformed time {text.strip()!r}: not a time of day")
    micro = int((match[4] or "").ljust(6, "0"))
    return time(hour, minute, min(second, 59), micro, tzinfo=UTC)


def _iso_time(value: object) -> datetime:
    shown = shorten(repr(value), 40)
    if not isinstance(value, str):
        raise _Reject(MALFORMED, f"malformed time {shown}: expected an ISO 8601 UTC string")
    try:
        moment = datetime.fromisoformat(value)
    except ValueError:
        raise _Reject(MALFORMED, f"malformed time {shown}: not ISO 8601") from None
    if moment.tzinfo is None:
        raise _Reject(MALFORMED, f"malformed time {shown}: no UTC offset (end it with Z)")
    try:
        return moment.astimezone(UTC)
    except OverflowError:
        raise _Reject(MALFORMED, f"malformed time {shown}: out of range") from None


def _text_number(name: str, text: str) -> float:
    try:
        value = float(text)
    except ValueError:
        raise _Reject(MALFORMED, f"malformed {name} {shorten(repr(text), 30)}: not a number") from None
    if not math.isfinite(value):
        raise _Reject(NON_FINITE, f"non-finite number: {name} is {text.strip()!r}")
    return value


def _json_number(document: dict[str, object], key: str) -> float:
    if key not in document:
        raise _Reject(MALFORMED, f"malformed JSON: no {key}")
    value = document[key]
    if isinstance(value, bool) or not isinstance(value, int | float):
        raise _Reject(MALFORMED, f"malformed {key} {shorten(repr(value), 30)}: not a number")
    try:
        number = float(value)
    except OverflowError:
        raise _Reject(NON_FINITE, f"non-finite number: {key} is too large") from None
    if not math.isfinite(number):
        raise _Reject(NON_FINITE, f"non-finite number: {key} is {value!r}")
    return number


def _check(fix: BalloonFix, now: datetime) -> None:
    if not -90.0 <= fix.lat <= 90.0:
        raise _Reject(LATITUDE_RANGE, f"latitude out of range: {fix.lat:g} (-90 to 90)")
    if not -180.0 <= fix.lon <= 180.0:
        raise _Reject(LONGITUDE_RANGE, f"longitude out of range: {fix.lon:g} (-180 to 180)")
    if fix.lat == 0.0 and fix.lon == 0.0:
        raise _Reject(NO_FIX, "no fix: position 0, 0 (what senders report without a fix)")
    low, high = ALTITUDE_RANGE_M
    if not low <= fix.alt_m <= high:
        raise _Reject(ALTITUDE_ABSURD, f"altitude absurd: {fix.alt_m:g} m (expected {low:g} to {high:g} m)")
    ahead = (fix.time - now).total_seconds()
    if ahead > FUTURE_LIMIT_S:
        raise _Reject(
            FUTURE_TIME, f"time in the future: {iso_utc(fix.time)} is {ahead:.0f} s ahead of the clock"
        )


class _LineSplitter:
    """Bytes from a stream in, complete lines out; a runaway line is cut, so memory stays bounded."""

    def __init__(self) -> None:
        self._buffer = bytearray()
        self._discarding = False

    def feed(self, data: bytes) -> list[bytes]:
        """Complete lines; a line over the limit comes out once, as its first ``MAX_LINE_BYTES + 1`` bytes."""
        lines: list[bytes] = []
        self._buffer += data
        while True:
            end = self._buffer.find(b"\n")
            if end < 0:
                break
            line = bytes(self._buffer[:end])
            del self._buffer[: end + 1]
            if self._discarding:
                self._discarding = False
            else:
                lines.append(line)
        if len(self._buffer) > MAX_LINE_BYTES:
            if not self._discarding:
                lines.append(bytes(self._buffer[: MAX_LINE_BYTES + 1]))
            self._buffer.clear()
            self._discarding = True
        return lines

    def take_partial(self) -> bytes:
        """The unfinished line (cut by a drop, a truncation or a rotation), forgotten from now on."""
        partial = b"" if self._discarding else bytes(self._buffer)
        self._buffer.clear()
        self._discarding = False
        return partial

    def skip_current_line(self) -> None:
        self._buffer.clear()
        self._discarding = True


@dataclass(frozen=True)
class FeedStatus:
    """What the operator needs to judge a feed: where from, is it up, and what it did with each line."""

    source: str
    state: str
    accepted: int = 0
    rejected: int = 0
    ignored: int = 0
    out_of_order: int = 0
    last_rejection: str | None = None
    last_rejected_line: str | None = None
    last_error: str | None = None
    reasons: tuple[tuple[str, int], ...] = ()
    """Rejections by reason, most frequent first."""


FeedListener = Callable[[BalloonFix | Rejection], None]


def reconnect_delay_s(attempt: int) -> int:
    """1, 2, 4 … 30 s: quick after a blip, gentle on a ground station that is down for long."""
    return BACKOFF_S[min(attempt, len(BACKOFF_S) - 1)]


def source_label(config: BalloonFeedConfig) -> str:
    if config.kind == "file":
        return f"file {config.path}"
    return f"{config.kind} {config.host}:{config.port}"


class BalloonFeed:
    """Reads one configured source on its own thread; ``latest()`` hands each new fix to the console once.

    ``listener`` (optional) sees every accepted fix and every rejection, on the reading thread, in
    order: ``drs balloon watch`` prints them. ``clock`` must return UTC-aware datetimes.
    """

    def __init__(
        self, config: BalloonFeedConfig, clock: Callable[[], datetime], listener: FeedListener | None = None
    ) -> None:
        if config.kind not in ("udp", "tcp", "file"):
            raise ConfigError(
                'balloon_feed: no balloon feed configured (add [balloon_feed] with kind = "udp", "tcp" or "file")'
            )
        self.config = config
        self.source = source_label(config)
        self._clock = clock
        self._listener = listener
        self._lock = threading.Lock()
        self._state = "not started"
        self._counts: Counter[str] = Counter()
        self._reasons: Counter[str] = Counter()
        self._last_rejection: Rejection | None = None
        self._last_error: str | None = None
        self._newest: datetime | None = None
        self._pending: TelemetryRecord | None = None
        self._stop = threading.Event()
        self._wake_reader, self._wake_writer = socket.socketpair()
        self._udp: socket.socket | None = None
        self._thread: threading.Thread | None = None

    def start(self) -> None:
        """Start reading; a UDP port that cannot be bound fails here, naming the address and the OS reason."""
        if self._thread is not None:
            raise LinkError(f"the balloon feed from {self.source} is already started")
        if self.config.kind == "udp":
            self._udp = self._bind_udp()
            self._set_state("listening")
        self._thread = threading.Thread(target=self._run, name=f"balloon feed {self.source}", daemon=True)
        self._thread.start()

    def stop(self) -> None:
        self._stop.set()
        try:
            self._wake_writer.send(b"x")
        except OSError:
            pass
        if self._thread is not None:
            self._thread.join(timeout=5.0)
        if self._udp is not None:
            self._udp.close()
        self._wake_reader.close()
        self._wake_writer.close()
        self._set_state("stopped")

    def latest(self) -> TelemetryRecord | None:
        """The newest accepted fix's record, once: ``None`` until a newer fix arrives."""
        with self._lock:
            record, self._pending = self._pending, None
            return record

    def status(self) -> FeedStatus:
        with self._lock:
            last = self._last_rejection
            return FeedStatus(
                source=self.source,
                state=self._state,
                accepted=self._counts["accepted"],
                rejected=self._counts["rejected"],
                ignored=self._counts["ignored"],
                out_of_order=self._counts["out_of_order"],
                last_rejection=last.detail if last else None,
                last_rejected_line=last.line if last else None,
                last_error=self._last_error,
                reasons=tuple(self._reasons.most_common()),
            )

    # --- the reading thread -------------------------------------------------------------------

    def _run(self) -> None:
        readers = {"udp": self._run_udp, "tcp": self._run_tcp, "file": self._run_file}
        while not self._stop.is_set():
            try:
                readers[self.config.kind]()
            except Exception as exc:  # the thread outlives any bug: the console keeps its other sources
                log.exception("balloon feed %s: reader failed; restarting it", self.source)
                self._error(f"reader failed ({type(exc).__name__}: {exc}); restarting")
                self._stop.wait(BACKOFF_S[0])

    def _bind_udp(self) -> socket.socket:
        host, port = self.config.host, self.config.port
        try:
            family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_DGRAM)[0]
            sock = socket.socket(family, kind, proto)
        except OSError as exc:
            raise LinkError(
                f"cannot listen for the balloon feed on udp {host}:{port}: {_reason(exc)}"
            ) from None
        try:
            # Ground stations broadcast so that several programs (chasemapper, OziPlotter) can listen on one
            # machine: horus-gui PAYLOAD_SUMMARY to 55672 and OziMux lines to 55683, auto_rx PAYLOAD_SUMMARY
            # to 55673 and OziMux lines to 8942 (OziPlotter's port). They all set SO_REUSEADDR, so must we.
            sock.setsockopt(socket.SOL_SOCKET, socket.SO_REUSEADDR, 1)
            sock.bind(address)
        except OSError as exc:
            sock.close()
            raise LinkError(
                f"cannot listen for the balloon feed on udp {host}:{port}: {_reason(exc)}"
            ) from None
        return sock

    def _run_udp(self) -> None:
        assert self._udp is not None
        with selectors.DefaultSelector() as selector:
            selector.register(self._udp, selectors.EVENT_READ)
            selector.register(self._wake_reader, selectors.EVENT_READ)
            while not self._stop.is_set():
                selector.select()
                if self._stop.is_set():
                    return
                try:
                    datagram = self._udp.recv(65536)
                except OSError as exc:
                    self._error(f"receive failed: {_reason(exc)}")
                    self._stop.wait(BACKOFF_S[0])
                    continue
                for line in datagram.split(b"\n"):
                    self._take(line)

    def _run_tcp(self) -> None:
        attempt = 0
        while not self._stop.is_set():
            self._set_state("connecting")
            sock = self._connect()
            if sock is not None:
                with sock:
                    if self._read_tcp(sock):
                        attempt = 0
            if self._stop.is_set():
                return
            delay = reconnect_delay_s(attempt)
            attempt += 1
            self._set_state(f"reconnecting in {delay} s")
            self._stop.wait(delay)

    def _connect(self) -> socket.socket | None:
        """A connected socket, or ``None`` with the reason recorded; a stop interrupts the wait at once."""
        host, port = self.config.host, self.config.port
        try:
            family, kind, proto, _, address = socket.getaddrinfo(host, port, type=socket.SOCK_STREAM)[0]
        except OSError as exc:
            self._error(f"cannot resolve {host}: {_reason(exc)}")
            return None
        sock = socket.socket(family, kind, proto)
        sock.setblocking(False)
        try:
            error = sock.connect_ex(address)
            if error not in (0, errno.EINPROGRESS):
                raise OSError(error, os.strerror(error))
            with selectors.DefaultSelector() as selector:
                selector.register(sock, selectors.EVENT_WRITE)
                selector.register(self._wake_reader, selectors.EVENT_READ)
                ready = selector.select(CONNECT_TIMEOUT_S)
            if self._stop.is_set():
                sock.close()
                return None
            if not ready:
                raise OSError(f"no answer in {CONNECT_TIMEOUT_S:g} s")
            error = sock.getsockopt(socket.SOL_SOCKET, socket.SO_ERROR)
            if error:
                raise OSError(error, os.strerror(error))
        except OSError as exc:
            sock.close()
            self._error(f"cannot connect to {host}:{port}: {_reason(exc)}")
            return None
        _keep_alive(sock)
        self._set_state("connected")
        log.info("balloon feed: connected to %s:%s", host, port)
        return sock

    def _read_tcp(self, sock: socket.socket) -> bool:
        """Read until the server drops or we stop; whether any complete line came (a working server)."""
        splitter = _LineSplitter()
        got_line = False
        with selectors.DefaultSelector() as selector:
            selector.register(sock, selectors.EVENT_READ)
            selector.register(self._wake_reader, selectors.EVENT_READ)
            while True:
                selector.select()
                if self._stop.is_set():
                    return got_line
                try:
                    data = sock.recv(65536)
                except BlockingIOError:
                    continue
                except OSError as exc:
                    self._error(f"connection to {self.config.host}:{self.config.port} lost: {_reason(exc)}")
                    break
                if not data:
                    self._error(f"connection closed by {self.config.host}:{self.config.port}")
                    break
                for line in splitter.feed(data):
                    got_line = True
                    self._take(line)
        self._discard_partial(splitter, "the connection dropped mid-line")
        return got_line

    def _run_file(self) -> None:
        path = self.config.path
        assert path is not None
        splitter = _LineSplitter()
        handle: BinaryIO | None = None
        identity: tuple[int, int] | None = None
        from_end = True
        try:
            while not self._stop.is_set():
                if handle is None:
                    handle, identity = self._open_log(path, splitter, from_end)
                    from_end = False
                if handle is not None:
                    self._drain(handle, splitter)
                    handle, identity = self._after_read(path, handle, identity, splitter)
                self._stop.wait(FILE_POLL_S)
        finally:
            if handle is not None:
                handle.close()

    def _open_log(
        self, path: Path, splitter: _LineSplitter, from_end: bool
    ) -> tuple[BinaryIO | None, tuple[int, int] | None]:
        """Open the log; at start only its last complete line counts (an immediate position, no replay)."""
        try:
            handle = path.open("rb")
        except FileNotFoundError:
            self._set_state(f"waiting for {path}")
            return None, None
        except OSError as exc:
            self._error(f"cannot read {path}: {_reason(exc)}")
            self._set_state(f"waiting for {path}")
            return None, None
        stat = os.fstat(handle.fileno())
        # Before the first line is taken, so that no reader sees a fix beside "not started".
        self._set_state(f"following {path}")
        if from_end:
            self._take_last_line(handle, splitter)
        return handle, (stat.st_dev, stat.st_ino)

    def _take_last_line(self, handle: BinaryIO, splitter: _LineSplitter) -> None:
        size = handle.seek(0, os.SEEK_END)
        start = max(0, size - TAIL_BYTES)
        handle.seek(start)
        tail = handle.read(size - start)
        end = tail.rfind(b"\n")
        if end < 0 and start == 0:
            handle.seek(0)  # one unfinished line: it is taken once it ends
            return
        if end < 0:
            splitter.skip_current_line()  # the end of a runaway line: the next line is the first to count
            return
        begin = tail.rfind(b"\n", 0, end) + 1
        if begin > 0 or start == 0:
            self._take(tail[begin:end])
        handle.seek(start + end + 1)

    def _drain(self, handle: BinaryIO, splitter: _LineSplitter) -> None:
        while chunk := handle.read(65536):
            for line in splitter.feed(chunk):
                self._take(line)

    def _after_read(
        self, path: Path, handle: BinaryIO, identity: tuple[int, int] | None, splitter: _LineSplitter
    ) -> tuple[BinaryIO | None, tuple[int, int] | None]:
        """Follow the name, like ``tail -F``: a rotated or deleted log is closed, a truncated one reread."""
        try:
            stat = os.stat(path)
        except FileNotFoundError:
            stat = None
        if stat is None or (stat.st_dev, stat.st_ino) != identity:
            self._drain(handle, splitter)  # what the writer added between our read and the rename
            handle.close()
            self._discard_partial(splitter, "the log was rotated mid-line")
            if stat is None:
                self._set_state(f"waiting for {path}")
            log.info("balloon feed: %s was rotated or removed; following the new file", path)
            return None, None
        if stat.st_size < handle.tell():
            log.info("balloon feed: %s was truncated; reading it from the start", path)
            handle.seek(0)
            self._discard_partial(splitter, "the log was truncated mid-line")
        return handle, identity

    # --- bookkeeping (reading thread in, any thread out) -------------------------------------------

    def _take(self, raw: bytes) -> None:
        line = raw.rstrip(b"\r")
        if not line.strip():
            return
        received_at = self._clock()
        text = line.decode("utf-8", errors="replace")
        outcome = _too_long(text) if len(line) > MAX_LINE_BYTES else parse_feed_line(text, received_at)
        with self._lock:
            if outcome is None:
                self._counts["ignored"] += 1
                return
            if isinstance(outcome, Rejection):
                self._reject(outcome)
            elif self._newest is not None and outcome.time <= self._newest:
                self._counts["out_of_order"] += 1
                return
            else:
                self._newest = outcome.time
                self._pending = outcome.record(self.source, received_at)
                self._counts["accepted"] += 1
        if isinstance(outcome, Rejection):
            log.debug("balloon feed %s: rejected %r: %s", self.source, outcome.line, outcome.detail)
        self._tell(outcome)

    def _reject(self, rejection: Rejection) -> None:
        self._counts["rejected"] += 1
        self._reasons[rejection.reason] += 1
        self._last_rejection = rejection

    def _discard_partial(self, splitter: _LineSplitter, why: str) -> None:
        partial = splitter.take_partial()
        if not partial.strip():
            return
        rejection = Rejection(
            PARTIAL, f"partial line discarded: {why}", shorten(partial.decode("utf-8", "replace"))
        )
        with self._lock:
            self._reject(rejection)
        self._tell(rejection)

    def _tell(self, outcome: BalloonFix | Rejection) -> None:
        if self._listener is None:
            return
        try:
            self._listener(outcome)
        except Exception:  # a listener's bug must not stop the feed
            log.exception("balloon feed %s: listener failed", self.source)

    def _set_state(self, state: str) -> None:
        with self._lock:
            self._state = state

    def _error(self, message: str) -> None:
        log.warning("balloon feed %s: %s", self.source, message)
        with self._lock:
            self._last_error = message


def _reason(exc: OSError) -> str:
    return exc.strerror or str(exc)


def _keep_alive(sock: socket.socket) -> None:
    """A ground station that vanishes from the LAN sends no FIN: keepalive notices within about a minute."""
    sock.setsockopt(socket.SOL_SOCKET, socket.SO_KEEPALIVE, 1)
    for option, value in (("TCP_KEEPIDLE", 30), ("TCP_KEEPINTVL", 10), ("TCP_KEEPCNT", 3)):
        if hasattr(socket, option):
            sock.setsockopt(socket.IPPROTO_TCP, getattr(socket, option), value)

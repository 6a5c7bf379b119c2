"""`drs mo serve`: receive the gateway's MO webhook (HTTP_POST form or HTTP_JSON), store it, answer 200.

The gateway wants HTTP 200 within 3 s, so a request is only checked (size, signature, required
fields), stored durably, and answered; anything heavier (command lifecycle, health) runs on a
worker thread after the answer has gone out. A report stored but never answered would be
delivered again, which the (imei, momsn, payload) de-duplication absorbs.

The server is the standard library's, kept small on purpose: it listens on loopback behind a TLS
reverse proxy (Caddy or nginx, docs/iridium.md) that faces the internet, so TLS, certificates and
slow or hostile clients are the proxy's job. Every request gets one access-log record; the
client's address is the peer's, or, only when the peer is ``mo.trusted_proxy``, the last address
of its X-Forwarded-For (anyone else could write any address there and forge the audit trail).
``stop`` drains: no new connection is taken, the requests in progress are answered, then the
after-answer work ends, so SIGTERM from systemd never cuts a report between its store and its 200.
"""

from __future__ import annotations

import ipaddress
import json
import logging
import queue
import socket
import threading
import time
from collections.abc import Callable
from datetime import UTC, datetime
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs

import jwt
from cryptography.hazmat.primitives import serialization
from cryptography.hazmat.primitives.asymmetric import rsa

from drs_link.config import MoConfig
from drs_link.errors import ConfigError, StoreError
from drs_link.iridium.reports import Delivery, ReportStore, StoredReport
from drs_link.store import parse_iso_utc, utc_now

log = logging.getLogger(__name__)
access_log = logging.getLogger(f"{__name__}.access")

MAX_KEY_BYTES = 65_536
HEALTH_PATH = "/health"
HEALTH_WAIT_S = 0.5
REQUEST_DEADLINE_S = 20.0
"""A request must arrive and be answered within this, however slowly its bytes drip in: the socket's own
timeout is per ``recv``, and one byte every few seconds once held a connection and its thread for ever.
The gateway itself gives up after 3 s."""
DRAIN_S = 10.0
"""How long ``stop`` waits for requests in progress: a handler's socket timeout, so only a client that
trickles its body slower than that is cut off (it got no 200, so the gateway delivers again)."""

JWT_ALGORITHMS = ["RS256"]
_MUST_BE_SIGNED = ("imei", "momsn", "data")
"""A JWT that does not sign these could be replayed on another message."""


class DeliveryRejected(Exception):
    """A delivery that cannot be stored as a report; carries the HTTP status to answer."""

    def __init__(self, status: int, reason: str) -> None:
        super().__init__(reason)
        self.status = status
        self.reason = reason


def load_public_key(path: Path | None) -> str | None:
    if path is None:
        return None
    try:
        with open(path, "rb") as file:
            data = file.read(MAX_KEY_BYTES + 1)
        text = data.decode("ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"mo.jwt_public_key_file: cannot read {path}: {exc}") from None
    if len(data) > MAX_KEY_BYTES or "PUBLIC KEY" not in text:
        raise ConfigError(f"mo.jwt_public_key_file: {path} is not a PEM public key")
    try:
        key = serialization.load_pem_public_key(data)
    except ValueError:
        # Parsed here, at start: a key with garbage inside once let the receiver start and 401 every delivery.
        raise ConfigError(
            f"mo.jwt_public_key_file: {path} holds a PEM block that is not a valid public key"
        ) from None
    if not isinstance(key, rsa.RSAPublicKey):
        raise ConfigError(
            f"mo.jwt_public_key_file: {path} is not an RSA key (Ground Control signs with RS256)"
        )
    return text


def _fields(content_type: str, body: bytes) -> dict[str, str]:
    kind = content_type.split(";")[0].strip().lower()
    try:
        text = body.decode("utf-8")
    except UnicodeDecodeError:
        raise DeliveryRejected(400, "body is not UTF-8") from None
    if kind == "application/json":
        try:
            document = json.loads(text)
        except json.JSONDecodeError:
            raise DeliveryRejected(400, "body is not valid JSON") from None
        except RecursionError:
            raise DeliveryRejected(400, "JSON nested too deeply") from None
        if not isinstance(document, dict):
            raise DeliveryRejected(400, "JSON body is not an object")
        return {str(k): str(v) for k, v in document.items() if isinstance(v, str | int | float)}
    if kind == "application/x-www-form-urlencoded":
        return {key: values[0] for key, values in parse_qs(text, keep_blank_values=True).items()}
    raise DeliveryRejected(415, f"unsupported content type {kind or '(none)'}")


def _ascii_digits(text: str) -> bool:
    """Digits 0-9 only: str.isdigit() also takes '²', full-width '５' and Arabic-Indic '٣', which int()
    then reads or refuses, so a forged IMEI or MOMSN passed the check, or crashed the handler."""
    return bool(text) and text.isascii() and text.isdigit()


def _float(fields: dict[str, str], name: str) -> float | None:
    try:
        return float(fields[name])
    except (KeyError, ValueError):
        return None


def _transmit_time(text: str | None) -> datetime | None:
    if not text:
        return None
    try:
        return datetime.strptime(text.strip(), "%y-%m-%d %H:%M:%S").replace(tzinfo=UTC)
    except ValueError:
        return None


_EXACT = frozenset(_MUST_BE_SIGNED)
"""Claims compared as exact text: the report's identity and payload. As numbers, 17 significant digits,
``_`` separators and leading zeros once let three altered ``data`` values be stored as verified."""
RECEIVER_WRITE_WAIT_S = 2.0
"""The longest a delivery waits for a store another process has locked before the answer is 503: the
gateway waits 3 s for an answer, and retries a 503 (a report is never lost to a lock, only delayed)."""
JWT_LEEWAY_S = 30
"""Clock difference allowed between Ground Control and this machine on ``iat``/``exp`` (both keep NTP
time; a token issued 1 s "in the future" was once refused with a 401 and the report lost to retries)."""


def _same_value(name: str, claim: object, delivered: str) -> bool:
    """``imei``, ``momsn`` and ``data`` equal as exact text (an integer claim as its decimal digits); the
    other fields also as numbers: the gateway's claims format is not documented (drs_protocol.md 4.2),
    and ``46.5`` signed for a delivered ``46.5000`` must not refuse a real report forever."""
    if name in _EXACT:
        return isinstance(claim, str | int) and not isinstance(claim, bool) and str(claim) == delivered
    if str(claim) == delivered:
        return True
    try:
        return isinstance(claim, int | float | str) and float(claim) == float(delivered)
    except ValueError:
        return False


class MoReceiver:
    """What one delivery means, independent of the HTTP server (checked, stored, then handed on)."""

    def __init__(
        self,
        reports: ReportStore,
        config: MoConfig,
        on_report: Callable[[StoredReport], None] | None = None,
        clock: Callable[[], datetime] = utc_now,
    ) -> None:
        self.reports = reports
        reports.write_wait_s = RECEIVER_WRITE_WAIT_S
        self.config = config
        self.public_key = load_public_key(config.jwt_public_key_file)
        if config.require_jwt and self.public_key is None:
            raise ConfigError(
                "mo.jwt_public_key_file is not set and mo.require_jwt is on (the default): give Ground "
                "Control's RS256 public key, or set mo.require_jwt = false to accept unsigned deliveries"
            )
        if not config.require_jwt:
            log.warning(
                "mo.require_jwt = false: deliveries without a valid Ground Control JWT are stored as "
                "unverified; anyone who can reach %s can forge a position report",
                config.path,
            )
        self.on_report = on_report
        self.clock = clock

    def _verify(self, fields: dict[str, str]) -> tuple[dict[str, str], bool]:
        """The fields to store, and whether the gateway signed them.

        Every delivered field must equal its claim, not only imei, momsn and data: a signed post with
        an altered ``transmit_time`` or ``iridium_*`` was once stored as verified. A field the JWT does
        not sign is not stored from a signed delivery.
        """
        token = fields.get("JWT")
        if not token:
            if self.config.require_jwt:
                raise DeliveryRejected(401, "no JWT and mo.require_jwt is set")
            return fields, False
        if self.public_key is None:
            return fields, False
        try:
            claims: dict[str, Any] = jwt.decode(
                token, self.public_key, algorithms=JWT_ALGORITHMS, leeway=JWT_LEEWAY_S
            )
        except jwt.PyJWTError as exc:
            raise DeliveryRejected(401, f"JWT rejected: {type(exc).__name__}") from None
        missing = [name for name in _MUST_BE_SIGNED if name not in claims]
        if missing:
            raise DeliveryRejected(401, f"the JWT does not sign {', '.join(missing)}")
        delivered = {name: value for name, value in fields.items() if name != "JWT"}
        for name, value in delivered.items():
            if name in claims and not _same_value(name, claims[name], value):
                raise DeliveryRejected(401, f"JWT claim {name} does not match the delivered {name}")
        unsigned = sorted(set(delivered) - set(claims))
        if unsigned:
            log.warning("MO delivery: fields the JWT does not sign were not stored: %s", ", ".join(unsigned))
        return {name: value for name, value in delivered.items() if name in claims}, True

    def health(self) -> tuple[int, str]:
        """What an unattended ground station's monitor asks (``GET /health``): can deliveries be stored,
        and how long since the last one came. No secret, no position: 200 when the store is writable."""
        writable, problem = True, None
        try:
            with self.reports.store.transaction(HEALTH_WAIT_S):
                pass
        except StoreError as exc:
            writable, problem = False, str(exc)
        rows = self.reports.store.query("SELECT MAX(received_utc) AS last FROM mo_report")
        last = rows[0]["last"] if rows else None
        age = None if last is None else round((self.clock() - parse_iso_utc(last)).total_seconds(), 1)
        answer = {"status": "ok" if writable else "store not writable", "store_writable": writable,
                  "last_delivery_age_s": age, "jwt_required": self.config.require_jwt}  # fmt: skip
        if problem:
            answer["problem"] = problem
        return (200 if writable else 503), json.dumps(answer)

    def handle(self, content_type: str, body: bytes, remote: str) -> tuple[int, str, StoredReport | None]:
        """Check and store one delivery; returns (HTTP status, reply text, the stored report if new)."""
        now = self.clock()
        try:
            fields, verified = self._verify(_fields(content_type, body))
            imei, momsn_text = fields.get("imei", ""), fields.get("momsn", "")
            if not (len(imei) == 15 and _ascii_digits(imei)):
                raise DeliveryRejected(400, "missing or malformed imei")
            if not _ascii_digits(momsn_text) or int(momsn_text) > 65535:
                raise DeliveryRejected(400, "missing or malformed momsn")
            if "data" not in fields:
                raise DeliveryRejected(400, "missing data")
        except DeliveryRejected as exc:
            self.reports.reject_delivery(now, remote, exc.reason, body.decode("utf-8", "replace"))
            log.warning("MO delivery from %s rejected: %s", remote, exc.reason)
            return exc.status, exc.reason, None
        serial = fields.get("serial", "")
        delivery = Delivery(
            imei=imei,
            momsn=int(momsn_text),
            data_hex=fields["data"],
            source="webhook-json" if content_type.lower().startswith("application/json") else "webhook-form",
            received_utc=now,
            transmit_utc=_transmit_time(fields.get("transmit_time")),
            serial=int(serial) if _ascii_digits(serial) else None,
            iridium_lat=_float(fields, "iridium_latitude"),
            iridium_lon=_float(fields, "iridium_longitude"),
            iridium_cep_km=_float(fields, "iridium_cep"),
            jwt_verified=verified,
            raw_delivery=body.decode("utf-8", "replace"),
        )
        try:
            stored, new = self.reports.add(delivery)
        except StoreError as exc:
            log.error("MO delivery %s/%s not stored: %s", imei, momsn_text, exc)
            return 503, "store unavailable; retry later", None  # the gateway retries a 5xx
        if not new:
            return 200, "OK (duplicate)", None
        return 200, "OK", stored


def _address(text: str) -> ipaddress.IPv4Address | ipaddress.IPv6Address | None:
    """The address, with an IPv4-mapped IPv6 one (``::ffff:127.0.0.1``) as the IPv4 it is."""
    try:
        address = ipaddress.ip_address(text.strip())
    except ValueError:
        return None
    mapped = address.ipv4_mapped if isinstance(address, ipaddress.IPv6Address) else None
    return mapped or address


class _Handler(BaseHTTPRequestHandler):
    server: MoHttpServer
    timeout = DRAIN_S
    """Seconds a stalled client may hold its connection (each has its own thread; this bounds them)."""

    def setup(self) -> None:
        super().setup()
        self._started = time.monotonic()
        self._unsent: str | None = None

    def handle_one_request(self) -> None:
        """One request under ``REQUEST_DEADLINE_S`` (the server's watchdog cuts the connection after it)."""
        self._started = time.monotonic()
        self.server.deadlines.watch(self.connection, REQUEST_DEADLINE_S)
        try:
            super().handle_one_request()
        finally:
            self.server.deadlines.forget(self.connection)

    def client(self) -> tuple[str, dict[str, str]]:
        """Who sent the request as the audit records it, and the access log's fields saying how that was decided."""
        peer = self.client_address[0]
        forwarded = self.headers.get("X-Forwarded-For") if getattr(self, "headers", None) else None
        if not forwarded:
            return peer, {"client": peer}
        if self.server.trusted_proxy is None or _address(peer) != self.server.trusted_proxy:
            return peer, {"client": peer, "forwarded_ignored": forwarded}
        client = _address(
            forwarded.split(",")[-1]
        )  # the one the proxy appended: earlier ones are the client's say
        if client is None:
            return peer, {"client": peer, "forwarded_unreadable": forwarded}
        return f"{client} via {peer}", {"client": str(client), "proxy": peer}

    def log_request(self, code: int | str = "-", size: int | str = "-") -> None:
        """The access log: one record a request, with the query string left out (it is never ours to keep)."""
        path = getattr(self, "path", "").split("?")[0]
        fields = {
            **self.client()[1],
            "method": getattr(self, "command", None) or "-",
            "path": path or "-",
            "status": int(code) if str(code).isdigit() else code,
            **({"unsent": self._unsent} if getattr(self, "_unsent", None) else {}),
            "request_bytes": self.headers.get("Content-Length", "-")
            if getattr(self, "headers", None)
            else "-",
            "ms": round(1000 * (time.monotonic() - self._started), 1),
        }
        shown = f"{fields['status']} NOT SENT ({self._unsent})" if fields.get("unsent") else fields["status"]
        access_log.info("%s %s %s", fields["method"], fields["path"], shown, extra=fields)

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - the stdlib's signature
        log.warning(format % args, extra=self.client()[1])

    def _answer(self, status: int, text: str, content_type: str = "text/plain; charset=utf-8") -> None:
        """Answer, then log it: the stdlib logs before writing, and a 200 the client never got (a broken
        pipe) was once in the access log as a 200."""
        encoded = (text + "\n").encode("utf-8")
        self.send_response_only(status)
        self.send_header("Server", self.version_string())
        self.send_header("Date", self.date_time_string())
        self.send_header("Content-Type", content_type)
        self.send_header("Content-Length", str(len(encoded)))
        try:
            self.end_headers()
            self.wfile.write(encoded)
            self.wfile.flush()
        except OSError as exc:
            self._unsent = f"client gone: {type(exc).__name__}"
            self.close_connection = True
        self.log_request(status)

    def do_GET(self) -> None:  # noqa: N802 - the stdlib's name
        if self.path.split("?")[0] == HEALTH_PATH:
            status, text = self.server.receiver.health()
            self._answer(status, text, "application/json")
            return
        self._answer(405, "POST the gateway's MO deliveries here")

    def do_POST(self) -> None:  # noqa: N802 - the stdlib's name
        receiver = self.server.receiver
        remote = self.client()[0]
        if self.path.split("?")[0] != receiver.config.path:
            self._answer(404, "unknown path")
            return
        length_text = self.headers.get("Content-Length")
        if length_text is None or not _ascii_digits(length_text):
            self.close_connection = True
            self._answer(411, "Content-Length required")
            return
        length = int(length_text)
        if length > receiver.config.max_body_bytes:
            self.close_connection = True
            receiver.reports.reject_delivery(
                receiver.clock(), remote, f"body of {length} bytes over the limit", ""
            )
            self._answer(413, f"body over {receiver.config.max_body_bytes} bytes")
            return
        body = self.rfile.read(length)
        if len(body) < length:
            self.close_connection = True
            self._answer(400, f"body of {len(body)} bytes is shorter than its Content-Length {length}")
            return
        status, text, stored = receiver.handle(self.headers.get("Content-Type", ""), body, remote)
        self._answer(status, text)
        if stored is not None:
            self.server.after_answer.put(stored)


class _Deadlines:
    """One watchdog for every connection's request deadline (a timer thread each would double the threads)."""

    def __init__(self) -> None:
        self._due: dict[socket.socket, float] = {}
        self._lock = threading.Lock()
        self._stopped = threading.Event()

    def watch(self, connection: socket.socket, seconds: float) -> None:
        with self._lock:
            self._due[connection] = time.monotonic() + seconds

    def forget(self, connection: socket.socket) -> None:
        with self._lock:
            self._due.pop(connection, None)

    def stop(self) -> None:
        self._stopped.set()

    def run(self) -> None:
        while not self._stopped.wait(0.25):
            now = time.monotonic()
            with self._lock:
                late = [connection for connection, due in self._due.items() if due <= now]
                for connection in late:
                    del self._due[connection]
            for connection in late:
                try:
                    connection.shutdown(socket.SHUT_RDWR)  # its thread's read or write ends at once
                except OSError:
                    pass
                log.warning("a request took longer than %.0f s and was cut off", REQUEST_DEADLINE_S)


class MoHttpServer(ThreadingHTTPServer):
    daemon_threads = True
    block_on_close = False
    """``stop`` drains, with a deadline; the stdlib's close would wait for every thread without one."""
    request_queue_size = 128
    """The listen backlog: the stdlib's 5 reset connections when 20 clients posted at once."""

    def __init__(self, receiver: MoReceiver) -> None:
        super().__init__((receiver.config.listen_host, receiver.config.listen_port), _Handler)
        self.receiver = receiver
        self.deadlines = _Deadlines()
        self.trusted_proxy = (
            _address(receiver.config.trusted_proxy) if receiver.config.trusted_proxy else None
        )
        self.after_answer: queue.Queue[StoredReport | None] = queue.Queue()
        self._service_threads: list[threading.Thread] = []
        self._in_flight = 0
        self._idle = threading.Condition()

    def process_request(self, request: Any, client_address: Any) -> None:
        with self._idle:
            self._in_flight += 1
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._finished()
            raise

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._finished()

    def _finished(self) -> None:
        with self._idle:
            self._in_flight -= 1
            self._idle.notify_all()

    def handle_error(self, request: Any, client_address: Any) -> None:
        log.exception("request from %s failed", client_address[0])

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        assert isinstance(host, str), "an IP socket's own address names its host as text, never bytes"
        return f"http://{host}:{port}{self.receiver.config.path}"

    def _work(self) -> None:
        while (stored := self.after_answer.get()) is not None:
            if self.receiver.on_report is not None:
                try:
                    self.receiver.on_report(stored)
                except Exception:
                    log.exception(
                        "processing MO %s/%s after storing it failed",
                        stored.delivery.imei,
                        stored.delivery.momsn,
                    )

    def start(self) -> MoHttpServer:
        self._service_threads = [
            threading.Thread(target=self.serve_forever, args=(0.05,), name="mo-http", daemon=True),
            threading.Thread(target=self._work, name="mo-after-answer", daemon=True),
            threading.Thread(target=self.deadlines.run, name="mo-deadlines", daemon=True),
        ]
        for thread in self._service_threads:
            thread.start()
        return self

    def stop(self, drain_s: float = DRAIN_S) -> int:
        """Take no more connections, answer the requests in progress, finish the after-answer work.

        Returns how many requests were still unanswered at the deadline (their clients got no 200).
        """
        self.shutdown()
        self.server_close()  # connections still in the backlog are refused now, not left to time out
        with self._idle:
            if self._in_flight:
                log.info("draining", extra={"in_flight": self._in_flight})
            self._idle.wait_for(lambda: self._in_flight == 0, timeout=drain_s)
            cut_off = self._in_flight
        if cut_off:
            log.warning(
                "stopped with requests unanswered; their senders retry", extra={"unanswered": cut_off}
            )
        self.after_answer.put(None)
        self.deadlines.stop()
        for thread in self._service_threads:
            thread.join(timeout=5)
        return cut_off

"""`drs mo serve`: receive the gateway's MO webhook (HTTP_POST form or HTTP_JSON), store it, answer 200.

The gateway wants HTTP 200 within 3 s, so a request is only checked (size, signature, required
fields), stored durably, and answered; anything heavier (command lifecycle, health) runs on a
worker thread after the answer has gone out. A report stored but never answered would be
delivered again, which the (imei, momsn, payload) de-duplication absorbs.
"""

from __future__ import annotations

import json
import logging
import queue
import threading
from collections.abc import Callable
from datetime import UTC, datetime
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from typing import Any
from urllib.parse import parse_qs

import jwt

from drs_link.config import MoConfig
from drs_link.errors import ConfigError, StoreError
from drs_link.iridium.reports import Delivery, ReportStore, StoredReport
from drs_link.store import utc_now

log = logging.getLogger(__name__)

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
        text = path.read_text(encoding="ascii")
    except (OSError, UnicodeDecodeError) as exc:
        raise ConfigError(f"mo.jwt_public_key_file: cannot read {path}: {exc}") from None
    if "PUBLIC KEY" not in text:
        raise ConfigError(f"mo.jwt_public_key_file: {path} is not a PEM public key")
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


def _same_value(claim: object, delivered: str) -> bool:
    """Equal as text, or as numbers: the gateway's claims format is not documented (drs_protocol.md
    4.2), and ``46.5`` signed for a delivered ``46.5000`` must not refuse a real report forever."""
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
            claims: dict[str, Any] = jwt.decode(token, self.public_key, algorithms=JWT_ALGORITHMS)
        except jwt.PyJWTError as exc:
            raise DeliveryRejected(401, f"JWT rejected: {type(exc).__name__}") from None
        missing = [name for name in _MUST_BE_SIGNED if name not in claims]
        if missing:
            raise DeliveryRejected(401, f"the JWT does not sign {', '.join(missing)}")
        delivered = {name: value for name, value in fields.items() if name != "JWT"}
        for name, value in delivered.items():
            if name in claims and not _same_value(claims[name], value):
                raise DeliveryRejected(401, f"JWT claim {name} does not match the delivered {name}")
        unsigned = sorted(set(delivered) - set(claims))
        if unsigned:
            log.warning("MO delivery: fields the JWT does not sign were not stored: %s", ", ".join(unsigned))
        return {name: value for name, value in delivered.items() if name in claims}, True

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


class _Handler(BaseHTTPRequestHandler):
    server: MoHttpServer
    timeout = 10.0
    """Seconds a stalled client may hold its connection (each has its own thread; this bounds them)."""

    def log_message(self, format: str, *args: object) -> None:  # noqa: A002 - the stdlib's signature
        log.info("%s %s", self.address_string(), format % args)

    def _answer(self, status: int, text: str) -> None:
        encoded = (text + "\n").encode("utf-8")
        self.send_response(status)
        self.send_header("Content-Type", "text/plain; charset=utf-8")
        self.send_header("Content-Length", str(len(encoded)))
        self.end_headers()
        self.wfile.write(encoded)

    def do_GET(self) -> None:  # noqa: N802 - the stdlib's name
        self._answer(405, "POST the gateway's MO deliveries here")

    def do_POST(self) -> None:  # noqa: N802 - the stdlib's name
        receiver = self.server.receiver
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
                receiver.clock(), self.client_address[0], f"body of {length} bytes over the limit", ""
            )
            self._answer(413, f"body over {receiver.config.max_body_bytes} bytes")
            return
        body = self.rfile.read(length)
        if len(body) < length:
            self.close_connection = True
            self._answer(400, f"body of {len(body)} bytes is shorter than its Content-Length {length}")
            return
        status, text, stored = receiver.handle(
            self.headers.get("Content-Type", ""), body, self.client_address[0]
        )
        self._answer(status, text)
        if stored is not None:
            self.server.after_answer.put(stored)


class MoHttpServer(ThreadingHTTPServer):
    daemon_threads = True
    request_queue_size = 128
    """The listen backlog: the stdlib's 5 reset connections when 20 clients posted at once."""

    def __init__(self, receiver: MoReceiver) -> None:
        super().__init__((receiver.config.listen_host, receiver.config.listen_port), _Handler)
        self.receiver = receiver
        self.after_answer: queue.Queue[StoredReport | None] = queue.Queue()
        self._service_threads: list[threading.Thread] = []

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
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
        ]
        for thread in self._service_threads:
            thread.start()
        return self

    def stop(self) -> None:
        self.shutdown()
        self.after_answer.put(None)
        self.server_close()
        for thread in self._service_threads:
            thread.join(timeout=5)

"""The HTTP server in front of ``api``: Tawhiri's paths, ``/health``, and the limits that keep it answering.

Why the limits: a thread serves each connection, so connections that send nothing would otherwise hold
every thread. At most ``MAX_CONNECTIONS`` are served at once and ``MAX_PER_CLIENT`` from one address
(a browser's idle pre-connections, or one hostile host, cannot lock the chase car out); a connection
must send its whole request within ``REQUEST_READ_S`` or is closed. A client that leaves before its
answer is written is one line in the log, not a traceback.
"""

from __future__ import annotations

import json
import logging
import socket
import sys
import threading
import time
from collections import Counter
from datetime import UTC, datetime
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from typing import Any
from urllib.parse import parse_qs, urlsplit

from predictor.tawhiri.api import (
    API_PATH,
    CAPSULE_PATH,
    HEALTH_PATH,
    Answer,
    PredictorService,
    answer,
    error_answer,
    route,
)
from predictor.tawhiri.request import ApiError

log = logging.getLogger(__name__)

MAX_CONNECTIONS = 32
"""Connections served at once; more are answered 503 at once, so stalled clients cannot take every thread."""
MAX_PER_CLIENT = 8
"""Connections served at once from one address; more from it are answered 503 at once."""
REQUEST_READ_S = 5.0
"""A client must send its whole request (line and headers) within this; then the socket is closed.
chasemapper and the SondeHub page send theirs at once; a browser's idle pre-connection waits here."""
DRAIN_S = 20.0
"""How long a stopping server waits for the predictions in flight (one takes seconds at most)."""
GONE = (BrokenPipeError, ConnectionResetError, ConnectionAbortedError, TimeoutError)
"""What writing to a client that has left raises: logged in one line."""

BUSY = (
    b"HTTP/1.0 503 Service Unavailable\r\nContent-Type: application/json\r\nRetry-After: 5\r\n"
    b"Connection: close\r\n\r\n"
    b'{"error": {"type": "ServiceUnavailable", "description": "Too many connections; try again in 5 s."}}'
)


class _Handler(BaseHTTPRequestHandler):
    server: ApiServer
    timeout = REQUEST_READ_S
    """Per read; the whole request is bounded by ``_deadline``."""

    def setup(self) -> None:
        super().setup()
        self._deadline = threading.Timer(REQUEST_READ_S, self._hang_up)
        self._deadline.daemon = True
        self._deadline.start()

    def _hang_up(self) -> None:
        """A client that has not sent its whole request in time is disconnected: a drip-feed holds nothing."""
        try:
            self.connection.shutdown(socket.SHUT_RDWR)
        except OSError:
            pass

    def parse_request(self) -> bool:
        ok = super().parse_request()
        self._deadline.cancel()  # the request is in: the prediction may take its time
        return ok

    def finish(self) -> None:
        self._deadline.cancel()
        super().finish()

    def do_GET(self) -> None:  # noqa: N802 (http.server's name)
        began = time.monotonic()
        parts = urlsplit(self.path)
        if parts.path.rstrip("/") == HEALTH_PATH:
            health = self.server.service.health()
            status = 200 if health["status"] == "ok" else 503
            reply: Answer = (status, "application/json", json.dumps(health), {"Cache-Control": "no-store"})
        elif (served := route(parts.path)) is None:
            error = ApiError(
                "RequestException", 404,
                f"No endpoint {parts.path}: the API answers GET {API_PATH}, GET {CAPSULE_PATH}<CAPSULE>/ "
                f"and GET {HEALTH_PATH}.",
            )  # fmt: skip
            reply = error_answer(error, datetime.now(UTC))
        else:
            query = parse_qs(parts.query, keep_blank_values=True)
            reply = answer(self.server.service, query, *served)
        self._reply(reply)
        log.info("%s %s %s → %d in %.0f ms", self.address_string(), self.command, self.path, reply[0],
                 1000 * (time.monotonic() - began))  # fmt: skip

    def do_HEAD(self) -> None:  # noqa: N802 (http.server's name)
        """As GET, with the same status and headers (Content-Length too) and no body."""
        self.do_GET()

    def _not_allowed(self) -> None:
        said = f"The method {self.command} is not allowed: the API answers GET and HEAD."
        status, kind, body, headers = error_answer(ApiError("MethodNotAllowed", 405, said), datetime.now(UTC))
        self._reply((status, kind, body, {**headers, "Allow": "GET, HEAD"}))

    do_POST = do_PUT = do_DELETE = do_PATCH = do_OPTIONS = _not_allowed  # noqa: N815 (http.server's names)

    def send_error(self, code: int, message: str | None = None, explain: str | None = None) -> None:
        """http.server's own refusals (an unknown method, a malformed request line, a header too long)
        in Tawhiri's error shape too, never its HTML page."""
        said = message or self.responses.get(code, ("Error",))[0]
        kind = "NotYetImplementedException" if code == 501 else "RequestException"
        _, content, body, _ = error_answer(ApiError(kind, code, f"{said}."), datetime.now(UTC))
        data = body.encode("utf-8")
        self.send_response(code, said)
        self.send_header("Content-Type", content)
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Connection", "close")
        self.end_headers()
        if getattr(self, "command", None) != "HEAD":
            self.wfile.write(data)

    def _reply(self, reply: Answer) -> None:
        status, kind, body, headers = reply
        data = body.encode("utf-8")
        self.send_response(status)
        self.send_header("Content-Type", kind)
        self.send_header("Content-Length", str(len(data)))
        self.send_header("Access-Control-Allow-Origin", "*")  # the SondeHub predictor is a web page
        for name, value in headers.items():
            self.send_header(name, value)
        self.end_headers()
        if self.command != "HEAD":
            self.wfile.write(data)

    def log_message(self, format: str, *args: Any) -> None:  # noqa: A002 (http.server's signature)
        log.debug(format, *args)


class ApiServer(ThreadingHTTPServer):
    """The HTTP server; ``port`` 0 takes a free one (``server_address`` then says which).

    At most ``MAX_CONNECTIONS`` connections are served at once, and ``MAX_PER_CLIENT`` from one address;
    one more is answered 503 and closed at once."""

    daemon_threads = True
    request_queue_size = 128
    """Connections waiting to be accepted: a burst is answered (or told 503) instead of left retrying SYNs."""

    def __init__(self, service: PredictorService, host: str = "127.0.0.1", port: int = 0) -> None:
        super().__init__((host, port), _Handler)
        self.service = service
        self._slots = threading.BoundedSemaphore(MAX_CONNECTIONS)
        self._per_client: Counter[str] = Counter()
        self._per_client_lock = threading.Lock()

    def process_request(self, request: Any, client_address: Any) -> None:
        client = str(client_address[0])
        with self._per_client_lock:
            admitted = self._per_client[client] < MAX_PER_CLIENT
            if admitted:
                self._per_client[client] += 1
        if not admitted or not self._slots.acquire(blocking=False):
            if admitted:
                self._leave(client)
            try:
                request.sendall(BUSY)
            except OSError:
                pass
            self.shutdown_request(request)
            return
        try:
            super().process_request(request, client_address)
        except BaseException:
            self._slots.release()
            self._leave(client)
            raise

    def _leave(self, client: str) -> None:
        with self._per_client_lock:
            self._per_client[client] -= 1
            if self._per_client[client] <= 0:
                del self._per_client[client]

    def process_request_thread(self, request: Any, client_address: Any) -> None:
        try:
            super().process_request_thread(request, client_address)
        finally:
            self._slots.release()
            self._leave(str(client_address[0]))

    def handle_error(self, request: Any, client_address: Any) -> None:
        """A client that left before its answer is one line; anything else is a bug, with its traceback."""
        error = sys.exc_info()[1]
        if isinstance(error, GONE):
            log.info("%s left before its answer was sent (%s)", client_address[0], type(error).__name__)
            return
        log.exception("serving %s failed", client_address[0])

    def drain(self, timeout_s: float = DRAIN_S) -> int:
        """Stop accepting and wait up to ``timeout_s`` for the requests in flight to be answered (SIGTERM
        once cut them off); how many were still running. Call it from another thread than the server's."""
        self.shutdown()
        deadline = time.monotonic() + timeout_s
        finished = 0
        while finished < MAX_CONNECTIONS and self._slots.acquire(
            timeout=max(0.0, deadline - time.monotonic())
        ):
            finished += 1
        self.server_close()
        return MAX_CONNECTIONS - finished

    @property
    def url(self) -> str:
        host, port = self.server_address[:2]
        assert isinstance(host, str), "an IP socket's own address names its host as text, never bytes"
        return f"http://{host}:{port}{API_PATH}"

"""The RockBLOCK password never reaches the operator in any encoding a server or proxy echoes it in."""

from __future__ import annotations

import base64
import threading
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from urllib.parse import quote, quote_plus

import pytest

from drs_link.iridium.gateway import RockblockGateway
from drs_link.redaction import redact, secret_forms

PASSWORD = "p@ss w+rd&é=ü/%"
ECHOES = [
    PASSWORD,
    quote(PASSWORD, safe=""),
    quote_plus(PASSWORD, safe=""),
    quote_plus(PASSWORD, safe="").lower(),
    base64.b64encode(f"ops:{PASSWORD}".encode()).decode(),
    "p@ss w+rd&amp;é=ü/%",
]


@pytest.mark.parametrize("echo", ECHOES, ids=["raw", "percent", "plus", "lowercase", "basic-auth", "html"])
def test_every_echoed_form_of_the_password_is_masked(echo: str) -> None:
    shown = redact(f"server said: user=ops&password={echo}&imei=1", secret_forms(PASSWORD, "ops"))
    assert echo not in shown and "password=***&imei=1" in shown


class EchoingGateway(BaseHTTPRequestHandler):
    """A gateway (or a proxy in front of it) whose error page quotes the request body back."""

    def do_POST(self) -> None:  # noqa: N802 (http.server's name)
        body = self.rfile.read(int(self.headers["Content-Length"])).decode("ascii")
        reply = f"FAILED,10,Invalid login credentials in request {body}".encode()
        self.send_response(200)
        self.send_header("Content-Length", str(len(reply)))
        self.end_headers()
        self.wfile.write(reply)

    def log_message(self, *args: object) -> None:
        pass


@pytest.fixture
def echoing_gateway() -> Iterator[str]:
    server = ThreadingHTTPServer(("127.0.0.1", 0), EchoingGateway)
    thread = threading.Thread(target=server.serve_forever, daemon=True)
    thread.start()
    try:
        yield f"http://127.0.0.1:{server.server_address[1]}/rockblock/MT"
    finally:
        server.shutdown()
        server.server_close()


def test_a_gateway_that_echoes_the_form_encoded_request_shows_no_password(echoing_gateway: str) -> None:
    gateway = RockblockGateway(echoing_gateway, "ops", PASSWORD, timeout_s=5.0, retry_delay_s=0.0)
    result = gateway.send("300234010753370", b"[INTERVAL=5]")
    assert result.status == "failed" and "password=***" in result.detail
    for form in secret_forms(PASSWORD, "ops"):
        assert form not in result.detail

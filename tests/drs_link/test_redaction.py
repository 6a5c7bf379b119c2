"""The RockBLOCK password never reaches the operator in any encoding a server or proxy echoes it in."""

from __future__ import annotations

import base64
import os
import sqlite3
import subprocess
import sys
import threading
import unicodedata
from collections.abc import Iterator
from http.server import BaseHTTPRequestHandler, ThreadingHTTPServer
from pathlib import Path
from urllib.parse import parse_qs, quote, quote_plus

import pytest

from drs_link.iridium.gateway import RockblockGateway
from drs_link.redaction import redact, secret_forms

REPO = Path(__file__).resolve().parents[2]
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


class EchoingEveryWay(BaseHTTPRequestHandler):
    """A gateway whose error page quotes the password back in the six encodings the re-probe found leaking
    (#24 item 10), and the whole request base64-encoded."""

    bodies: list[bytes] = []

    def do_POST(self) -> None:  # noqa: N802 (http.server's name)
        body = self.rfile.read(int(self.headers["Content-Length"]))
        self.bodies.append(body)
        password = parse_qs(body.decode("ascii"))["password"][0]
        echoes = [form for form, _ in six_encodings(password, body)]
        reply = ("FAILED,10,Invalid login credentials: " + " | ".join(echoes)).encode()
        self.send_response(200)
        self.send_header("Content-Length", str(len(reply)))
        self.end_headers()
        self.wfile.write(reply)

    def log_message(self, *args: object) -> None:
        pass


def six_encodings(password: str, body: bytes) -> list[tuple[str, str]]:
    """(the password so encoded, the encoding's name); for base64 of the body, the run of its characters
    that only the password's bytes decide."""
    sent = quote_plus(password, safe="").encode()
    start = body.index(sent)
    token = base64.b64encode(body).decode()
    first, last = -(-start // 3), (start + len(sent)) // 3
    return [
        (quote(password), "quote with / safe"),
        ("".join(f"&#{ord(c)};" for c in password), "HTML numeric entities"),
        (quote(quote(password, safe=""), safe=""), "double percent-encoding"),
        (token[4 * first : 4 * last], "base64 of the body"),
        (unicodedata.normalize("NFD", password), "NFD"),
        (repr(password.encode())[2:-1], "bytes repr"),
    ]


def test_every_output_of_a_real_run_is_free_of_the_password_in_each_echoed_encoding(tmp_path: Path) -> None:
    server = ThreadingHTTPServer(("127.0.0.1", 0), EchoingEveryWay)
    threading.Thread(target=server.serve_forever, daemon=True).start()
    config = tmp_path / "drs.toml"
    config.write_text(
        f'[operator]\nname = "alice"\n[data]\ndir = "{tmp_path / "data"}"\n'
        f'[rockblock]\nmt_url = "http://127.0.0.1:{server.server_address[1]}/rockblock/MT"\nusername = "ops"\n'
        'password_env = "DRS_TEST_RB"\ntimeout_s = 5.0\n'
        '[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nimei = "300234010753370"\nrockblock_serial = 11800\n'
    )
    env = {**os.environ, "PYTHONPATH": str(REPO), "DRS_TEST_RB": PASSWORD}
    outputs = []
    try:
        for argv in (
            ["mt", "send", "DRS1", "--interval", "5", "--confirm", "DRS1"],
            ["mt", "status", "DRS1", "--json"],
        ):
            done = subprocess.run([sys.executable, "-m", "console.commands.main", "--config", str(config), *argv],
                                  cwd=REPO, capture_output=True, text=True, timeout=60, env=env)  # fmt: skip
            outputs += [done.stdout, done.stderr]
    finally:
        server.shutdown()
        server.server_close()
    assert "FAILED 10" in outputs[0] or "Invalid login" in outputs[0] + outputs[1], outputs
    store = tmp_path / "data" / "drs.sqlite"
    rows = sqlite3.connect(store).execute("SELECT detail FROM mt_command UNION ALL SELECT detail FROM audit")
    outputs += [str(row[0]) for row in rows]
    outputs += [
        path.read_bytes().decode("utf-8", "replace")
        for path in (tmp_path / "data").iterdir()
        if path.is_file()
    ]
    [body] = EchoingEveryWay.bodies
    leaks = [(name, index) for form, name in six_encodings(PASSWORD, body) + [(PASSWORD, "raw")]
             for index, text in enumerate(outputs) if form in text]  # fmt: skip
    assert leaks == []
    assert "***" in outputs[0] + outputs[1]


def test_a_password_given_as_password_env_is_refused_at_load_without_being_shown(tmp_path: Path) -> None:
    from drs_link.config import parse_config
    from drs_link.errors import ConfigError

    with pytest.raises(ConfigError) as refused:
        parse_config({"rockblock": {"password_env": "hunter2xyz"}})
    assert "hunter2xyz" not in str(refused.value) and "rockblock.password_env" in str(refused.value)

"""`drs mo serve` as deployed: a real process, real signals, real sockets, its access log and its audit."""

from __future__ import annotations

import os
import signal
import socket
import subprocess
import sys
import threading
import time
import tomllib
from pathlib import Path
from urllib.parse import urlsplit

import pytest

from drs_link.config import parse_config
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.reports import ReportStore
from drs_link.sim.rockblock import MoDelivery, mo_body, post_mo
from drs_link.store import Store

from .helpers import IMEI, T0, fix_at

REPO = Path(__file__).resolve().parents[3]
DRS = "import sys, console.commands.main as c; sys.exit(c.main())"


def delivery(momsn: int) -> MoDelivery:
    return MoDelivery(IMEI, 11800, momsn, format_mo(fix_at(T0), 8.9, momsn % 256), T0, 46.5, 6.6, 2.0)


class Receiver:
    """A `drs mo serve` process and the URL it printed; its output is read as it comes, as journald does
    (a pipe nobody reads fills at 64 kB and then stalls every thread that logs)."""

    def __init__(self, tmp_path: Path, extra_mo: str = "") -> None:
        self.config = tmp_path / "drs.toml"
        self.config.write_text(
            f'[data]\ndir = "{tmp_path / "data"}"\n'
            f'[mo]\nlisten_host = "127.0.0.1"\nlisten_port = 0\nrequire_jwt = false\n{extra_mo}'
        )
        self.store_path = tmp_path / "data" / "drs.sqlite"
        self.process = subprocess.Popen(
            [sys.executable, "-c", DRS, "--config", str(self.config), "mo", "serve"],
            cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
            env={**os.environ, "PYTHONPATH": str(REPO)},
        )  # fmt: skip
        assert self.process.stdout is not None and self.process.stderr is not None
        line = self.process.stdout.readline()
        assert line.startswith("listening on http://127.0.0.1:"), line + self.process.stderr.read()
        self.url = line.split()[2]
        self._logged: list[str] = []
        self._readers = [
            threading.Thread(target=lambda: self.process.stdout.read(), daemon=True),  # type: ignore[union-attr]
            threading.Thread(target=lambda: self._logged.extend(self.process.stderr), daemon=True),  # type: ignore[arg-type]
        ]
        for reader in self._readers:
            reader.start()

    def wait(self) -> tuple[int, str]:
        """The exit status and everything it logged, once it has ended."""
        status = self.process.wait(timeout=30)
        for reader in self._readers:
            reader.join(timeout=10)
        return status, "".join(self._logged)

    def stop(self) -> tuple[int, str]:
        """SIGTERM, as systemd stops it."""
        self.process.send_signal(signal.SIGTERM)
        return self.wait()

    def stored_momsns(self) -> set[int]:
        store = Store.open(self.store_path)
        try:
            return {r.delivery.momsn for r in ReportStore(store).for_imei(IMEI)}
        finally:
            store.close()

    def rejected(self) -> list[tuple[str, str]]:
        store = Store.open(self.store_path)
        try:
            return [
                (row["remote"], row["reason"]) for row in store.query("SELECT * FROM mo_delivery_rejected")
            ]
        finally:
            store.close()


def _half_sent_post(url: str, momsn: int) -> tuple[socket.socket, bytes]:
    """A POST whose headers and first body bytes are sent and the rest held back: in flight until finished."""
    body, content_type = mo_body(delivery(momsn))
    parts = urlsplit(url)
    sock = socket.create_connection((parts.hostname or "", parts.port or 80), timeout=20)
    head = (
        f"POST {parts.path} HTTP/1.1\r\nHost: {parts.netloc}\r\nContent-Type: {content_type}\r\n"
        f"Content-Length: {len(body)}\r\n\r\n"
    )
    sock.sendall(head.encode() + body[:10])
    return sock, body[10:]


def _finish(sock: socket.socket, rest: bytes) -> bytes:
    sock.sendall(rest)
    reply = b""
    while chunk := sock.recv(4096):
        reply += chunk
    sock.close()
    return reply


def test_sigterm_mid_burst_drains_and_loses_no_acknowledged_report(
    tmp_path: Path, receivers: list[Receiver]
) -> None:
    receiver = Receiver(tmp_path)
    receivers.append(receiver)
    answers: dict[int, int | str] = {}
    signalled = threading.Event()

    def client(first: int) -> None:
        momsn = first
        while True:
            try:
                answers[momsn] = post_mo(receiver.url, delivery(momsn), timeout_s=10)
            except OSError as exc:  # refused or reset: never an HTTP answer
                answers[momsn] = type(getattr(exc, "reason", exc)).__name__
                if signalled.is_set():
                    return  # the listening socket is closed: the gateway would retry later
            momsn += 1

    threads = [threading.Thread(target=client, args=(1000 * i,)) for i in range(1, 9)]
    for thread in threads:
        thread.start()
    slow, rest = _half_sent_post(
        receiver.url, 42
    )  # a delivery whose body is still arriving when SIGTERM comes
    deadline = time.monotonic() + 20
    while sum(status == 200 for status in list(answers.values())) < 100 and time.monotonic() < deadline:
        time.sleep(0.005)
    receiver.process.send_signal(signal.SIGTERM)
    signalled.set()
    time.sleep(0.3)  # the receiver has stopped listening and is waiting for the slow one
    assert _finish(slow, rest).split(b"\r\n")[0] == b"HTTP/1.0 200 OK"
    for thread in threads:
        thread.join(timeout=30)
    status, err = receiver.wait()

    assert status == 0, err
    acknowledged = {momsn for momsn, status in answers.items() if status == 200} | {42}
    assert len(acknowledged) > 100 and acknowledged <= receiver.stored_momsns()
    refused = [status for status in answers.values() if status != 200]
    assert refused and all(isinstance(status, str) for status in refused), (
        refused
    )  # no 4xx/5xx, only closed doors
    assert " INFO console.commands.iridium: stopping signal=SIGTERM" in err
    assert " INFO drs_link.iridium.webhook: draining in_flight=" in err
    assert " INFO console.commands.iridium: stopped unanswered=0" in err


def _post_from(url: str, body: bytes, forwarded: str | None) -> int:
    import urllib.error
    import urllib.request

    headers = {"Content-Type": "application/x-www-form-urlencoded"}
    if forwarded is not None:
        headers["X-Forwarded-For"] = forwarded
    request = urllib.request.Request(url + "?token=not-for-the-log", data=body, headers=headers)
    try:
        with urllib.request.urlopen(request, timeout=5) as response:
            return int(response.status)
    except urllib.error.HTTPError as exc:
        return int(exc.code)


@pytest.mark.parametrize(
    ("trusted", "audited", "logged"),
    [
        ('trusted_proxy = "127.0.0.1"\n', "203.0.113.9 via 127.0.0.1", "client=203.0.113.9 proxy=127.0.0.1"),
        ("", "127.0.0.1", 'client=127.0.0.1 forwarded_ignored="198.51.100.1, 203.0.113.9"'),
        (
            'trusted_proxy = "192.0.2.1"\n',
            "127.0.0.1",
            'client=127.0.0.1 forwarded_ignored="198.51.100.1, 203.0.113.9"',
        ),
    ],
    ids=["from-the-trusted-proxy", "no-proxy-trusted", "from-another-address"],
)
def test_x_forwarded_for_names_the_client_only_from_the_trusted_proxy(
    tmp_path: Path, receivers: list[Receiver], trusted: str, audited: str, logged: str
) -> None:
    """The proxy appends the address it saw; what came before it is the sender's own say and is not believed."""
    receiver = Receiver(tmp_path, trusted)
    receivers.append(receiver)
    assert _post_from(receiver.url, b"imei=1&momsn=1&data=00", "198.51.100.1, 203.0.113.9") == 400
    assert _post_from(receiver.url, mo_body(delivery(7))[0], "198.51.100.1, 203.0.113.9") == 200
    status, err = receiver.stop()
    assert status == 0
    assert receiver.rejected() == [(audited, "missing or malformed imei")]
    access = [line for line in err.splitlines() if " INFO drs_link.iridium.webhook.access: " in line]
    assert len(access) == 2 and all(logged in line for line in access), access
    assert " status=400 " in access[0] and " status=200 " in access[1] and " path=/rockblock/mo " in access[1]
    assert "not-for-the-log" not in err


def test_a_trusted_proxy_that_is_not_an_address_is_refused_at_start(tmp_path: Path) -> None:
    config = tmp_path / "drs.toml"
    config.write_text('[mo]\nrequire_jwt = false\ntrusted_proxy = "localhost"\n')
    done = subprocess.run(
        [sys.executable, "-c", DRS, "--config", str(config), "mo", "serve"],
        cwd=REPO, capture_output=True, text=True, timeout=60, env={**os.environ, "PYTHONPATH": str(REPO)},
    )  # fmt: skip
    assert done.returncode == 1
    assert done.stderr.startswith("drs: error: mo.trusted_proxy: 'localhost' must be the proxy's IP address")


def test_the_documented_server_configuration_is_one_the_receiver_takes() -> None:
    """docs/iridium.md's /etc/drs/drs.toml, as an operator would copy it."""
    text = (REPO / "docs" / "iridium.md").read_text(encoding="utf-8")
    start = text.index("```toml\n", text.index("### Configuration on the server")) + len("```toml\n")
    config = parse_config(tomllib.loads(text[start : text.index("```", start)]))
    assert (config.mo.listen_host, config.mo.trusted_proxy, config.mo.require_jwt) == (
        "127.0.0.1",
        "127.0.0.1",
        True,
    )
    assert config.store_path == Path("/var/lib/drs/drs.sqlite")

"""The store when it cannot be written: on a read-only filesystem it can still be read, and locked by another
process the receiver answers 503 inside the gateway's 3 s, the access log says which answers never reached
their client, `drs mt send` says it is waiting, and `GET /health` tells a monitor (issue #24 items 7, 8, 12;
#25 item 10). Real processes, real sockets, a real read-only bind mount (in a user namespace)."""

from __future__ import annotations

import json
import os
import shutil
import socket
import sqlite3
import subprocess
import sys
import time
import urllib.error
import urllib.request
from collections.abc import Iterator
from contextlib import contextmanager
from datetime import timedelta
from pathlib import Path

import pytest

from drs_link.iridium.firmware import format_mo
from drs_link.iridium.reports import ReportStore
from drs_link.sim.rockblock import MoDelivery, SimulatedRockblock, mo_body, post_mo
from drs_link.store import Store, utc_now
from tests.console.commands.test_cli_iridium import write_config

from .helpers import IMEI, fix_at, to_delivery
from .test_receiver_process import DRS, REPO, Receiver


@pytest.fixture(autouse=True)
def _private_server_in_this_process(monkeypatch: pytest.MonkeyPatch) -> None:
    """`drs` acts through its private operations server; here in a thread of this process, so what these
    tests watch or patch in the operations layer is what the server runs (drs_link.server.private)."""
    monkeypatch.setenv("DRS_PRIVATE_SERVER", "thread")


def drs(
    config: Path, *argv: str, wrap: list[str] | None = None, **env: str
) -> subprocess.CompletedProcess[str]:
    command = [sys.executable, "-c", DRS, "--config", str(config), *argv]
    return subprocess.run(
        [*(wrap or []), *command], cwd=REPO, capture_output=True, text=True, timeout=120,
        env={**os.environ, "PYTHONPATH": str(REPO), **env},
    )  # fmt: skip


def mo(momsn: int, minutes_ago: float, alt: float = 400.0) -> MoDelivery:
    moment = utc_now().replace(microsecond=0) - timedelta(minutes=minutes_ago)
    return MoDelivery(
        IMEI, 11800, momsn, format_mo(fix_at(moment, alt=alt), 8.9, momsn), moment, 46.5, 6.6, 2.0
    )


def read_only(folder: Path) -> list[str]:
    """The command prefix that runs a process with ``folder`` bind-mounted read-only over itself."""
    if shutil.which("unshare") is None:
        pytest.skip("unshare is not installed")
    probe = subprocess.run(["unshare", "-rm", "true"], capture_output=True)
    if probe.returncode != 0:
        pytest.skip(f"no user namespaces here: {probe.stderr.decode().strip()}")
    script = f'mount --bind "{folder}" "{folder}" && mount -o remount,bind,ro "{folder}" && exec "$@"'
    return ["unshare", "-rm", "sh", "-c", script, "sh"]


def test_a_store_on_a_read_only_filesystem_is_read_by_recovery_health_status_and_export(
    tmp_path: Path,
) -> None:
    config = write_config(tmp_path)
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    reports = ReportStore(store)
    for momsn, (minutes, alt) in enumerate(
        [(30, 9_000.0), (20, 3_000.0), (10, 400.0), (5, 400.0), (1, 400.0)]
    ):
        reports.add(to_delivery(mo(momsn, minutes, alt)))
    assert (
        drs(config, "mt", "send", "DRS1", "--interval", "5", "--confirm", "DRS1", DRS_TEST_RB="x").returncode
        == 1
    )  # fmt: skip  (no gateway: one command, failed)
    store.close()
    before = (tmp_path / "data" / "drs.sqlite").read_bytes()
    wrap = read_only(tmp_path / "data")
    out = tmp_path / "track.csv"
    for argv in (["mo", "health", "DRS1"], ["mt", "status", "DRS1"], ["recovery", "DRS1"],
                 ["mo", "export", "DRS1", "--out", str(out)]):  # fmt: skip
        done = drs(config, *argv, wrap=wrap)
        assert done.returncode == 0, f"{argv}: {done.stderr}"
        assert "Read-only file system" not in done.stderr and "Traceback" not in done.stderr
    assert out.read_text().count("\n") == 6, "a header and the five fixes"
    status = drs(config, "mt", "status", "DRS1", wrap=wrap).stdout
    assert "[INTERVAL=5]" in status
    refused = drs(
        config, "mt", "send", "DRS1", "--interval", "7", "--confirm", "DRS1", wrap=wrap, DRS_TEST_RB="x"
    )
    assert refused.returncode == 1 and "read-only filesystem: nothing can be recorded" in refused.stderr
    assert refused.stderr.count("\n") == 1
    assert (tmp_path / "data" / "drs.sqlite").read_bytes() == before


HOLD_THE_LOCK = """
import sqlite3, sys
conn = sqlite3.connect(sys.argv[1], isolation_level=None)
conn.execute("BEGIN EXCLUSIVE")
print("locked", flush=True)
sys.stdin.readline()
conn.execute("ROLLBACK")
"""


@contextmanager
def locked(store_path: Path) -> Iterator[subprocess.Popen[str]]:
    """Another process holding the store's write lock until the block ends."""
    holder = subprocess.Popen([sys.executable, "-c", HOLD_THE_LOCK, str(store_path)],
                              stdin=subprocess.PIPE, stdout=subprocess.PIPE, text=True)  # fmt: skip
    try:
        assert holder.stdout is not None and holder.stdout.readline() == "locked\n"
        yield holder
    finally:
        if holder.poll() is None:
            assert holder.stdin is not None
            holder.stdin.write("\n")
            holder.stdin.flush()
        holder.wait(timeout=10)


def health(url: str) -> tuple[int, dict[str, object]]:
    target = url.replace("/rockblock/mo", "/health")
    try:
        with urllib.request.urlopen(target, timeout=10) as answer:
            return answer.status, json.loads(answer.read())
    except urllib.error.HTTPError as error:
        return error.code, json.loads(error.read())


def test_a_locked_store_gets_503_inside_three_seconds_and_the_post_is_stored_when_retried(
    tmp_path: Path, receivers: list[Receiver]
) -> None:
    receiver = Receiver(tmp_path)
    receivers.append(receiver)
    assert post_mo(receiver.url, mo(1, 3)) == 200
    status, answer = health(receiver.url)
    assert status == 200 and answer["store_writable"] is True
    assert 0 <= answer["last_delivery_age_s"] < 60  # type: ignore[operator]
    assert set(answer) == {"status", "store_writable", "last_delivery_age_s", "jwt_required"}
    with locked(receiver.store_path):
        started = time.monotonic()
        assert post_mo(receiver.url, mo(2, 2), timeout_s=10) == 503
        took = time.monotonic() - started
        status, answer = health(receiver.url)
        assert status == 503 and answer["store_writable"] is False
    assert took < 3.0, f"the gateway waits 3 s; the 503 took {took:.2f} s"
    assert post_mo(receiver.url, mo(2, 2)) == 200, "the gateway's retry"
    _, logged = receiver.stop()
    assert receiver.stored_momsns() == {1, 2}
    assert "POST /rockblock/mo 503" in logged


def test_an_answer_whose_client_left_is_logged_as_not_sent_not_as_200(
    tmp_path: Path, receivers: list[Receiver]
) -> None:
    receiver = Receiver(tmp_path)
    receivers.append(receiver)
    assert post_mo(receiver.url, mo(1, 3)) == 200
    body, content_type = mo_body(mo(2, 2))
    host, port = receiver.url.split("//")[1].split("/")[0].split(":")
    with locked(receiver.store_path) as holder:
        client = socket.create_connection((host, int(port)), timeout=10)
        head = (f"POST /rockblock/mo HTTP/1.1\r\nHost: {host}\r\nContent-Type: {content_type}\r\n"
                f"Content-Length: {len(body)}\r\n\r\n")  # fmt: skip
        client.sendall(head.encode() + body)
        time.sleep(0.5)  # read by the receiver, which now waits for the store
        client.setsockopt(socket.SOL_SOCKET, socket.SO_LINGER, b"\x01\x00\x00\x00\x00\x00\x00\x00")
        client.close()  # a reset, as a gateway that gave up
        assert holder.stdin is not None
        holder.stdin.write("\n")
        holder.stdin.flush()
    time.sleep(1.0)
    _, logged = receiver.stop()
    assert receiver.stored_momsns() == {1, 2}, "stored: the gateway's retry will be a duplicate"
    [line] = [entry for entry in logged.splitlines() if "POST /rockblock/mo" in entry and "NOT SENT" in entry]
    assert "200 NOT SENT (client gone" in line


def test_drs_mt_send_says_it_is_waiting_for_a_locked_store(tmp_path: Path) -> None:
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        config = write_config(tmp_path, gateway.url)
        assert drs(config, "mt", "status", "DRS1").returncode == 0  # the store and its tables exist
        with locked(tmp_path / "data" / "drs.sqlite"):
            sender = subprocess.Popen(
                [sys.executable, "-c", DRS, "--config", str(config), "mt", "send", "DRS1", "--interval", "5",
                 "--confirm", "DRS1"],
                cwd=REPO, stdout=subprocess.PIPE, stderr=subprocess.PIPE, text=True,
                env={**os.environ, "PYTHONPATH": str(REPO), "DRS_TEST_RB": "pw"},
            )  # fmt: skip
            assert sender.stderr is not None
            line = sender.stderr.readline()
            assert "is locked by another process: waiting up to" in line, line
            assert sender.poll() is None, "said while the store is still locked, not after"
        out, err = sender.communicate(timeout=60)
        assert sender.returncode == 0, err
        assert "queued" in out and len(gateway.requests) == 1


def test_a_drip_fed_request_is_cut_off_at_the_request_deadline(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> None:
    from drs_link.config import MoConfig
    from drs_link.iridium import webhook

    monkeypatch.setattr(webhook, "REQUEST_DEADLINE_S", 2.0)
    store = Store.open(tmp_path / "drs.sqlite")
    config = MoConfig(listen_host="127.0.0.1", listen_port=0, require_jwt=False)
    server = webhook.MoHttpServer(webhook.MoReceiver(ReportStore(store), config)).start()
    try:
        host, port = server.server_address[:2]
        client = socket.create_connection((host, port), timeout=30)
        started = time.monotonic()
        cut = False
        for byte in b"POST /rockblock/mo HTTP/1.1\r\nHost: x\r\nContent-Length: 1000\r\n\r\n" + b"x" * 100:
            try:
                client.sendall(bytes([byte]))
            except OSError:
                cut = True
                break
            time.sleep(0.2)
            if time.monotonic() - started > 10:
                break
        if not cut:
            cut = client.recv(100) == b""
        assert cut and time.monotonic() - started < 6, (
            "one byte every 0.2 s once held the connection for ever"
        )
        client.close()
    finally:
        server.stop()
        store.close()
    assert (
        sqlite3.connect(tmp_path / "drs.sqlite").execute("SELECT COUNT(*) FROM mo_report").fetchone()[0] == 0
    )

"""The MO webhook on 127.0.0.1 with the simulated gateway posting to it, and the email importer."""

from __future__ import annotations

import json
import os
import socket
import sqlite3
import threading
import urllib.request
from collections.abc import Iterator
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from drs_link.config import MoConfig
from drs_link.errors import ConfigError
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.importer import NAMES_ACCEPTED, import_files
from drs_link.iridium.reports import ReportStore, StoredReport
from drs_link.iridium.webhook import MoHttpServer, MoReceiver
from drs_link.sim.rockblock import MoDelivery, generate_test_keys, post_mo
from drs_link.store import Store

from .helpers import IMEI, T0, fix_at


@pytest.fixture(scope="module")
def gateway_keys() -> tuple[str, str]:
    return generate_test_keys()


@pytest.fixture
def store(tmp_path: Path) -> Iterator[Store]:
    store = Store.open(tmp_path / "drs.sqlite")
    yield store
    store.close()


def serve(store: Store, config: MoConfig, on_report=None) -> MoHttpServer:
    return MoHttpServer(MoReceiver(ReportStore(store), config, on_report)).start()


def delivery(momsn: int = 7, payload: bytes | None = None) -> MoDelivery:
    payload = format_mo(fix_at(T0), 8.9, 3) if payload is None else payload
    return MoDelivery(IMEI, 11800, momsn, payload, T0 + timedelta(seconds=40), 46.51, 6.61, 3.0)


LOCAL = MoConfig(listen_host="127.0.0.1", listen_port=0, max_body_bytes=2048, require_jwt=False)
"""Opted out of the JWT: most tests here are about bodies, not signatures (those below opt back in)."""


def test_form_and_json_deliveries_are_stored_parsed_and_duplicates_dropped(store: Store) -> None:
    server = serve(store, LOCAL)
    try:
        assert post_mo(server.url, delivery(7)) == 200
        assert post_mo(server.url, delivery(7), as_json=True) == 200
        assert post_mo(server.url, delivery(8), as_json=True) == 200
    finally:
        server.stop()
    reports = ReportStore(store).for_imei(IMEI)
    assert [(r.delivery.momsn, r.delivery.source) for r in reports] == [
        (7, "webhook-form"),
        (8, "webhook-json"),
    ]
    first = reports[0]
    assert first.report is not None and first.report.fix is not None and first.report.fix.time == T0
    assert first.delivery.transmit_utc == T0 + timedelta(seconds=40)
    assert first.delivery.iridium_cep_km == 3.0
    assert "momsn=7" in (first.delivery.raw_delivery or "")


def test_malformed_payload_is_stored_as_rejected_and_answered_200(store: Store) -> None:
    server = serve(store, LOCAL)
    try:
        assert post_mo(server.url, delivery(9, b"\x01\x02garbage")) == 200
    finally:
        server.stop()
    [report] = ReportStore(store).for_imei(IMEI)
    assert not report.parsed.accepted and "not printable ASCII" in (report.parsed.reason or "")


def _post(url: str, body: bytes, content_type: str) -> int:
    request = urllib.request.Request(url, data=body, headers={"Content-Type": content_type})
    try:
        with urllib.request.urlopen(request, timeout=5) as response:
            return int(response.status)
    except urllib.error.HTTPError as exc:
        return int(exc.code)


def test_malformed_deliveries_get_specific_errors_and_are_kept_for_forensics(store: Store) -> None:
    server = serve(store, LOCAL)
    try:
        assert _post(server.url, b"{not json", "application/json") == 400
        assert _post(server.url, b"imei=123&momsn=1&data=00", "application/x-www-form-urlencoded") == 400
        assert _post(server.url, b"imei=300234010753370&data=00", "application/x-www-form-urlencoded") == 400
        assert _post(server.url, b"x", "text/plain") == 415
        assert _post(server.url, b"x" * 4096, "application/x-www-form-urlencoded") == 413
        assert _post(server.url.replace("/rockblock/mo", "/elsewhere"), b"x", "application/json") == 404
    finally:
        server.stop()
    reasons = [reason for reason, _ in ReportStore(store).rejected_deliveries()]
    assert reasons == [
        "body is not valid JSON",
        "missing or malformed imei",
        "missing or malformed momsn",
        "unsupported content type text/plain",
        "body of 4096 bytes over the limit",
    ]
    assert ReportStore(store).for_imei(IMEI) == []


def test_signed_deliveries_are_verified_and_badly_signed_ones_refused(
    store: Store, require_signed: MoConfig, gateway_keys: tuple[str, str]
) -> None:
    private, _ = gateway_keys
    forger_private, _ = generate_test_keys()
    server = serve(store, require_signed)
    try:
        assert post_mo(server.url, delivery(1), jwt_private_key=private) == 200
        assert post_mo(server.url, delivery(2), jwt_private_key=forger_private) == 401
        assert post_mo(server.url, delivery(3)) == 401
        tampered = delivery(4)
        signed_fields = tampered.fields()
        import jwt

        token = jwt.encode({"iss": "Rock 7", **signed_fields}, private, algorithm="RS256")
        body = json.dumps({**signed_fields, "data": "00", "JWT": token}).encode()
        assert _post(server.url, body, "application/json") == 401
    finally:
        server.stop()
    [report] = ReportStore(store).for_imei(IMEI)
    assert report.delivery.momsn == 1 and report.delivery.jwt_verified
    reasons = [reason for reason, _ in ReportStore(store).rejected_deliveries()]
    assert reasons == [
        "JWT rejected: InvalidSignatureError",
        "no JWT and mo.require_jwt is set",
        "JWT claim data does not match the delivered data",
    ]


def test_the_receiver_requires_a_jwt_by_default_and_says_how_to_opt_out(store: Store) -> None:
    with pytest.raises(ConfigError, match="jwt_public_key_file is not set.*mo.require_jwt = false"):
        MoReceiver(ReportStore(store), MoConfig())


def test_opting_out_of_the_jwt_is_loud(store: Store, caplog: pytest.LogCaptureFixture) -> None:
    MoReceiver(ReportStore(store), LOCAL)
    assert "anyone who can reach /rockblock/mo can forge a position report" in caplog.text


def _signed(private: str, fields: dict[str, object]) -> str:
    import jwt

    return jwt.encode({"iss": "Rock 7", **fields}, private, algorithm="RS256")


@pytest.fixture
def require_signed(tmp_path: Path, gateway_keys: tuple[str, str]) -> MoConfig:
    """The receiver as deployed: a JWT required, verified with the (test) gateway's public key."""
    key_file = tmp_path / "rock7.pem"
    key_file.write_text(gateway_keys[1])
    return replace(LOCAL, jwt_public_key_file=key_file, require_jwt=True)


def _post_json_once(store: Store, config: MoConfig, body: bytes) -> int:
    """One JSON delivery to a receiver started for it; the HTTP status."""
    server = serve(store, config)
    try:
        return _post(server.url, body, "application/json")
    finally:
        server.stop()


@pytest.mark.parametrize(
    ("field", "altered"),
    [("transmit_time", "26-09-01 11:00:00"), ("iridium_latitude", "12.3400"), ("serial", "11801")],
)
def test_a_signed_delivery_with_any_field_altered_is_refused(
    store: Store, require_signed: MoConfig, gateway_keys: tuple[str, str], field: str, altered: str
) -> None:
    fields = delivery(5).fields()
    body = json.dumps({**fields, field: altered, "JWT": _signed(gateway_keys[0], fields)}).encode()
    assert _post_json_once(store, require_signed, body) == 401
    assert ReportStore(store).for_imei(IMEI) == []
    assert [reason for reason, _ in ReportStore(store).rejected_deliveries()] == [
        f"JWT claim {field} does not match the delivered {field}"
    ]


def test_a_jwt_that_does_not_sign_the_data_is_refused(
    store: Store, require_signed: MoConfig, gateway_keys: tuple[str, str]
) -> None:
    """Such a token, lifted from any real delivery, would vouch for whatever data came with it."""
    fields = delivery(6).fields()
    token = _signed(gateway_keys[0], {k: v for k, v in fields.items() if k != "data"})
    assert _post_json_once(store, require_signed, json.dumps({**fields, "JWT": token}).encode()) == 401
    assert [reason for reason, _ in ReportStore(store).rejected_deliveries()] == [
        "the JWT does not sign data"
    ]


def test_signed_numbers_match_by_value_and_unsigned_fields_are_not_stored(
    store: Store, require_signed: MoConfig, gateway_keys: tuple[str, str]
) -> None:
    """The gateway's claim formats are not documented: 46.51 signed as a number matches "46.5100"."""
    fields = delivery(9).fields()
    claims: dict[str, object] = {**fields, "iridium_latitude": 46.51, "momsn": 9}
    del claims["iridium_cep"]
    body = json.dumps(
        {**fields, "iridium_latitude": "46.5100", "JWT": _signed(gateway_keys[0], claims)}
    ).encode()
    assert _post_json_once(store, require_signed, body) == 200
    [report] = ReportStore(store).for_imei(IMEI)
    assert report.delivery.jwt_verified and report.delivery.iridium_lat == pytest.approx(46.51)
    assert report.delivery.iridium_cep_km is None


def test_heavy_work_runs_after_the_answer(store: Store) -> None:
    release = threading.Event()
    seen: list[StoredReport] = []

    def slow_processing(stored: StoredReport) -> None:
        release.wait(10)
        seen.append(stored)

    server = serve(store, LOCAL, slow_processing)
    try:
        assert post_mo(server.url, delivery(5), timeout_s=5) == 200
        assert seen == []
        release.set()
    finally:
        server.stop()
    assert [s.delivery.momsn for s in seen] == [5]


def test_email_attachments_import_once_and_bad_files_are_reported(store: Store, tmp_path: Path) -> None:
    good = tmp_path / f"{IMEI}-12.bin"
    good.write_bytes(format_mo(fix_at(T0), 8.9, 3))
    garbage = tmp_path / f"{IMEI}-13.bin"
    garbage.write_bytes(b"\xff\xfe")
    badly_named = tmp_path / "message.bin"
    badly_named.write_bytes(b"x")
    huge = tmp_path / f"{IMEI}-14.bin"
    huge.write_bytes(b"1" * 400)
    missing = tmp_path / f"{IMEI}-15.bin"
    reports = ReportStore(store)
    outcomes = import_files([good, garbage, badly_named, huge, missing, good], reports)
    assert [o.status for o in outcomes] == ["new", "rejected", "error", "error", "error", "duplicate"]
    assert (
        outcomes[2].message == f"name is not {NAMES_ACCEPTED}"
        and "<imei>_<momsn>.sbd (RockBLOCK)" in NAMES_ACCEPTED
    )
    assert [r.delivery.momsn for r in reports.for_imei(IMEI)] == [13, 12] or [
        r.delivery.momsn for r in reports.for_imei(IMEI)
    ] == [12, 13]


@pytest.mark.parametrize(
    ("name", "momsn", "transmitted"),
    [
        (f"{IMEI}-000123.bin", 123, None),
        (f"{IMEI}-00000.sbd", 0, None),
        (f"{IMEI}_125.sbd", 125, None),
        (f"19-04-07_09-59-59_{IMEI}_000124.sbd", 124, datetime(2019, 4, 7, 9, 59, 59, tzinfo=UTC)),
    ],
)
def test_rockblock_iridium_direct_and_zero_padded_names_are_imported(
    store: Store, tmp_path: Path, name: str, momsn: int, transmitted: datetime | None
) -> None:
    path = tmp_path / name
    path.write_bytes(format_mo(fix_at(T0), 8.9, 3))
    [outcome] = import_files([path], ReportStore(store))
    assert outcome.status == "new" and outcome.stored is not None
    assert outcome.stored.delivery.momsn == momsn and outcome.stored.delivery.transmit_utc == transmitted


@pytest.mark.parametrize(
    "name",
    [f"{IMEI}-٣.bin", f"{IMEI[:-1]}５-3.bin", f"{IMEI}-65536.bin", "19-13-40_25-00-00_" + IMEI + "_1.sbd"],
)
def test_non_ascii_digits_out_of_range_momsns_and_impossible_times_are_refused(
    store: Store, tmp_path: Path, name: str
) -> None:
    path = tmp_path / name
    path.write_bytes(format_mo(fix_at(T0), 8.9, 3))
    [outcome] = import_files([path], ReportStore(store))
    assert outcome.status == "error"


def test_a_fifo_is_refused_without_blocking(store: Store, tmp_path: Path) -> None:
    fifo = tmp_path / f"{IMEI}-7.sbd"
    os.mkfifo(fifo)
    [outcome] = import_files([fifo], ReportStore(store))
    assert outcome.status == "error" and "not a regular file" in outcome.message


def _raw_post(url: str, head_length: int, body: bytes) -> bytes:
    """A POST whose Content-Length says ``head_length`` but whose body is ``body`` (then the client stops).

    The whole reply is read until the server closes: headers and body arrive as separate writes.
    """
    from urllib.parse import urlsplit

    parts = urlsplit(url)
    with socket.create_connection((parts.hostname, parts.port), timeout=5) as conn:
        conn.sendall(
            f"POST {parts.path} HTTP/1.1\r\nHost: x\r\nContent-Type: application/x-www-form-urlencoded\r\n"
            f"Content-Length: {head_length}\r\n\r\n".encode()
            + body
        )
        conn.shutdown(socket.SHUT_WR)
        reply = b""
        while chunk := conn.recv(4096):
            reply += chunk
        return reply


def test_a_body_shorter_than_its_content_length_is_refused_not_stored_cut(store: Store) -> None:
    """The cut body once stored iteration 1234 as 12, and the gateway's redelivery became a second report."""
    body = f"imei={IMEI}&momsn=7&data={format_mo(fix_at(T0), 8.9, 1234).hex()}".encode()
    server = serve(store, LOCAL)
    try:
        reply = _raw_post(server.url, len(body), body[:-6])
    finally:
        server.stop()
    assert reply.startswith(b"HTTP/1.0 400") and b"shorter than its Content-Length" in reply
    assert ReportStore(store).for_imei(IMEI) == []


@pytest.mark.parametrize(
    "body",
    [
        b"imei=300234010753370&momsn=%C2%B2&data=00",
        "imei=30023401075337５&momsn=1&data=00".encode(),
        "imei=300234010753370&momsn=٣&data=00".encode(),
    ],  # fmt: skip
    ids=["superscript-momsn", "fullwidth-imei", "arabic-indic-momsn"],
)
def test_digits_other_than_ascii_are_refused_with_400(store: Store, body: bytes) -> None:
    server = serve(store, LOCAL)
    try:
        assert _post(server.url, body, "application/x-www-form-urlencoded") == 400
    finally:
        server.stop()
    assert ReportStore(store).for_imei(IMEI) == []


def test_a_burst_of_connections_waits_in_the_listen_backlog_while_every_thread_is_busy(store: Store) -> None:
    """The stdlib's backlog of 5 reset connections when 20 gateway clients posted at once. Here nothing
    accepts until 40 connections have arrived: each must complete its handshake in the kernel's queue (a
    connection beyond a full queue never does while nobody accepts, so this cannot pass by chance), and
    each is then answered."""
    server = MoHttpServer(MoReceiver(ReportStore(store), LOCAL))
    waiting: list[socket.socket] = []
    serving = False
    try:
        for _ in range(40):
            waiting.append(socket.create_connection(server.server_address[:2], timeout=2.0))
        serving = server.start() is server
        for conn in waiting:
            conn.sendall(b"GET / HTTP/1.0\r\n\r\n")
            assert conn.recv(64).startswith(b"HTTP/1.0 405")
    finally:
        for conn in waiting:
            conn.close()
        if serving:
            server.stop()
        else:
            server.server_close()  # never served: stop() would wait for a loop that never ran


def test_a_serial_in_other_digits_keeps_the_report_without_the_serial(store: Store) -> None:
    """``serial=²`` on an otherwise valid report once lost the report: the serial is optional, the report is not."""
    body = f"imei={IMEI}&momsn=7&serial=%C2%B2&data={format_mo(fix_at(T0), 8.9, 3).hex()}".encode()
    server = serve(store, LOCAL)
    try:
        assert _post(server.url, body, "application/x-www-form-urlencoded") == 200
    finally:
        server.stop()
    [stored] = ReportStore(store).for_imei(IMEI)
    assert stored.report is not None and stored.report.iteration == 3 and stored.delivery.serial is None


def test_json_nested_thousands_deep_gets_a_400_not_an_empty_reply(store: Store) -> None:
    server = serve(store, replace(LOCAL, max_body_bytes=1_000_000))
    try:
        assert _post(server.url, b"[" * 100_000 + b"]" * 100_000, "application/json") == 400
    finally:
        server.stop()
    assert ReportStore(store).rejected_deliveries()[-1][0] == "JSON nested too deeply"


def test_a_store_that_cannot_be_written_answers_503_so_the_gateway_retries(store: Store) -> None:
    """A full disk or any store failure: the gateway must hear "retry", not a closed connection."""
    receiver = MoReceiver(ReportStore(store), LOCAL)
    store.conn.execute("PRAGMA query_only = ON")  # every write now fails inside SQLite
    body = f"imei={IMEI}&momsn=7&data={format_mo(fix_at(T0), 8.9, 3).hex()}".encode()
    status, text, stored = receiver.handle("application/x-www-form-urlencoded", body, "127.0.0.1")
    assert (status, stored) == (503, None) and "retry" in text


def test_a_store_that_cannot_be_written_still_answers_every_post_over_http(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """A full disk: a report gets 503 (retry), and a delivery refused anyway still gets its refusal, not
    a connection closed without an answer (keeping the refused body for forensics once raised there)."""
    connect = Store._connect

    def read_only(self: Store) -> sqlite3.Connection:
        conn = connect(self)
        conn.execute("PRAGMA query_only = ON")  # every write now fails inside SQLite
        return conn

    server = serve(store, LOCAL)
    monkeypatch.setattr(Store, "_connect", read_only)  # the handler threads open their connections now
    try:
        valid = f"imei={IMEI}&momsn=7&data={format_mo(fix_at(T0), 8.9, 3).hex()}".encode()
        assert _post(server.url, valid, "application/x-www-form-urlencoded") == 503
        assert _post(server.url, b"imei=1&momsn=7&data=00", "application/x-www-form-urlencoded") == 400
        assert _post(server.url, b"x" * 4096, "application/x-www-form-urlencoded") == 413
    finally:
        server.stop()
    assert ReportStore(store).for_imei(IMEI) == [] and ReportStore(store).rejected_deliveries() == []


def test_the_oldest_rejected_deliveries_make_room_for_new_ones(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    import drs_link.iridium.reports as reports

    monkeypatch.setattr(reports, "REJECTED_KEPT", 5)
    book = ReportStore(store)
    for n in range(12):
        book.reject_delivery(T0, "127.0.0.1", f"garbage {n}", "x" * 10_000)
    kept = book.rejected_deliveries()
    assert [reason for reason, _ in kept] == [f"garbage {n}" for n in range(7, 12)]
    assert all(len(body) == reports.REJECTED_BODY_CHARS for _, body in kept)


@pytest.mark.parametrize(
    ("field", "altered"),
    [("data", "31323334353637383931"), ("data", "3132_3334_3536_3738_3930"), ("data", "0031323334353637383930"),
     ("momsn", "09"), ("momsn", "9.0"), ("imei", "0300234010753370")],
)  # fmt: skip
def test_identity_and_payload_claims_are_compared_as_exact_text_not_as_numbers(
    store: Store, require_signed: MoConfig, gateway_keys: tuple[str, str], field: str, altered: str
) -> None:
    """#24 item 5: a signed data of 20 digits matched a delivered one differing in the 20th digit (equal as
    floats), with ``_`` separators or with leading zeros, and was stored as verified."""
    fields = {**delivery(9).fields(), "data": "31323334353637383930"}
    claims: dict[str, object] = {**fields, "momsn": 9}
    body = json.dumps({**fields, field: altered, "JWT": _signed(gateway_keys[0], claims)}).encode()
    assert _post_json_once(store, require_signed, body) == 401
    assert ReportStore(store).for_imei(IMEI) == [] and ReportStore(store).for_imei("0300234010753370") == []
    assert [reason for reason, _ in ReportStore(store).rejected_deliveries()] == [
        f"JWT claim {field} does not match the delivered {field}"
    ]


def test_a_token_issued_a_second_ahead_of_this_clock_is_accepted_within_the_leeway(
    store: Store, require_signed: MoConfig, gateway_keys: tuple[str, str]
) -> None:
    import time

    fields = delivery(10).fields()
    ahead = _signed(gateway_keys[0], {**fields, "iat": int(time.time()) + 2})
    assert _post_json_once(store, require_signed, json.dumps({**fields, "JWT": ahead}).encode()) == 200
    far = _signed(gateway_keys[0], {**fields, "momsn": "11", "iat": int(time.time()) + 600})
    assert (
        _post_json_once(store, require_signed, json.dumps({**fields, "momsn": "11", "JWT": far}).encode())
        == 401
    )

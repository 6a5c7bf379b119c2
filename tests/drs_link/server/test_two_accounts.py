"""The attacks of issue #29, each by one person with one account, against a real shared `drs server`.

On main before the server each of these worked: an operator approved their own PARACHUTE override from a
config they wrote (their own ssh key listed as JM's approver key), or forged an approval with one UPDATE of
the group-writable store. Here the server knows each caller from the kernel (SO_PEERCRED) and its own
`[[operator]]` list, and its store sits in its own 0700 directory: each attack is refused, nothing
reaches the gateway, and only a second account's live approval lets the command go.
"""

from __future__ import annotations

import os
import pwd
import socket
import sqlite3
from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path

import pytest

from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.server.protocol import PROTOCOL, DecideRequest, encode
from drs_link.sim.rockblock import SimulatedRockblock
from drs_link.store import Store, utc_now
from tests.drs_link.server.team import (
    Server,
    Team,
    as_account,
    client_config,
    drs,
    drs_waiting,
    needs_root,
    server_config,
)

pytestmark = needs_root
IMEI = "300434060000029"
PASSWORD = "pw-server"
OVERRIDE = "the chase team sees it on the ground; GNSS frozen"
PARACHUTE = ["mt", "send", "DRS1", "--parachute", "next", "--accept-midnight", "--confirm", "DRS1",
             "--override-landed", OVERRIDE]  # fmt: skip


@pytest.fixture
def gateway() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password=PASSWORD, imeis=(IMEI,)) as simulated:
        yield simulated


@pytest.fixture
def server(place: Path, team: Team, gateway: SimulatedRockblock) -> Iterator[Server]:
    """The team's server with the two-person rule on, and a capsule falling at 8 km (no landed evidence)."""
    config = server_config(place, team, (
        f'[rockblock]\nmt_url = "{gateway.url}"\nusername = "ops"\npassword_env = "DRS_SERVER_RB"\n'
        f'timeout_s = 5.0\n[console]\nrequire_second_operator = true\n'
        f'[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nport = 9\nimei = "{IMEI}"\nrockblock_serial = 17001\n'
    ))  # fmt: skip
    store = Store.open(place / "state" / "drs.sqlite")
    start = utc_now() - timedelta(minutes=12)
    for n in range(6):
        add_report(store, n, start + timedelta(minutes=2 * n), 20000.0 - 2400.0 * n)
    store.close()
    running = Server(config, place, team.group, {"DRS_SERVER_RB": PASSWORD})
    yield running
    running.stop()


def add_report(store: Store, momsn: int, at: datetime, alt_m: float) -> None:
    fix = GnssFix(at, 67.70 + 0.0001 * momsn, 21.60, alt_m, 20.0, 90.0, 0.9, 9)
    delivery = Delivery(IMEI, momsn, format_mo(fix, 8.7, momsn).hex(), "webhook", at + timedelta(seconds=20),
                        transmit_utc=at + timedelta(seconds=15))  # fmt: skip
    ReportStore(store).add(delivery)


def audit(place: Path, action: str) -> list[tuple[str, dict[str, object] | None]]:
    store = Store.open(place / "state" / "drs.sqlite")
    try:
        return [(a.result, a.detail) for a in store.audit("DRS1") if a.action == action]
    finally:
        store.close()


def audit_rows(place: Path) -> int:
    store = Store.open(place / "state" / "drs.sqlite")
    try:
        return int(store.query("SELECT COUNT(*) FROM audit")[0][0])
    finally:
        store.close()


def raw(user: str, sock: Path, request: bytes) -> str:
    """Bytes written straight to the server's socket as ``user``; the answer's text."""

    def talk() -> int:
        conn = socket.socket(socket.AF_UNIX, socket.SOCK_STREAM)
        conn.connect(str(sock))
        conn.sendall(request)  # and reads until the server closes (Connection: close)
        chunks = []
        while chunk := conn.recv(65536):
            chunks.append(chunk)
        print(b"".join(chunks).decode(errors="replace"))
        return 0

    return as_account(user, talk)[1]


def post(path: str, body: bytes, headers: str = "") -> bytes:
    return (f"POST /v{PROTOCOL}{path} HTTP/1.1\r\nHost: drs\r\nContent-Type: application/json\r\n{headers}"
            f"Content-Length: {len(body)}\r\nConnection: close\r\n\r\n").encode() + body  # fmt: skip


def test_a_parachute_override_goes_only_once_another_account_approves_and_every_shortcut_is_refused(
    server: Server,
    place: Path,
    team: Team,
    gateway: SimulatedRockblock,
) -> None:
    alice_config = client_config(place, team.alice)
    # Alice's own config, the attack of #29: she names herself JM (the approver key list it also had is
    # no longer read at all: such a file is refused, tests/drs_link/test_config.py).
    forged = place / "forged.toml"
    forged.write_text(f'[operator]\nname = "JM"\n[server]\nsocket = "{server.socket}"\n')
    forged.chmod(0o644)
    waiting = drs_waiting(team.alice, alice_config, *PARACHUTE, "--await-approval")
    lines = []
    while not (line := waiting.readline()).startswith("approval #"):
        assert line, f"the send ended before asking: {''.join(lines)}"
        lines.append(line)
    assert line.startswith("approval #1: waiting for another account to run `drs approve 1`")

    code, out = drs(team.alice, forged, "approve", "1")
    assert code == 1 and f"the same login ({team.alice}) that requested it cannot approve it" in out, out

    claim = encode(DecideRequest(PROTOCOL, True))[:-1] + b',"account":"' + team.bob.encode() + b'"}'
    answer = raw(team.alice, server.socket, post("/approvals/1", claim))
    assert "400" in answer.splitlines()[0] and "unknown field" in answer and "account" in answer, answer
    answer = raw(team.alice, server.socket, post(
        "/approvals/1", encode(DecideRequest(PROTOCOL, True)), f"X-Drs-Account: {team.bob}\r\nX-Remote-User: JM\r\n"
    ))  # fmt: skip
    assert "409" in answer.splitlines()[0] and f"the same login ({team.alice})" in answer, answer

    code, out = drs(team.mallory, client_config(place, team.mallory), "approve", "1")
    assert code == 1 and f"the account {team.mallory}" in out and "not an operator of this server" in out, out
    code, out = drs(team.outsider, client_config(place, team.outsider), "approve", "1")
    assert code == 1 and "permission denied: this account is not in the server's group" in out, out

    def forge_in_store() -> int:
        store = place / "state" / "drs.sqlite"
        for attempt in (
            lambda: sqlite3.connect(store).execute("UPDATE approval SET state='approved', decided_by='JM'"),
            lambda: open(store, "r+b"),  # noqa: SIM115 - the open itself is what the OS refuses
        ):
            try:
                attempt()
            except (PermissionError, sqlite3.OperationalError) as exc:
                print(f"refused: {exc}")
            else:
                print("WRITTEN")
        return 0

    code, out = as_account(team.alice, forge_in_store)
    assert out.count("refused: ") == 2 and "WRITTEN" not in out, out
    assert gateway.requests == [], "nothing reached the gateway while it waited"

    code, out = drs(team.bob, client_config(place, team.bob), "approve", "1")
    assert code == 0 and "approved by JM" in out, out
    code, out = waiting.result()
    assert code == 0, out
    assert "approval #1: approved by JM (" + team.bob in out and "queued" in out
    [queued] = list(gateway.queues[IMEI])
    assert queued.startswith(b"[PARACHUTE="), queued
    peers = audit(place, "approval.peer")
    uids = {pwd.getpwnam(team.alice).pw_uid, pwd.getpwnam(team.bob).pw_uid}
    assert {d["uid"] for _, d in peers if d} == uids and [r for r, _ in peers] == ["requester", "approver"]
    [authorised] = [d for r, d in audit(place, "mt.parachute") if r == "authorised"]
    assert authorised is not None and authorised["override_landed"] == OVERRIDE
    assert str(authorised["approved_by"]).startswith(f"JM ({team.bob})")


def test_one_account_alone_cannot_queue_parachute_in_flight_under_the_rule(
    server: Server,
    place: Path,
    team: Team,
    gateway: SimulatedRockblock,
) -> None:
    alice_config = client_config(
        place, team.alice, '[console]\nrequire_second_operator = false\ncrew = ["EL", "JM"]\n'
    )
    for people in (["--second-operator", "JM"], ["--single-operator-waiver", "alone tonight"]):
        code, out = drs(team.alice, alice_config, *PARACHUTE, *people)
        assert code == 1 and "require_second_operator is on" in out, out
    assert gateway.requests == []
    assert [r for r, _ in audit(place, "mt.parachute")] == ["refused", "refused"]


def test_malformed_oversized_and_out_of_order_messages_get_one_clear_error_and_change_nothing(
    server: Server,
    place: Path,
    team: Team,
    gateway: SimulatedRockblock,
) -> None:
    before = audit_rows(place)
    cases = {
        "not JSON": (post("/approvals/1", b"{approve: yes"), "400", "not JSON"),
        "wrong type": (post("/approvals/1", b'{"protocol": 1, "approve": "yes"}'), "400", "Expected `bool`"),
        "no protocol": (post("/approvals/1", b'{"approve": true}'), "400", "missing required field `protocol`"),
        "other version": (post("/approvals/1", b'{"protocol": 2, "approve": true}'), "400",
                          "the client speaks protocol 2, this server 1"),
        "oversized": (post("/capsules/DRS1/fire", b'{"protocol": 1, "typed_name": "' + b"x" * 100_000 + b'"}'),
                      "413" , "larger than 65536 bytes"),
        "unknown route": (b"GET /v2/hello HTTP/1.1\r\nHost: drs\r\nConnection: close\r\n\r\n", "400",
                          "this server speaks protocol 1"),
        "no such approval": (post("/approvals/7", encode(DecideRequest(PROTOCOL, True))), "409",
                             "approval #7 does not exist"),
    }  # fmt: skip
    for name, (request, status, said) in cases.items():
        answer = raw(team.alice, server.socket, request)
        first = answer.splitlines()[0] if answer else ""
        assert said in answer and (status in first or name == "oversized"), (name, answer)
    assert audit_rows(place) == before, "nothing was acted on, so nothing was audited"
    code, out = drs(
        team.alice, client_config(place, team.alice), "capsule", "go", "DRS1", "--confirm", "DRS1"
    )
    assert code == 1 and "DRS1: FIRE refused: not armed" in out, out
    assert gateway.requests == []
    assert server.process.poll() is None, "the server is still up"


def test_the_server_refuses_a_configuration_another_account_could_write(place: Path, team: Team) -> None:
    config = server_config(place, team, "")
    config.chmod(0o664)
    code, out = drs("root", config, "server", "--socket", str(place / "s.sock"))
    assert code == 1 and "writable by its group or others (mode 0664)" in out, out
    config.chmod(0o644)
    os.chown(config, pwd.getpwnam(team.alice).pw_uid, -1)
    code, out = drs("root", config, "server", "--socket", str(place / "s.sock"))
    assert code == 1 and f"belongs to {team.alice}; it must belong to root (chown root" in out, out
    os.chown(config, 0, -1)
    (place / "state").chmod(0o770)
    code, out = drs("root", config, "server", "--socket", str(place / "s.sock"))
    assert code == 1 and "must be its own, mode 0700" in out, out

"""The landed gate trusts only what it can: JWT-verified reports, fixes not dated after their arrival, and a
track the capsule could have flown (issue #24 item 1: three forged unsigned POSTs once queued PARACHUTE).

The end-to-end case runs as deployed: a `drs mo serve` process that accepts unsigned deliveries
(``require_jwt = false``) alongside signed ones, real POSTs on loopback, and `drs mt send` as its own process
against the simulated RockBLOCK gateway.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path

import pytest

from drs_link.errors import RefusedError
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.landed import landed_evidence
from drs_link.iridium.mo import parse_payload
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import Delivery, ReportStore, StoredReport
from drs_link.ops.approval import ApprovalBook, Login
from drs_link.ops.authorize import authorize_mt
from drs_link.sim.rockblock import MoDelivery, SimulatedRockblock, generate_test_keys, post_mo
from drs_link.store import Store, utc_now
from tests.console.commands.test_cli_iridium import write_config

from .helpers import IMEI, fix_at
from .test_receiver_process import DRS, REPO, Receiver


def signed_fall(now: datetime) -> list[tuple[datetime, float, float]]:
    """Ten fixes a minute apart falling from 24.1 km to 15.1 km, the last 11 s before ``now``."""
    last = now - timedelta(seconds=11)
    return [(last - timedelta(minutes=9 - i), 24_100.0 - 1_000.0 * i, 17.0) for i in range(10)]


def forged_landing(now: datetime) -> list[tuple[datetime, float, float]]:
    """Three still fixes at 400 m dated now+5 s, +65 s and +125 s: the attack of the issue."""
    return [(now + timedelta(seconds=5 + 60 * i), 400.0, 0.0) for i in range(3)]


def mo(momsn: int, moment: datetime, alt: float, speed: float) -> MoDelivery:
    payload = format_mo(fix_at(moment, alt=alt, speed=speed), 8.9, momsn)
    return MoDelivery(IMEI, 11800, momsn, payload, moment, 46.5, 6.6, 2.0)


@pytest.fixture
def gateway() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password="pw") as simulated:
        yield simulated


def waived_parachute(tmp_path: Path, gateway: SimulatedRockblock) -> subprocess.CompletedProcess[str]:
    """`drs mt send DRS1 --parachute next --single-operator-waiver …` as its own process, on the data dir
    the receiver wrote (the operator's config)."""
    config = write_config(tmp_path, gateway.url)
    return subprocess.run(
        [sys.executable, "-c", DRS, "--config", str(config), "mt", "send", "DRS1", "--parachute", "next",
         "--accept-midnight", "--confirm", "DRS1", "--single-operator-waiver", "alone at the site"],
        cwd=REPO, capture_output=True, text=True, timeout=60,
        env={**os.environ, "PYTHONPATH": str(REPO), "DRS_TEST_RB": "pw"},
    )  # fmt: skip


def test_forged_unsigned_still_fixes_after_a_signed_fall_do_not_queue_parachute(
    tmp_path: Path, gateway: SimulatedRockblock
) -> None:
    private, public = generate_test_keys()
    key_file = tmp_path / "rock7.pem"
    key_file.write_text(public)
    receiver = Receiver(tmp_path, f'jwt_public_key_file = "{key_file}"\n')
    try:
        now = utc_now().replace(microsecond=0)
        for momsn, (moment, alt, speed) in enumerate(signed_fall(now), start=1):
            assert post_mo(receiver.url, mo(momsn, moment, alt, speed), jwt_private_key=private) == 200
        for momsn, (moment, alt, speed) in enumerate(forged_landing(now), start=20):
            assert post_mo(receiver.url, mo(momsn, moment, alt, speed)) == 200, "stored, as unverified"
    finally:
        receiver.stop()
    sent = waived_parachute(tmp_path, gateway)
    assert sent.returncode == 1, sent.stdout + sent.stderr
    assert "NOT LANDED: last fix" in sent.stderr and "at 15,100 m" in sent.stderr
    assert "3 report(s) without a verified JWT ignored" in sent.stderr
    assert gateway.requests == [], "nothing reached the gateway"
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    try:
        [refused] = [a for a in store.audit() if a.action == "mt.parachute"]
        trusted = refused.detail["landed"]["trusted"]  # type: ignore[index]
        assert refused.result == "refused" and trusted["only_jwt_verified"] is True
        assert trusted["reports"] == 10 and len(trusted["ignored_unverified"]) == 3
    finally:
        store.close()


def stored(index: int, fix_time: datetime, alt: float, speed: float, received: datetime) -> StoredReport:
    payload = format_mo(fix_at(fix_time, alt=alt, speed=speed), 8.9, index)
    return StoredReport(index, Delivery(IMEI, index, payload.hex(), "test", received), parse_payload(payload))


def test_fixes_dated_after_their_arrival_are_not_evidence() -> None:
    now = utc_now().replace(microsecond=0)
    fall = [stored(i, t, alt, v, t + timedelta(seconds=40)) for i, (t, alt, v) in enumerate(signed_fall(now))]
    forged = [stored(20 + i, t, alt, v, now) for i, (t, alt, v) in enumerate(forged_landing(now))]
    evidence = landed_evidence(fall + forged)
    assert not evidence.on_ground and not evidence.verified
    assert evidence.trusted["ignored_future_dated"] == [21, 22], "+5 s is inside the 10 s leeway"
    assert "2 fix(es) dated after their arrival ignored" in evidence.summary


def test_a_drop_faster_than_any_fall_is_not_a_landing() -> None:
    """14.7 km down in 16 s, then still fixes stamped honestly: the landing rule alone called it landed."""
    now = utc_now().replace(microsecond=0)
    fall = signed_fall(now - timedelta(minutes=10))
    top = fall[-1][0]
    still = [(top + timedelta(seconds=16 + 60 * i), 400.0, 0.0) for i in range(3)]
    reports = [stored(i, t, alt, v, t + timedelta(seconds=40)) for i, (t, alt, v) in enumerate(fall + still)]
    evidence = landed_evidence(reports)
    assert not evidence.on_ground
    assert "implausible jump" in evidence.summary and "14.7 km down" in evidence.summary
    assert "in 16 s" in evidence.summary


def test_landed_evidence_from_unverified_reports_needs_another_logins_approval_never_a_name_or_waiver(
    tmp_path: Path,
) -> None:
    start = utc_now().replace(microsecond=0) - timedelta(minutes=20)
    moments = [start + timedelta(minutes=2 * i) for i in range(6)]
    alts = [9_000.0, 6_000.0, 3_000.0, 412.0, 412.0, 412.0]
    reports = [stored(i, t, a, 6.0 if a > 412 else 0.2, t + timedelta(seconds=40))
               for i, (t, a) in enumerate(zip(moments, alts, strict=True))]  # fmt: skip
    evidence = landed_evidence(reports)
    assert evidence.on_ground and not evidence.verified and "UNVERIFIED" in evidence.summary
    message = MtComposer().add("PARACHUTE", (10, 20)).build()
    store = Store.open(tmp_path / "drs.sqlite")
    try:
        refusal = "without a verified JWT.*another login must approve it"
        with pytest.raises(RefusedError, match=refusal):
            authorize_mt(store, "DRS1", "alice", message, reports, require_second_operator=False)
        with pytest.raises(RefusedError, match=refusal):
            authorize_mt(
                store, "DRS1", "alice", message, reports, second_operator="bob", crew=("alice", "bob")
            )
        with pytest.raises(RefusedError, match=refusal):
            authorize_mt(store, "DRS1", "alice", message, reports, single_operator_waiver="alone")
        book, alice = ApprovalBook(store), Login("alice")
        request = book.request("DRS1", "parachute", message.text, "alice", alice, command=message.text)
        book.decide(request.id, "bob", Login("bob"), approve=True)
        details = authorize_mt(store, "DRS1", "alice", message, reports, approval=request.id, login=alice)
        assert details["landed"]["verified"] is False and details["approved_by"] == "bob (bob)"
    finally:
        store.close()


def forged_past_landing(now: datetime, count: int = 31) -> list[tuple[datetime, float, float]]:
    """Issue #31's attack: ``count`` unsigned fixes two minutes apart, dated in the past (so none is dated
    after its arrival), a plausible fall from 9 km at 6 m/s then still at 412 m: a landing by every rule
    but the JWT."""
    first = now - timedelta(minutes=2 * count + 5)
    out = []
    for i in range(count):
        alt = max(412.0, 9_000.0 - 720.0 * i)
        out.append((first + timedelta(minutes=2 * i), alt, 6.0 if alt > 412.0 else 0.0))
    return out


def test_thirty_one_forged_unsigned_past_dated_fixes_and_a_waiver_never_queue_parachute(
    tmp_path: Path, gateway: SimulatedRockblock
) -> None:
    """Issue #31 item 4, as deployed: a receiver with ``require_jwt = false`` takes 31 forged POSTs, then
    `drs mt send --single-operator-waiver` (its own process) is refused and nothing reaches the gateway;
    the same evidence with another login's approval is allowed."""
    receiver = Receiver(tmp_path)
    try:
        now = utc_now().replace(microsecond=0)
        for momsn, (moment, alt, speed) in enumerate(forged_past_landing(now), start=1):
            assert post_mo(receiver.url, mo(momsn, moment, alt, speed)) == 200
    finally:
        receiver.stop()
    sent = waived_parachute(tmp_path, gateway)
    assert sent.returncode == 1, sent.stdout + sent.stderr
    assert "UNVERIFIED: from 31 report(s)" in sent.stderr and "another login must approve it" in sent.stderr
    assert gateway.requests == [], "nothing reached the gateway"
    store = Store.open(tmp_path / "data" / "drs.sqlite")
    try:
        [refused] = [a for a in store.audit() if a.action == "mt.parachute"]
        assert refused.result == "refused" and refused.detail["landed"]["on_ground"] is True  # type: ignore[index]
        reports = ReportStore(store).for_imei(IMEI)
        message = MtComposer().add("PARACHUTE", (10, 20)).build()
        book, requester = ApprovalBook(store), Login("alice")
        request = book.request("DRS1", "parachute", message.text, "alice", requester, command=message.text)
        book.decide(request.id, "bob", Login("bob"), approve=True)
        details = authorize_mt(store, "DRS1", "alice", message, reports, approval=request.id, login=requester)
        assert details["approved_by"] == "bob (bob)" and details["landed"]["verified"] is False
    finally:
        store.close()


def test_the_per_report_verdicts_apply_the_same_trust_as_the_gate() -> None:
    """The console marks each report with ``LandedVerdicts``; it must agree with the gate on every prefix:
    a signed fall then forged still fixes, future-dated still fixes, and a jump."""
    from dataclasses import replace

    from drs_link.iridium.landed import LandedVerdicts

    now = utc_now().replace(microsecond=0) - timedelta(hours=1)
    fall = [stored(i, t, alt, v, t + timedelta(seconds=40)) for i, (t, alt, v) in enumerate(signed_fall(now))]
    signed = [replace(r, delivery=replace(r.delivery, jwt_verified=True)) for r in fall]
    last = fall[-1].time
    at = [last + timedelta(minutes=30 + 2 * i) for i in range(3)]
    still = [stored(30 + i, at[i], 400.0, 0.0, at[i] + timedelta(minutes=1)) for i in range(3)]
    future = [stored(40 + i, last + timedelta(minutes=40 + 2 * i), 400.0, 0.0, last + timedelta(minutes=30))
              for i in range(3)]  # fmt: skip
    jump = [stored(50 + i, last + timedelta(seconds=16 + 60 * i), 400.0, 0.0, last + timedelta(minutes=5 + i))
            for i in range(3)]  # fmt: skip
    cases = [fall + still, fall[:5] + signed[5:] + still, fall + future, fall + jump, signed + still]
    for reports in cases:
        fed = LandedVerdicts()
        assert [fed.add(r) for r in reports] == [
            landed_evidence(reports[: i + 1]).on_ground for i in range(len(reports))
        ]
    assert landed_evidence(fall + still).on_ground and not landed_evidence(signed + still).on_ground

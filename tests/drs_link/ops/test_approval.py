"""Second-operator approval from another login: the request waits, a different login decides, once.

A login is an OS account (the server reads it from each connection: tests/drs_link/server/ pins that
with real accounts); here the book is given them directly. The PARACHUTE send runs as a real `drs` process against the simulated RockBLOCK on loopback while
`drs approve` runs from another login.
"""

from __future__ import annotations

import threading
from pathlib import Path

import pytest

from drs_link.errors import RefusedError
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import ReportStore
from drs_link.ops.approval import ApprovalBook, Login
from drs_link.ops.authorize import approval_command, authorize_mt
from drs_link.store import Store, utc_now
from tests.clock import ManualClock
from tests.drs_link.iridium.helpers import IMEI
from tests.drs_link.iridium.test_parachute_gate import audit_of, falling, landed, recent, seed

ALICE = Login("alice")
BOB = Login("bob")


def test_one_account_is_one_person_whatever_name_it_acts_under() -> None:
    assert not ALICE.same_person(BOB)
    assert ALICE.same_person(Login("alice", "JM")), "the operator name does not make another person"
    assert ALICE == Login("alice", "EL") and str(Login("alice", "EL")) == "alice", (
        "the audit names the account"
    )


@pytest.fixture
def book(tmp_path: Path) -> ApprovalBook:
    return ApprovalBook(Store.open(tmp_path / "drs.sqlite"), ManualClock(utc_now()))


def test_the_requesting_login_cannot_approve_its_own_request(book: ApprovalBook) -> None:
    request = book.request("DRS1", "parachute", "[PARACHUTE=01:19]", "alice", ALICE)
    with pytest.raises(RefusedError, match="the same login .* that requested it cannot approve it"):
        book.decide(request.id, "alice", ALICE, approve=True)
    with pytest.raises(RefusedError, match="cannot approve it"):
        book.decide(request.id, "bob", Login("alice"), approve=True)  # a typed name is not another login
    assert book.get(request.id).state == "pending"
    refusals = [r for r in book.store.audit("DRS1") if r.result == "refused"]
    assert len(refusals) == 2 and refusals[0].detail["login"] == str(ALICE)


def test_a_store_from_before_the_server_keeps_its_key_columns_readable_and_one_account_stays_one_person(
    tmp_path: Path,
) -> None:
    """The ssh-agent proof wrote a key fingerprint beside each account; the table is read as it is."""
    import sqlite3

    path = tmp_path / "drs.sqlite"
    with sqlite3.connect(path) as old:
        old.execute(
            "CREATE TABLE approval (id INTEGER PRIMARY KEY AUTOINCREMENT, capsule TEXT NOT NULL, action TEXT "
            "NOT NULL, summary TEXT NOT NULL, requested_by TEXT NOT NULL, requester_user TEXT NOT NULL, "
            "requester_key TEXT, requested_utc TEXT NOT NULL, expires_utc TEXT NOT NULL, state TEXT NOT NULL, "
            "decided_by TEXT, decider_user TEXT, decider_key TEXT, decided_utc TEXT, reason TEXT)"
        )
        old.execute(
            "INSERT INTO approval (capsule, action, summary, requested_by, requester_user, requester_key, "
            "requested_utc, expires_utc, state) VALUES ('DRS1', 'parachute', '[PARACHUTE=01:19]', 'EL', "
            "'ops', 'SHA256:keyA', '2026-01-01T00:00:00Z', '2999-01-01T00:00:00Z', 'pending')"
        )
    book = ApprovalBook(Store.open(path), ManualClock(utc_now()))
    assert book.get(1).requester == Login("ops") and book.open_requests()[0].id == 1
    with pytest.raises(RefusedError, match=r"the same login \(ops\) that requested it cannot approve it"):
        book.decide(1, "JM", Login("ops"), approve=True)  # its old key made another "person" of one account
    assert book.decide(1, "JM", BOB, approve=True).decider == BOB
    newer = book.request("DRS1", "go", "release DRS1", "alice", ALICE, command="ARM window #1")
    assert book.get(newer.id).requester == ALICE


def test_an_approval_is_spent_once_by_its_requester_on_its_command(book: ApprovalBook) -> None:
    request = book.request("DRS1", "go", "release DRS1", "alice", ALICE, command="ARM window #1")
    approved = book.decide(request.id, "bob", BOB, approve=True, reason="checked the go/no-go")
    assert approved.state == "approved" and approved.decider == BOB
    with pytest.raises(RefusedError, match="was given for DRS1 Go"):
        book.use(request.id, "DRS1", "parachute", ALICE)
    with pytest.raises(RefusedError, match="was requested by"):
        book.use(request.id, "DRS1", "go", Login("mallory"))
    people = book.use(request.id, "DRS1", "go", ALICE)
    assert people == {"approved_by": f"bob ({BOB})", "approval": str(request.id)}
    with pytest.raises(RefusedError, match="is used, not approved"):
        book.use(request.id, "DRS1", "go", ALICE)
    decided = [r.detail for r in book.store.audit("DRS1") if r.action == "approval.approved"]
    assert decided[0]["login"] == str(BOB) and decided[0]["requester_login"] == str(ALICE)


def test_a_request_and_an_approval_expire(book: ApprovalBook) -> None:
    clock = book.clock
    assert isinstance(clock, ManualClock)
    late = book.request("DRS1", "parachute", "[PARACHUTE=01:19]", "alice", ALICE, ttl_s=60.0)
    clock.advance(60.0)
    assert book.open_requests() == []
    with pytest.raises(RefusedError, match=r"it is pending, expired .*, not pending"):
        book.decide(late.id, "bob", BOB, approve=True)
    unused = book.request(
        "DRS1", "parachute", "[PARACHUTE=01:21]", "alice", ALICE, ttl_s=60.0, command="[PARACHUTE=01:21]"
    )
    book.decide(unused.id, "bob", BOB, approve=True)
    clock.advance(61.0)
    with pytest.raises(RefusedError, match=r"is approved, expired"):
        book.use(unused.id, "DRS1", "parachute", ALICE)


def test_two_approvers_at_once_decide_it_once(book: ApprovalBook) -> None:
    request = book.request("DRS1", "go", "release DRS1", "alice", ALICE)
    outcomes: list[str] = []
    approvers = [Login("bob"), Login("carol"), Login("dave"), Login("erin")]

    def decide(login: Login, approve: bool) -> None:
        try:
            outcomes.append(book.decide(request.id, login.user, login, approve).state)
        except RefusedError:
            outcomes.append("refused")

    threads = [threading.Thread(target=decide, args=(login, i % 2 == 0)) for i, login in enumerate(approvers)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert outcomes.count("refused") == 3
    [winner] = [o for o in outcomes if o != "refused"]
    assert book.get(request.id).state == winner


def test_parachute_with_an_approval_from_another_login_is_audited_with_both(tmp_path: Path) -> None:
    store = seed(tmp_path, landed(recent(10.5)))
    reports = ReportStore(store).for_imei(IMEI)
    book = ApprovalBook(store)
    message = MtComposer().add("PARACHUTE", (1, 19)).build()
    request = book.request("DRS1", "parachute", message.text, "alice", ALICE, command=message.text)
    with pytest.raises(RefusedError, match="not approved"):
        authorize_mt(store, "DRS1", "alice", message, reports, approval=request.id, login=ALICE)
    book.decide(request.id, "bob", BOB, approve=True)
    people = authorize_mt(store, "DRS1", "alice", message, reports, approval=request.id, login=ALICE)
    assert people["approved_by"] == f"bob ({BOB})"
    authorised = audit_of(store, "mt.parachute")[-1]
    assert authorised["result"] == "authorised" and authorised["approval"] == str(request.id)


CHILD = "import sys; from console.commands.main import main; sys.exit(main(sys.argv[1:]))"


def test_an_approval_request_is_refused_for_a_command_the_rule_does_not_cover(tmp_path: Path) -> None:
    book = ApprovalBook(Store.open(tmp_path / "drs.sqlite"))
    with pytest.raises(ValueError, match="unknown hazardous action"):
        book.request("DRS1", "interval", "[INTERVAL=5]", "alice", ALICE)


def test_an_approval_is_void_once_the_capsules_state_changed_and_its_requester_may_cancel_one(
    book: ApprovalBook,
) -> None:
    """#23: a request stayed "pending" after the capsule it was for had been released."""
    take_over = "release-authority take-over: laptop1 died"
    request = book.request("DRS1", "authority", take_over, "alice", ALICE, command=take_over,
                           capsule_state="powered")  # fmt: skip
    book.decide(request.id, "bob", BOB, approve=True)
    with pytest.raises(RefusedError, match="was given for release-authority take-over: laptop1 died, not"):
        book.use(request.id, "DRS1", "authority", ALICE, "release-authority take-over: other", "powered")
    with pytest.raises(RefusedError, match="was given while DRS1 was powered; it is now released"):
        book.use(request.id, "DRS1", "authority", ALICE, take_over, "released")
    assert book.get(request.id).state == "void" and book.open_requests() == []
    second = book.request(
        "DRS1", "parachute", "[PARACHUTE=01:19]", "alice", ALICE, command="[PARACHUTE=01:19]"
    )
    with pytest.raises(RefusedError, match="only they can cancel it"):
        book.cancel(second.id, "bob", BOB)
    assert book.cancel(second.id, "alice", ALICE).state == "cancelled"
    with pytest.raises(RefusedError, match=r"it is cancelled \(cancelled by alice\), not pending"):
        book.decide(second.id, "bob", BOB, approve=True)
    states = [(a.action, a.result) for a in book.store.audit("DRS1")]
    assert ("approval.void", "void") in states and ("approval.cancelled", "cancelled") in states


def test_an_approval_of_the_parachute_text_never_stands_for_an_in_flight_override(tmp_path: Path) -> None:
    """The approver saw "[PARACHUTE=…]", not that the landed gate would be overridden: the override and its
    reason are part of what is approved, so the approval of the text alone cannot drop it in flight."""
    store = seed(tmp_path, falling(recent(10.5)))
    reports = ReportStore(store).for_imei(IMEI)
    book = ApprovalBook(store)
    message = MtComposer().add("PARACHUTE", (1, 19)).build()
    plain = book.request("DRS1", "parachute", message.text, "alice", ALICE, command=message.text)
    book.decide(plain.id, "bob", BOB, approve=True)
    override = "the chase team sees it on the ground"
    with pytest.raises(
        RefusedError, match=r"was given for \[PARACHUTE=01:19\], not .*OVERRIDE of the landed gate"
    ):
        authorize_mt(store, "DRS1", "alice", message, reports, approval=plain.id, login=ALICE,
                     override_landed=override)  # fmt: skip
    bound = approval_command(message, override)
    told = book.request("DRS1", "parachute", bound, "alice", ALICE, command=bound)
    assert "OVERRIDE of the landed gate: the chase team" in told.describe(utc_now()), (
        "what the approver reads"
    )
    book.decide(told.id, "bob", BOB, approve=True)
    people = authorize_mt(store, "DRS1", "alice", message, reports, approval=told.id, login=ALICE,
                          override_landed=override)  # fmt: skip
    assert people["override_landed"] == override and people["approval"] == str(told.id)


def test_an_approval_for_one_parachute_time_never_sends_another(tmp_path: Path) -> None:
    store = seed(tmp_path, landed(recent(10.5)))
    reports = ReportStore(store).for_imei(IMEI)
    book = ApprovalBook(store)
    approved_text = MtComposer().add("PARACHUTE", (1, 19)).build()
    request = book.request(
        "DRS1", "parachute", approved_text.text, "alice", ALICE, command=approved_text.text
    )
    book.decide(request.id, "bob", BOB, approve=True)
    other = MtComposer().add("PARACHUTE", (1, 21)).build()
    with pytest.raises(RefusedError, match=r"was given for \[PARACHUTE=01:19\], not \[PARACHUTE=01:21\]"):
        authorize_mt(store, "DRS1", "alice", other, reports, approval=request.id, login=ALICE)
    assert book.get(request.id).state == "approved", "still only good for 01:19"
    assert audit_of(store, "mt.parachute")[-1]["result"] == "refused"


def test_a_parachute_refused_after_its_approval_leaves_it_unspent_and_a_sent_one_spends_it_with_its_row(
    tmp_path: Path,
) -> None:
    """Issue #29: a refusal after ``approval.used`` must not be possible. The gateway's password is missing:
    refused before the approval is spent. With it, the approval is marked used in the transaction that
    records the MT (``CommandLifecycle.request``'s ``also``)."""
    from drs_link.errors import ConfigError
    from drs_link.ops.ops_state import SecondOperator
    from drs_link.sim.rockblock import SimulatedRockblock
    from tests.drs_link.iridium.test_parachute_gate import signed
    from tests.drs_link.ops.test_brief import parachute_ops

    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        ops, store = parachute_ops(tmp_path, gateway)
        for report in signed(landed(recent(10.5))):
            ReportStore(store).add(report.delivery)
        plan = ops.iridium.plan_parachute("DRS1", None, accept_midnight=True)
        message = MtComposer().add("PARACHUTE", (plan.hour, plan.minute)).build()
        book = ApprovalBook(store)
        second = SecondOperator(
            await_approval=True, on_pending=lambda r: book.decide(r.id, "JM", Login("jm"), approve=True)
        )
        ops.state.environ = {}
        with pytest.raises(ConfigError):
            ops.iridium.send_mt("DRS1", message, "DRS1", second, queue_by=plan.queue_by)
        assert book.get(1).state == "approved" and gateway.requests == []
        assert not [a for a in store.audit() if a.action == "approval.used"]
        ops.state.environ = {"DRS_TEST_RB": "pw"}
        ops.iridium.send_mt("DRS1", message, "DRS1", second, queue_by=plan.queue_by)
        assert book.get(2).state == "used" and len(gateway.requests) == 1
        assert [a.action for a in store.audit()].count("approval.used") == 1

"""Second-operator approval from another login: the request waits, a different login decides, once.

Logins are real: the OS account of this process and SSH keys made by ssh-keygen, proven through a real
ssh-agent against the configuration's [[approver]] list (test_identity.py pins the proof itself). The
PARACHUTE send runs as a real `drs` process against the simulated RockBLOCK on loopback while
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

ALICE_A = Login("ops", "SHA256:keyA")
ALICE_B = Login("ops", "SHA256:keyB")


def test_one_account_is_one_person_unless_different_keys_say_otherwise() -> None:
    assert not Login("alice").same_person(Login("bob"))
    assert Login("ops").same_person(Login("ops"))
    assert Login("ops").same_person(ALICE_A), "a key on one side only cannot tell them apart"
    assert not ALICE_A.same_person(ALICE_B)


@pytest.fixture
def book(tmp_path: Path) -> ApprovalBook:
    return ApprovalBook(Store.open(tmp_path / "drs.sqlite"), ManualClock(utc_now()))


def test_the_requesting_login_cannot_approve_its_own_request(book: ApprovalBook) -> None:
    request = book.request("DRS1", "parachute", "[PARACHUTE=01:19]", "alice", ALICE_A)
    with pytest.raises(RefusedError, match="the same login .* that requested it cannot approve it"):
        book.decide(request.id, "alice", ALICE_A, approve=True)
    with pytest.raises(RefusedError, match="cannot approve it"):
        book.decide(request.id, "bob", Login("ops"), approve=True)  # a typed name is not another login
    assert book.get(request.id).state == "pending"
    refusals = [r for r in book.store.audit("DRS1") if r.result == "refused"]
    assert len(refusals) == 2 and refusals[0].detail["login"] == str(ALICE_A)


def test_an_approval_is_spent_once_by_its_requester_on_its_command(book: ApprovalBook) -> None:
    request = book.request("DRS1", "go", "release DRS1", "alice", ALICE_A, command="ARM window #1")
    approved = book.decide(request.id, "bob", ALICE_B, approve=True, reason="checked the go/no-go")
    assert approved.state == "approved" and approved.decider == ALICE_B
    with pytest.raises(RefusedError, match="was given for DRS1 Go"):
        book.use(request.id, "DRS1", "parachute", ALICE_A)
    with pytest.raises(RefusedError, match="was requested by"):
        book.use(request.id, "DRS1", "go", Login("mallory"))
    people = book.use(request.id, "DRS1", "go", ALICE_A)
    assert people == {"approved_by": f"bob ({ALICE_B})", "approval": str(request.id)}
    with pytest.raises(RefusedError, match="is used, not approved"):
        book.use(request.id, "DRS1", "go", ALICE_A)
    decided = [r.detail for r in book.store.audit("DRS1") if r.action == "approval.approved"]
    assert decided[0]["login"] == str(ALICE_B) and decided[0]["requester_login"] == str(ALICE_A)


def test_a_request_and_an_approval_expire(book: ApprovalBook) -> None:
    clock = book.clock
    assert isinstance(clock, ManualClock)
    late = book.request("DRS1", "parachute", "[PARACHUTE=01:19]", "alice", ALICE_A, ttl_s=60.0)
    clock.advance(60.0)
    assert book.open_requests() == []
    with pytest.raises(RefusedError, match=r"it is pending, expired .*, not pending"):
        book.decide(late.id, "bob", ALICE_B, approve=True)
    unused = book.request(
        "DRS1", "parachute", "[PARACHUTE=01:21]", "alice", ALICE_A, ttl_s=60.0, command="[PARACHUTE=01:21]"
    )
    book.decide(unused.id, "bob", ALICE_B, approve=True)
    clock.advance(61.0)
    with pytest.raises(RefusedError, match=r"is approved, expired"):
        book.use(unused.id, "DRS1", "parachute", ALICE_A)


def test_two_approvers_at_once_decide_it_once(book: ApprovalBook) -> None:
    request = book.request("DRS1", "go", "release DRS1", "alice", ALICE_A)
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
    request = book.request("DRS1", "parachute", message.text, "alice", ALICE_A, command=message.text)
    with pytest.raises(RefusedError, match="not approved"):
        authorize_mt(store, "DRS1", "alice", message, reports, approval=request.id, login=ALICE_A)
    book.decide(request.id, "bob", ALICE_B, approve=True)
    people = authorize_mt(store, "DRS1", "alice", message, reports, approval=request.id, login=ALICE_A)
    assert people["approved_by"] == f"bob ({ALICE_B})"
    authorised = audit_of(store, "mt.parachute")[-1]
    assert authorised["result"] == "authorised" and authorised["approval"] == str(request.id)


CHILD = "import sys; from console.commands.main import main; sys.exit(main(sys.argv[1:]))"


def test_an_approval_request_is_refused_for_a_command_the_rule_does_not_cover(tmp_path: Path) -> None:
    book = ApprovalBook(Store.open(tmp_path / "drs.sqlite"))
    with pytest.raises(ValueError, match="unknown hazardous action"):
        book.request("DRS1", "interval", "[INTERVAL=5]", "alice", ALICE_A)


def test_an_approval_is_void_once_the_capsules_state_changed_and_its_requester_may_cancel_one(
    book: ApprovalBook,
) -> None:
    """#23: a request stayed "pending" after the capsule it was for had been released."""
    take_over = "release-authority take-over: laptop1 died"
    request = book.request("DRS1", "authority", take_over, "alice", ALICE_A, command=take_over,
                           capsule_state="powered")  # fmt: skip
    book.decide(request.id, "bob", ALICE_B, approve=True)
    with pytest.raises(RefusedError, match="was given for release-authority take-over: laptop1 died, not"):
        book.use(request.id, "DRS1", "authority", ALICE_A, "release-authority take-over: other", "powered")
    with pytest.raises(RefusedError, match="was given while DRS1 was powered; it is now released"):
        book.use(request.id, "DRS1", "authority", ALICE_A, take_over, "released")
    assert book.get(request.id).state == "void" and book.open_requests() == []
    second = book.request(
        "DRS1", "parachute", "[PARACHUTE=01:19]", "alice", ALICE_A, command="[PARACHUTE=01:19]"
    )
    with pytest.raises(RefusedError, match="only they can cancel it"):
        book.cancel(second.id, "bob", ALICE_B)
    assert book.cancel(second.id, "alice", ALICE_A).state == "cancelled"
    with pytest.raises(RefusedError, match=r"it is cancelled \(cancelled by alice\), not pending"):
        book.decide(second.id, "bob", ALICE_B, approve=True)
    states = [(a.action, a.result) for a in book.store.audit("DRS1")]
    assert ("approval.void", "void") in states and ("approval.cancelled", "cancelled") in states


def test_an_approval_of_the_parachute_text_never_stands_for_an_in_flight_override(tmp_path: Path) -> None:
    """The approver saw "[PARACHUTE=…]", not that the landed gate would be overridden: the override and its
    reason are part of what is approved, so the approval of the text alone cannot drop it in flight."""
    store = seed(tmp_path, falling(recent(10.5)))
    reports = ReportStore(store).for_imei(IMEI)
    book = ApprovalBook(store)
    message = MtComposer().add("PARACHUTE", (1, 19)).build()
    plain = book.request("DRS1", "parachute", message.text, "alice", ALICE_A, command=message.text)
    book.decide(plain.id, "bob", ALICE_B, approve=True)
    override = "the chase team sees it on the ground"
    with pytest.raises(
        RefusedError, match=r"was given for \[PARACHUTE=01:19\], not .*OVERRIDE of the landed gate"
    ):
        authorize_mt(store, "DRS1", "alice", message, reports, approval=plain.id, login=ALICE_A,
                     override_landed=override)  # fmt: skip
    bound = approval_command(message, override)
    told = book.request("DRS1", "parachute", bound, "alice", ALICE_A, command=bound)
    assert "OVERRIDE of the landed gate: the chase team" in told.describe(utc_now()), (
        "what the approver reads"
    )
    book.decide(told.id, "bob", ALICE_B, approve=True)
    people = authorize_mt(store, "DRS1", "alice", message, reports, approval=told.id, login=ALICE_A,
                          override_landed=override)  # fmt: skip
    assert people["override_landed"] == override and people["approval"] == str(told.id)


def test_an_approval_for_one_parachute_time_never_sends_another(tmp_path: Path) -> None:
    store = seed(tmp_path, landed(recent(10.5)))
    reports = ReportStore(store).for_imei(IMEI)
    book = ApprovalBook(store)
    approved_text = MtComposer().add("PARACHUTE", (1, 19)).build()
    request = book.request(
        "DRS1", "parachute", approved_text.text, "alice", ALICE_A, command=approved_text.text
    )
    book.decide(request.id, "bob", ALICE_B, approve=True)
    other = MtComposer().add("PARACHUTE", (1, 21)).build()
    with pytest.raises(RefusedError, match=r"was given for \[PARACHUTE=01:19\], not \[PARACHUTE=01:21\]"):
        authorize_mt(store, "DRS1", "alice", other, reports, approval=request.id, login=ALICE_A)
    assert book.get(request.id).state == "approved", "still only good for 01:19"
    assert audit_of(store, "mt.parachute")[-1]["result"] == "refused"


def test_a_parachute_refused_after_its_approval_leaves_it_unspent_and_a_sent_one_spends_it_with_its_row(
    tmp_path: Path,
) -> None:
    """Issue #29: a refusal after ``approval.used`` must not be possible. The gateway's password is missing:
    refused before the approval is spent. With it, the approval is marked used in the transaction that
    records the MT (``CommandLifecycle.request``'s ``also``)."""
    from drs_link.errors import ConfigError
    from drs_link.ops.operations import SecondOperator
    from drs_link.sim.rockblock import SimulatedRockblock
    from tests.drs_link.iridium.test_parachute_gate import signed
    from tests.drs_link.ops.test_brief import parachute_ops

    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        ops, store = parachute_ops(tmp_path, gateway)
        for report in signed(landed(recent(10.5))):
            ReportStore(store).add(report.delivery)
        plan = ops.plan_parachute("DRS1", None, accept_midnight=True)
        message = MtComposer().add("PARACHUTE", (plan.hour, plan.minute)).build()
        book = ApprovalBook(store)
        second = SecondOperator(
            await_approval=True, on_pending=lambda r: book.decide(r.id, "JM", Login("jm"), approve=True)
        )
        ops.environ = {}
        with pytest.raises(ConfigError):
            ops.send_mt("DRS1", message, "DRS1", second, queue_by=plan.queue_by)
        assert book.get(1).state == "approved" and gateway.requests == []
        assert not [a for a in store.audit() if a.action == "approval.used"]
        ops.environ = {"DRS_TEST_RB": "pw"}
        ops.send_mt("DRS1", message, "DRS1", second, queue_by=plan.queue_by)
        assert book.get(2).state == "used" and len(gateway.requests) == 1
        assert [a.action for a in store.audit()].count("approval.used") == 1

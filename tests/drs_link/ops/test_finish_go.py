"""Finishing an unverified Go (issue #29 Why-3): only the holder of its ARM window, within 60 s of the
failed attempt, with its approval still valid under the rule; the release time is the verified Go's.

The real OperatorOps, state machine, ARM windows and approvals on a real store; the Pi is the in-process
one of the state-machine tests (its Go's outcome set per attempt), and every wait is the manual clock's.
"""

from __future__ import annotations

from pathlib import Path

import pytest

from drs_link.config import parse_config
from drs_link.errors import LinkError, RefusedError
from drs_link.link.backends import GoResult
from drs_link.ops.approval import Approval, ApprovalBook, Login
from drs_link.ops.arming import FINISH_GO_S
from drs_link.ops.capsule import ReleaseState
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.ops_state import SecondOperator
from drs_link.store import Store, iso_utc
from tests.clock import ManualClock
from tests.drs_link.ops.test_arming import T0, go_report
from tests.drs_link.ops.test_release_state_machine import InProcessPi

UNVERIFIED = GoResult(False, True, False, None, "")
VERIFIED = GoResult(True, True, True, None, "Dropping in 30 seconds!\nShutting down...\n")
HOLDER = "el@ground drs"


def operations(
    store: Store,
    clock: ManualClock,
    pi: InProcessPi,
    holder: str = HOLDER,
    rule: bool = False,
    window_s: float = 60,
) -> OperatorOps:
    config = parse_config({
        "operator": {"name": "EL"},
        "console": {"require_second_operator": rule, "arm_window_s": window_s},
        "capsule": [{"name": "DRS1", "host": "127.0.0.1", "port": 9}],
    })  # fmt: skip
    ops = OperatorOps(config, store, clock=clock, sleep=clock.advance, holder=holder, login=Login("el"))
    ops.state.ops("DRS1").machine.backend = pi  # type: ignore[assignment]
    return ops


def jm_approves(store: Store, clock: ManualClock) -> SecondOperator:
    """Another login approves each request as soon as it is made."""

    def approve(request: Approval) -> None:
        ApprovalBook(store, clock).decide(request.id, "JM", Login("jm"), approve=True)

    return SecondOperator(await_approval=True, on_pending=approve)


def unverified_go(ops: OperatorOps, clock: ManualClock, pi: InProcessPi, second: SecondOperator) -> None:
    """Power on, ARM, FIRE whose link drops before GoGoGo is confirmed: go-sent-unverified."""
    machine = ops.state.ops("DRS1").machine
    machine.power_on(confirmed=True)
    assert machine.wait_for_microcontroller().waiting_for_go
    ops.release.arm("DRS1", go_report(clock))
    pi.go_outcome = UNVERIFIED
    with pytest.raises(LinkError, match="may or may not"):
        ops.release.fire("DRS1", "DRS1", lambda: go_report(clock), second)
    assert machine.record().state is ReleaseState.GO_SENT


@pytest.fixture
def clock() -> ManualClock:
    return ManualClock(T0)


@pytest.fixture
def pi(clock: ManualClock) -> InProcessPi:
    return InProcessPi(clock)


@pytest.fixture
def store(tmp_path: Path) -> Store:
    return Store.open(tmp_path / "drs.sqlite")


def test_the_holder_finishes_within_60_s_and_the_release_time_is_the_verified_gos(
    store: Store, clock: ManualClock, pi: InProcessPi
) -> None:
    ops = operations(store, clock, pi)
    unverified_go(ops, clock, pi, SecondOperator(waiver="alone at the launch site"))
    failed_at = ops.state.ops("DRS1").machine.record().go_at
    clock.advance(23)
    pi.go_outcome = VERIFIED
    ops.release.finish_go("DRS1", "DRS1")
    record = ops.state.ops("DRS1").machine.record()
    assert record.state is ReleaseState.RELEASED and pi.calls.count("go") == 2
    assert record.go_at == clock() and record.failed_go_at == failed_at
    finishing = [a.detail for a in store.audit("DRS1") if a.action == "go" and a.result == "finishing"]
    assert finishing == [{"state": "go-sent-unverified", "failed_go_at": iso_utc(failed_at), "window": 1}]  # type: ignore[arg-type]
    assert ops.state.ops("DRS1").arming.status().state.value == "fired"


def test_a_finish_later_than_60_s_after_the_failed_attempt_is_refused(
    store: Store, clock: ManualClock, pi: InProcessPi
) -> None:
    ops = operations(store, clock, pi)
    unverified_go(ops, clock, pi, SecondOperator(waiver="alone at the launch site"))
    clock.advance(FINISH_GO_S + 1)
    pi.go_outcome = VERIFIED
    with pytest.raises(RefusedError, match=r"finish refused: the failed attempt was 61 s ago \(limit 60 s\); "
                                            "a fresh ARM and FIRE under every rule is needed"):  # fmt: skip
        ops.release.finish_go("DRS1", "DRS1")
    assert pi.calls.count("go") == 1 and ops.release.release_state("DRS1") is ReleaseState.GO_SENT
    assert [a.result for a in store.audit("DRS1") if a.action == "go"][-1] == "refused"


def test_another_holder_cannot_finish_the_go_even_at_once(
    store: Store, clock: ManualClock, pi: InProcessPi
) -> None:
    ops = operations(store, clock, pi)
    unverified_go(ops, clock, pi, SecondOperator(waiver="alone at the launch site"))
    other = operations(store, clock, pi, holder="jm@other drs")
    clock.advance(5)
    pi.go_outcome = VERIFIED
    with pytest.raises(
        RefusedError, match=r"only the holder of ARM window #1 \(EL at .*\) may finish its Go"
    ):
        other.release.finish_go("DRS1", "DRS1")
    assert pi.calls.count("go") == 1


def test_under_the_rule_the_approval_must_still_be_valid(
    store: Store, clock: ManualClock, pi: InProcessPi
) -> None:
    """The Go approval ends with its ARM window (30 s here); 35 s after the failed attempt (inside the 60 s)
    its approval has expired: refused, though the Pi would have taken it."""
    ops = operations(store, clock, pi, rule=True, window_s=30)
    unverified_go(ops, clock, pi, jm_approves(store, clock))
    clock.advance(35)
    pi.go_outcome = VERIFIED
    with pytest.raises(RefusedError, match=r"finish refused: its approval #1 expired at 12:00:\d\dZ"):
        ops.release.finish_go("DRS1", "DRS1")
    assert pi.calls.count("go") == 1


def test_under_the_rule_a_finish_within_the_approvals_life_goes_ahead(
    store: Store, clock: ManualClock, pi: InProcessPi
) -> None:
    ops = operations(store, clock, pi, rule=True)
    unverified_go(ops, clock, pi, jm_approves(store, clock))
    clock.advance(10)
    pi.go_outcome = VERIFIED
    ops.release.finish_go("DRS1", "DRS1")
    assert ops.release.release_state("DRS1") is ReleaseState.RELEASED
    finishing = [a.detail for a in store.audit("DRS1") if a.action == "go" and a.result == "finishing"]
    assert finishing[0] is not None and finishing[0]["approval"] == 1


def test_after_a_refused_late_finish_a_poll_that_finds_the_pi_up_lets_a_fresh_arm_and_fire_release(
    store: Store, clock: ManualClock, pi: InProcessPi
) -> None:
    """A Pi still answering 60 s after the failed attempt was neither shut down by the Go script nor
    dropped with the capsule: the Go was never taken, the FIRING window closes, and only a fresh ARM and
    FIRE releases (it was a dead end: ARM refused "the capsule is firing", go/no-go said released)."""
    ops = operations(store, clock, pi)
    alone = SecondOperator(waiver="alone at the launch site")
    unverified_go(ops, clock, pi, alone)
    failed_at = ops.state.ops("DRS1").machine.record().go_at
    clock.advance(FINISH_GO_S + 1)
    with pytest.raises(RefusedError, match="once a poll finds the Pi still up 60 s after the attempt"):
        ops.release.finish_go("DRS1", "DRS1")
    with pytest.raises(RefusedError, match="ARM refused: the capsule is firing"):
        ops.release.arm("DRS1", go_report(clock))
    ops.links.poll("DRS1")
    record = ops.state.ops("DRS1").machine.record()
    assert record.state is ReleaseState.POWERED and record.go_at is None and record.failed_go_at == failed_at
    assert record.note == "Go of 12:00:23Z never taken: the Pi still answered 61 s later"
    status = ops.state.ops("DRS1").arming.status()
    assert status.state.value == "disarmed" and status.last_disarm_reason == record.note
    assert [a.result for a in store.audit("DRS1") if a.action == "go"][-1] == "not taken"
    with pytest.raises(RefusedError, match="FIRE refused: not armed"):
        ops.release.fire("DRS1", "DRS1", lambda: go_report(clock), alone)
    assert pi.calls.count("go") == 1
    ops.release.arm("DRS1", go_report(clock))
    pi.go_outcome = VERIFIED
    ops.release.fire("DRS1", "DRS1", lambda: go_report(clock), alone)
    record = ops.state.ops("DRS1").machine.record()
    assert record.state is ReleaseState.RELEASED and pi.calls.count("go") == 2
    assert record.go_at == clock() and record.failed_go_at == failed_at


def test_a_pi_that_does_not_answer_leaves_the_go_unverified(
    store: Store, clock: ManualClock, pi: InProcessPi
) -> None:
    ops = operations(store, clock, pi)
    unverified_go(ops, clock, pi, SecondOperator(waiver="alone at the launch site"))
    clock.advance(FINISH_GO_S + 30)
    pi.serial_error = LinkError("DRS1: connection timed out")
    ops.links.poll("DRS1")
    assert ops.release.release_state("DRS1") is ReleaseState.GO_SENT
    assert ops.state.ops("DRS1").arming.status().state.value == "firing"


def test_within_the_finish_time_a_poll_leaves_the_unverified_go_to_its_holder(
    store: Store, clock: ManualClock, pi: InProcessPi
) -> None:
    """The Go script shuts the Pi down only ~6 s after GoGoGo: a Pi that answers early proves nothing."""
    ops = operations(store, clock, pi)
    unverified_go(ops, clock, pi, SecondOperator(waiver="alone at the launch site"))
    reads = pi.calls.count("read_serial 120")
    clock.advance(FINISH_GO_S - 1)
    ops.links.poll("DRS1")
    assert ops.release.release_state("DRS1") is ReleaseState.GO_SENT
    assert pi.calls.count("read_serial 120") == reads

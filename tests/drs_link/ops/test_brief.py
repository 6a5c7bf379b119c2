"""The approver sees what they approve (issue #29 Why-6): one brief, built by the operations layer when
the request is made and stored with it, printed the same by `drs approve` and the console.

Go: the exact command, every go/no-go verdict of the poll its ARM window was opened on, each waiver with
its reason and author. PARACHUTE: the exact MT text and the landed evidence, or the override's reason.
"""

from __future__ import annotations

from collections.abc import Iterator
from pathlib import Path

import pytest

from drs_link.config import parse_config
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import ReportStore
from drs_link.ops.approval import Approval, ApprovalBook, Login
from drs_link.ops.gonogo import evaluate
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.ops_state import SecondOperator
from drs_link.ops.staleness import Reading
from drs_link.sim.rockblock import SimulatedRockblock
from drs_link.store import Store
from tests.clock import ManualClock
from tests.console.commands.test_cli_iridium import run, write_config
from tests.drs_link.iridium.helpers import IMEI
from tests.drs_link.iridium.test_parachute_gate import falling, landed, recent, signed
from tests.drs_link.ops.test_arming import T0, inputs
from tests.drs_link.ops.test_finish_go import VERIFIED, operations
from tests.drs_link.ops.test_release_state_machine import InProcessPi

WAIVER = "no fix under the balloon's shadow, dropping anyway"


def approving(store: Store, seen: list[Approval], clock: ManualClock | None = None) -> SecondOperator:
    """Another login reads the request (kept in ``seen``) and approves it."""

    def approve(request: Approval) -> None:
        seen.append(request)
        ApprovalBook(store, clock).decide(request.id, "JM", Login("jm"), approve=True)

    return SecondOperator(await_approval=True, on_pending=approve)


def test_a_go_request_shows_the_command_every_verdict_and_every_waiver_with_reason_and_author(
    tmp_path: Path,
) -> None:
    clock = ManualClock(T0)
    pi = InProcessPi(clock)
    store = Store.open(tmp_path / "drs.sqlite")
    ops = operations(store, clock, pi, rule=True)
    machine = ops.state.ops("DRS1").machine
    machine.power_on(confirmed=True)
    assert machine.wait_for_microcontroller().waiting_for_go
    ops.release.waive("DRS1", "gnss", WAIVER)

    def poll():  # type: ignore[no-untyped-def]
        no_fix = inputs(clock(), gnss_fix=Reading(False, clock(), 10.0))
        return evaluate("DRS1", no_fix, clock(), ops.state.ops("DRS1").waivers.waivers)

    ops.release.arm("DRS1", poll())
    seen: list[Approval] = []
    pi.go_outcome = VERIFIED
    ops.release.fire("DRS1", "DRS1", poll, approving(store, seen, clock))
    [request] = seen
    lines = request.for_approver(clock())
    assert lines[1] == "  command: Go: release DRS1 in ARM window #1"
    assert "  go/no-go:" in lines
    for title in ("SSH link up", "Power-on done", "Microcontroller talking", "Storage sync complete",
                  "Prediction fresh", "Gateway configured"):  # fmt: skip
        assert any(line.startswith("    GO      ") and title in line for line in lines), title
    assert f"    WAIVED  GNSS fix fresh: no fix; waived by EL: {WAIVER}" in lines
    assert f"  waiver: gnss waived by EL: {WAIVER}" in lines
    assert ApprovalBook(store, clock).get(request.id).for_approver(clock())[1:] == lines[1:], "stored"


@pytest.fixture
def gateway() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as simulated:
        yield simulated


def parachute_ops(tmp_path: Path, gateway: SimulatedRockblock) -> tuple[OperatorOps, Store]:
    config = parse_config({
        "operator": {"name": "EL"},
        "data": {"dir": str(tmp_path / "data")},
        "rockblock": {"mt_url": gateway.url, "username": "ops", "password_env": "DRS_TEST_RB"},
        "capsule": [{"name": "DRS1", "host": "127.0.0.1", "imei": IMEI, "rockblock_serial": 11800}],
    })  # fmt: skip
    store = Store.open(config.store_path)
    return OperatorOps(config, store, environ={"DRS_TEST_RB": "pw"}, login=Login("el")), store


def test_a_parachute_request_shows_the_text_and_the_landed_evidence(
    tmp_path: Path, gateway: SimulatedRockblock, capsys: pytest.CaptureFixture[str]
) -> None:
    ops, store = parachute_ops(tmp_path, gateway)
    for report in signed(landed(recent(10.5))):
        ReportStore(store).add(report.delivery)
    plan = ops.iridium.plan_parachute("DRS1", None, accept_midnight=True)
    message = MtComposer().add("PARACHUTE", (plan.hour, plan.minute)).build()
    seen: list[Approval] = []
    ops.iridium.send_mt("DRS1", message, "DRS1", approving(store, seen), queue_by=plan.queue_by)
    [request] = seen
    lines = request.for_approver(ops.state.clock())
    assert lines[1] == f"  command: {message.text}"
    assert lines[2].startswith("  landed evidence: landed ") and "JWT-verified" in lines[2]
    assert not any("OVERRIDE" in line for line in lines)
    assert len(gateway.requests) == 1


def test_an_overriding_parachute_request_shows_the_override_reason_and_what_it_overrides(
    tmp_path: Path, gateway: SimulatedRockblock, capsys: pytest.CaptureFixture[str]
) -> None:
    """And `drs approve`, from the approver's own process, prints exactly the same lines."""
    ops, store = parachute_ops(tmp_path, gateway)
    for report in falling(recent(9)):
        ReportStore(store).add(report.delivery)
    message = MtComposer().add("PARACHUTE", (1, 19)).build()
    reason = "chase team sees it on the ground; GNSS frozen"
    book = ApprovalBook(store)
    printed: list[str] = []

    def listed(request: Approval) -> None:
        config = write_config(tmp_path, gateway.url)
        assert run(config, "approve") == 0
        printed.extend(capsys.readouterr().out.splitlines())
        book.decide(request.id, "JM", Login("jm"), approve=False, reason="not yet")

    second = SecondOperator(await_approval=True, on_pending=listed)
    with pytest.raises(Exception, match="rejected"):
        ops.iridium.send_mt("DRS1", message, "DRS1", second, override_landed=reason)
    request = book.get(1)
    lines = request.for_approver(book.clock())
    assert f"  OVERRIDE of the landed gate, reason: {reason}" in lines
    assert any(line.startswith("  landed evidence: NOT LANDED: last fix") for line in lines)
    assert printed[1:] == lines[1:], "drs approve prints the brief the operations layer built"
    assert gateway.requests == []

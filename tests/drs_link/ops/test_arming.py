"""ARM then FIRE, enforced in the domain layer on top of the release state machine's tokens."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from drs_link.config import CapsuleConfig, parse_config
from drs_link.errors import RefusedError
from drs_link.link.backends.stock import StockBackend
from drs_link.link.ssh import CapsuleLink
from drs_link.ops.approval import ApprovalBook, Login, window_command
from drs_link.ops.arming import FIRING_STALE_S, ArmingController, ArmState, check_second_operator
from drs_link.ops.capsule import ReleaseState, ReleaseStateMachine
from drs_link.ops.gonogo import (
    WAIVER_REASON_MAX,
    GoNoGoInputs,
    GoNoGoReport,
    PredictionCheck,
    WaiverBook,
    evaluate,
)
from drs_link.ops.staleness import Reading
from drs_link.sim import CapsuleSimulator
from drs_link.store import Store
from tests.clock import ManualClock

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)


def inputs(now: datetime, **changes: object) -> GoNoGoInputs:
    ring = ((-64.1, -31.1), (-63.9, -31.1), (-63.9, -30.9), (-64.1, -30.9))
    base = GoNoGoInputs(
        link_up=Reading(True, now, 10.0),
        microcontroller_waiting=Reading(True, now, 10.0),
        gnss_fix=Reading(True, now, 10.0),
        sync_fraction=Reading(1.0, now, 60.0),
        prediction=Reading(PredictionCheck(-31.0, -64.0, ring), now, 120.0),
        gateway_credentials=Reading(True, now, 600.0),
        powered=True,
    )
    return replace(base, **changes)  # type: ignore[arg-type]


def go_report(clock: ManualClock, **changes: object) -> GoNoGoReport:
    return evaluate("DRS1", inputs(clock(), **changes), clock())


@pytest.fixture
def store(tmp_path: Path) -> Store:
    return Store.open(tmp_path / "drs.sqlite")


def offline_machine(store: Store, clock: ManualClock, name: str = "DRS1") -> ReleaseStateMachine:
    """The real state machine for a capsule nobody is connected to (the tests that never reach Go)."""
    capsule = parse_config({"capsule": [{"name": name, "host": "127.0.0.1", "port": 9}]}).capsules[0]
    return ReleaseStateMachine(store, capsule, StockBackend(capsule, CapsuleLink(capsule)), "EL", clock=clock)


def controller(store: Store, clock: ManualClock, name: str = "DRS1", **kwargs: object) -> ArmingController:
    return ArmingController(store, offline_machine(store, clock, name), "EL", clock=clock, **kwargs)  # type: ignore[arg-type]


def test_fire_is_refused_without_arm_and_the_refusal_is_audited(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock)
    with pytest.raises(RefusedError, match="not armed"):
        arming.fire("DRS1", go_report(clock))
    assert [(a.action, a.result) for a in store.audit("DRS1")] == [("fire", "refused")]


def test_arm_is_refused_on_no_go_with_the_reasons(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock)
    with pytest.raises(RefusedError, match="GNSS fix fresh: no fix"):
        arming.arm(go_report(clock, gnss_fix=Reading(False, T0, 10.0)))
    assert arming.status().state is ArmState.DISARMED


def test_stale_data_blocks_arm(store: Store) -> None:
    clock = ManualClock(T0)
    stale = inputs(T0)
    clock.advance(30)
    with pytest.raises(RefusedError, match="STALE"):
        controller(store, clock).arm(evaluate("DRS1", stale, clock()))


def test_arm_opens_a_window_that_counts_down_and_expires(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock, arm_window_s=45.0)
    status = arming.arm(go_report(clock))
    assert status.armed and status.remaining_s == 45.0
    clock.advance(30)
    assert arming.status().remaining_s == 15.0
    clock.advance(15)
    status = arming.status()
    assert status.state is ArmState.DISARMED
    assert (status.last_disarm_reason or "").startswith("ARM window expired at ")
    with pytest.raises(RefusedError, match="FIRE refused: not armed: ARM window expired at [0-9:]+Z"):
        arming.fire("DRS1", go_report(clock))


def test_link_loss_disarms(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock)
    arming.arm(go_report(clock))
    assert arming.link_lost().last_disarm_reason == "link lost"
    assert ("disarm", "link lost") in [(a.action, a.result) for a in store.audit("DRS1")]


def test_a_changed_verdict_or_a_no_go_poll_disarms(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock)
    partial = {"sync_fraction": Reading(0.9, T0, 60.0)}
    book = WaiverBook(store, "DRS1", clock)
    book.grant("sync", "EL", "rest is on the ground copy")
    arming.arm(evaluate("DRS1", inputs(clock(), **partial), clock(), book.waivers))
    clock.advance(2)
    assert arming.observe(evaluate("DRS1", inputs(clock(), **partial), clock(), book.waivers)).armed
    status = arming.observe(evaluate("DRS1", inputs(clock()), clock(), book.waivers))
    assert status.state is ArmState.DISARMED and status.last_disarm_reason == "inputs changed since ARM"
    arming.arm(go_report(clock))
    clock.advance(25)
    status = arming.observe(evaluate("DRS1", inputs(T0 + timedelta(seconds=2)), clock()))
    assert status.state is ArmState.DISARMED and "STALE" in (status.last_disarm_reason or "")


def test_a_wrong_capsule_name_is_refused_and_nothing_is_sent(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock)
    arming.arm(go_report(clock))
    with pytest.raises(RefusedError, match="'DRS2' does not name 'DRS1'"):
        arming.fire("DRS2", go_report(clock))
    assert arming.status().armed
    assert store.audit("DRS1")[-1].detail == {"reason": "wrong capsule name typed", "typed": "DRS2"}


def test_a_single_operator_waiver_longer_than_the_stated_cap_is_refused_with_its_length() -> None:
    """#23: a 3,000-character reason pushed go/no-go and the checklist off the screen."""
    assert check_second_operator("EL", None, "x" * WAIVER_REASON_MAX, required=False)
    with pytest.raises(RefusedError, match=rf"at most {WAIVER_REASON_MAX} characters \(this one has 3000\)"):
        check_second_operator("EL", None, "x" * 3000, required=False)


def test_without_the_rule_a_typed_second_operator_must_be_another_person_on_the_crew_list() -> None:
    crew = ("EL", "MS")
    with pytest.raises(RefusedError, match="different person"):
        check_second_operator("EL", " el ", None, required=False, crew=crew)
    with pytest.raises(RefusedError, match=r"'Bob' is not in the crew list \(\[console\] crew: EL, MS\)"):
        check_second_operator("EL", "Bob", None, required=False, crew=crew)
    with pytest.raises(RefusedError, match="crew: none configured"):
        check_second_operator("EL", "MS", None, required=False)
    assert check_second_operator("EL", "ms", None, required=False, crew=crew) == {"second_operator": "ms"}
    assert check_second_operator("EL", None, None, required=False) == {}
    assert check_second_operator("EL", None, "alone", required=False) == {"single_operator_waiver": "alone"}


@pytest.mark.parametrize(
    ("second", "waiver", "words"),
    [("MS", None, "a typed second operator is not accepted"), (None, "alone", "a single-operator waiver is not "
     "accepted"), (None, None, "a second login's approval is needed")],
)  # fmt: skip
def test_with_the_rule_required_only_another_logins_approval_counts(
    second: str | None, waiver: str | None, words: str
) -> None:
    """#23: `--second-operator Bob` and `--single-operator-waiver alone` were accepted with the rule on."""
    with pytest.raises(RefusedError, match=words) as refused:
        check_second_operator("EL", second, waiver, required=True, crew=("EL", "MS"))
    assert "drs approve ID" in str(refused.value)


def test_fire_with_a_required_second_operator_refuses_a_typed_name(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock, require_second_operator=True)
    arming.arm(go_report(clock))
    with pytest.raises(RefusedError, match="typed second operator is not accepted"):
        arming.fire("DRS1", go_report(clock), second_operator="MS")
    assert arming.status().armed


def test_fire_spends_only_an_approval_another_login_gave_for_go(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock, require_second_operator=True)
    book = ApprovalBook(store, clock)
    request = book.request("DRS1", "go", "release DRS1", "EL", Login("el"), command=window_command(1))
    arming.arm(go_report(clock))
    with pytest.raises(RefusedError, match=r"FIRE refused: approval #1 is pending, not approved"):
        arming.fire("DRS1", go_report(clock), approval=request.id, login=Login("el"))
    book.decide(request.id, "JM", Login("jm"), approve=True)
    with pytest.raises(RefusedError, match=r"FIRE refused: approval #1 was requested by el, not by jm"):
        arming.fire("DRS1", go_report(clock), approval=request.id, login=Login("jm"))
    assert [a.result for a in store.audit("DRS1") if a.action == "fire"] == ["refused", "refused"]


@pytest.mark.slow
@pytest.mark.parametrize("second", ["waiver", "approval"])
def test_armed_fire_releases_the_simulated_capsule_through_the_state_machine_tokens(
    make_sim: Callable[..., CapsuleSimulator],
    sim_config: Callable[..., CapsuleConfig],
    store: Store,
    second: str,
) -> None:
    sim = make_sim()
    config = sim_config(sim)
    link = CapsuleLink(config)
    machine = ReleaseStateMachine(
        store, config, StockBackend(config, link), "EL", clock=sim.clock.now, sleep=sim.clock.sleep
    )
    machine.power_on(confirmed=True)
    assert machine.wait_for_microcontroller().waiting_for_go
    arming = ArmingController(store, machine, "EL", clock=sim.clock.now, arm_window_s=600.0)
    people: dict[str, object] = {"single_operator_waiver": "test drop, one person"}
    if second == "approval":  # the second operator approved from their own login
        book = ApprovalBook(store, sim.clock.now)
        request = book.request("DRS1", "go", "release DRS1", "EL", Login("el"), command=window_command(1))
        book.decide(request.id, "JM", Login("jm"), approve=True)
        people = {"approval": request.id, "login": Login("el")}
    report = evaluate("DRS1", inputs(sim.clock.now()), sim.clock.now())
    arming.arm(report)
    record = arming.fire("DRS1", report, **people)  # type: ignore[arg-type]
    assert record.state is ReleaseState.RELEASED and sim.firmware.go_at is not None
    assert arming.status().state is ArmState.FIRED
    actions = [(a.action, a.result) for a in store.audit("DRS1") if not a.action.startswith("approval.")]
    assert actions[-5:] == [
        ("arm", "armed"),
        ("fire", "authorised"),
        ("go-confirmation", "minted"),
        ("go", "sending"),
        ("go", "released, Pi shut down"),
    ]
    with pytest.raises(RefusedError, match="fired"):
        arming.arm(report)
    machine.reset("DRS1")
    assert arming.after_reset().last_disarm_reason == "capsule reset after recovery"
    link.close()


def test_a_late_approval_never_fires_in_a_later_arm_window(store: Store) -> None:
    """#23: ARM, ask another login, let the window expire, ARM again, approve: it fired the capsule."""
    clock = ManualClock(T0)
    arming = controller(store, clock, arm_window_s=30.0, require_second_operator=True)
    book = ApprovalBook(store, clock)
    first = arming.arm(go_report(clock)).window
    assert first is not None
    request = book.request("DRS1", "go", "release DRS1", "EL", Login("el"), command=window_command(first.id),
                           window_id=first.id, deadline=first.until_utc)  # fmt: skip
    assert request.expires_utc == first.until_utc, "the deadline is the window's end"
    clock.advance(31)
    second = arming.arm(go_report(clock)).window
    assert second is not None and second.id != first.id
    assert book.open_requests() == [], "drs approve lists only what can still be used"
    with pytest.raises(RefusedError, match=r"it is void \(ARM window #1 closed: ARM window expired at"):
        book.decide(request.id, "JM", Login("jm"), approve=True)
    with pytest.raises(
        RefusedError, match="FIRE refused: approval #1 was given for ARM window #1, not ARM window #2"
    ):
        arming.fire("DRS1", go_report(clock), approval=request.id, login=Login("el"))
    assert arming.status().armed, "the refusal leaves the new window as it was"
    actions = [(a.action, a.result) for a in store.audit("DRS1")]
    assert ("approval.void", "void") in actions and ("fire", "refused") in actions


def test_an_approval_for_one_window_cannot_be_spent_in_another(store: Store) -> None:
    clock = ManualClock(T0)
    arming = controller(store, clock, require_second_operator=True)
    book = ApprovalBook(store, clock)
    first = arming.arm(go_report(clock)).window
    assert first is not None
    request = book.request("DRS1", "go", "release DRS1", "EL", Login("el"), command=window_command(first.id),
                           window_id=first.id, deadline=first.until_utc)  # fmt: skip
    book.decide(request.id, "JM", Login("jm"), approve=True)
    arming.disarm("operator disarmed", any_holder=True)
    assert book.get(request.id).state == "void"
    arming.arm(go_report(clock))
    with pytest.raises(RefusedError, match="was given for ARM window #1, not ARM window #2"):
        arming.fire("DRS1", go_report(clock), approval=request.id, login=Login("el"))


def test_one_arm_per_capsule_the_second_holder_is_refused_and_told_who_holds_it(store: Store) -> None:
    clock = ManualClock(T0)
    console1 = controller(store, clock, holder="el@laptop1 pid 1")
    console2 = controller(store, clock, holder="jm@laptop2 pid 2")
    console1.arm(go_report(clock))
    with pytest.raises(
        RefusedError, match=r"ARM window #1 is held by EL at .* until 12:01:00Z; one ARM per capsule"
    ):
        console2.arm(go_report(clock))
    assert console2.status().armed and not console2.status().mine
    with pytest.raises(RefusedError, match="the ARM window is held by EL at .*, not this console"):
        console2.fire("DRS1", go_report(clock), single_operator_waiver="alone")
    console2.observe(go_report(clock, gnss_fix=Reading(False, T0, 10.0)))
    assert console1.status().armed, "another console's poll never disarms a window it does not hold"
    clock.advance(61)
    assert console2.arm(go_report(clock)).mine, "once the window ran out, another console may ARM"


# Attacks of a flight-safety review: each tries to make FIRE happen when it must not.


def approved_go(store: Store, clock: ManualClock, window_id: int | None, capsule: str = "DRS1") -> int:
    """A Go request of login ``el``, bound to ``window_id`` (None: unbound, as rows made before the binding),
    approved by another login."""
    book = ApprovalBook(store, clock)
    bound = {"command": window_command(window_id), "window_id": window_id} if window_id is not None else {}
    request = book.request(capsule, "go", f"release {capsule}", "EL", Login("el"), **bound)  # type: ignore[arg-type]
    book.decide(request.id, "JM", Login("jm"), approve=True)
    return request.id


def test_an_approval_bound_to_no_window_never_fires(store: Store) -> None:
    """A request from before the binding (NULL command) could be spent in any window within its TTL."""
    clock = ManualClock(T0)
    arming = controller(store, clock, require_second_operator=True)
    unbound = approved_go(store, clock, None)
    arming.arm(go_report(clock))
    with pytest.raises(
        RefusedError, match=r"FIRE refused: approval #1 is bound to no command .* ask for a new one"
    ):
        arming.fire("DRS1", go_report(clock), approval=unbound, login=Login("el"))
    assert arming.status().armed and ApprovalBook(store, clock).get(unbound).state == "approved"


def test_an_approval_for_another_capsule_never_fires_this_one(store: Store) -> None:
    clock = ManualClock(T0)
    other = controller(store, clock, "DRS2")
    arming = controller(store, clock, require_second_operator=True)
    window2 = other.arm(evaluate("DRS2", inputs(clock()), clock())).window
    assert window2 is not None
    theirs = approved_go(store, clock, window2.id, "DRS2")
    window1 = arming.arm(go_report(clock)).window
    assert window1 is not None
    with pytest.raises(RefusedError, match="approval #1 was given for DRS2 Go .release., not DRS1 Go"):
        arming.fire("DRS1", go_report(clock), approval=theirs, login=Login("el"))


def test_a_window_that_runs_out_between_the_checks_and_the_submit_leaves_the_approval_unspent(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The window runs out between the approval's checks and the submit (a slow disk, a paused process):
    the transaction that marks the approval used and moves the window to FIRING reads the clock again and
    refuses both, so the approval is not spent on a FIRE that was refused (issue #29: never a refusal
    after ``approval.used``)."""
    clock = ManualClock(T0)
    arming = controller(store, clock, arm_window_s=30.0, require_second_operator=True)
    window = arming.arm(go_report(clock)).window
    assert window is not None
    approval = approved_go(store, clock, window.id)
    check = ApprovalBook.check

    def slow_check(book: ApprovalBook, *args: object, **kwargs: object) -> object:
        request = check(book, *args, **kwargs)  # type: ignore[arg-type]
        clock.advance(31)
        return request

    monkeypatch.setattr(ApprovalBook, "check", slow_check)
    with pytest.raises(RefusedError, match=r"FIRE refused: approval #1 is void \(ARM window #1 closed\)"):
        arming.fire("DRS1", go_report(clock), approval=approval, login=Login("el"))
    assert not [
        a for a in store.audit("DRS1") if a.action in ("approval.used", "fire") and a.result != "refused"
    ]
    assert arming.status().state is ArmState.DISARMED


def test_the_approval_is_marked_used_in_the_transaction_that_starts_firing_and_never_without_it(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """The order, pinned: every check, then one transaction that marks the approval used and moves the window
    to FIRING. When the window's compare-and-set loses (another process closed it inside that instant),
    the mark used rolls back with it; when it wins, both are in the store before anything is audited."""
    import drs_link.ops.arming as arming_module

    clock = ManualClock(T0)
    arming = controller(store, clock, require_second_operator=True)
    window = arming.arm(go_report(clock)).window
    assert window is not None
    approval = approved_go(store, clock, window.id)
    seen: list[str] = []
    start = arming_module.start_firing_in

    def lost(conn: object, *args: object) -> bool:
        [row] = conn.execute("SELECT state FROM approval WHERE id = ?", (approval,)).fetchall()  # type: ignore[attr-defined]
        seen.append(str(row["state"]))
        return False

    monkeypatch.setattr(arming_module, "start_firing_in", lost)
    with pytest.raises(RefusedError, match=r"FIRE refused: ARM window #1 closed meanwhile"):
        arming.fire("DRS1", go_report(clock), approval=approval, login=Login("el"))
    assert seen == ["used"], "marked used first, inside the transaction"
    assert ApprovalBook(store, clock).get(approval).state == "approved", "rolled back with the lost FIRING"
    assert not [a for a in store.audit("DRS1") if a.action == "approval.used"]

    def won(conn: object, *args: object) -> bool:
        [row] = conn.execute("SELECT state FROM approval WHERE id = ?", (approval,)).fetchall()  # type: ignore[attr-defined]
        seen.append(str(row["state"]))
        return start(conn, *args)  # type: ignore[arg-type]

    monkeypatch.setattr(arming_module, "start_firing_in", won)
    with pytest.raises(RefusedError, match="power-on has not succeeded"):  # the offline machine: no Go
        arming.fire("DRS1", go_report(clock), approval=approval, login=Login("el"))
    assert seen[-1] == "used" and ApprovalBook(store, clock).get(approval).state == "used"
    actions = [a.action for a in store.audit("DRS1")]
    assert actions.index("approval.used") < actions.index("go-confirmation"), "spent, then the Go ran"


def test_two_processes_arming_at_once_open_one_window(tmp_path: Path) -> None:
    """Each console has its own connection to the store; the compare-and-set lets exactly one win."""
    import threading

    clock = ManualClock(T0)
    path = tmp_path / "shared.sqlite"
    consoles = [controller(Store.open(path), clock, holder=f"op{i}@laptop{i} pid {i}") for i in range(4)]
    start = threading.Barrier(len(consoles))
    outcomes: list[str] = []

    def arm(console: ArmingController) -> None:
        start.wait()
        try:
            outcomes.append("armed" if console.arm(go_report(clock)).mine else "lost")
        except RefusedError as exc:
            outcomes.append(str(exc))

    threads = [threading.Thread(target=arm, args=(console,)) for console in consoles]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    assert outcomes.count("armed") == 1, outcomes
    assert all("one ARM per capsule" in o for o in outcomes if o != "armed"), outcomes
    rows = Store.open(path).query("SELECT state FROM arm_window")
    assert [row["state"] for row in rows] == ["armed"]


def test_a_crashed_consoles_arm_window_blocks_the_capsule_only_until_it_runs_out(store: Store) -> None:
    clock = ManualClock(T0)
    crashed = controller(store, clock, holder="el@laptop1 pid 4242 #0badf00d")
    crashed.arm(go_report(clock))
    del crashed  # the console died while ARMED: nobody closes its window
    console = controller(store, clock)
    with pytest.raises(RefusedError, match="held by EL at .* until 12:01:00Z"):
        console.arm(go_report(clock))
    clock.advance(60)
    assert console.arm(go_report(clock)).mine
    disarms = [a.result for a in store.audit("DRS1") if a.action == "disarm"]
    assert disarms == ["ARM window expired at 12:01:00Z"], "closed once, audited once"


def test_a_new_process_given_a_dead_consoles_pid_cannot_fire_in_its_window(store: Store) -> None:
    """The holder was account@host pid: a process that the kernel gave the crashed console's pid was it."""
    clock = ManualClock(T0)
    crashed = controller(store, clock)
    window = crashed.arm(go_report(clock)).window
    assert window is not None
    store.write("UPDATE arm_window SET holder = ? WHERE id = ?", (f"{window.session} #deadbeef", window.id))
    reborn = controller(store, clock)  # same account, host and pid as the window's session
    assert reborn.session == window.session and not reborn.status().mine
    with pytest.raises(
        RefusedError, match="FIRE refused: the ARM window is held by EL at .*, not this console"
    ):
        reborn.fire("DRS1", go_report(clock), single_operator_waiver="alone")


def test_a_fire_that_died_before_go_left_frees_the_capsule_after_a_grace(store: Store) -> None:
    """A console killed between FIRING and the state machine's go-sent write left FIRING for ever."""
    clock = ManualClock(T0)
    arming = controller(store, clock)
    window = arming.arm(go_report(clock)).window
    assert window is not None and arming.windows.start_firing(window.id, arming.holder, clock())
    clock.advance(60 + FIRING_STALE_S - 1)
    with pytest.raises(RefusedError, match="ARM refused: the capsule is firing"):
        arming.arm(go_report(clock))
    clock.advance(1)
    status = arming.status()
    assert status.state is ArmState.DISARMED
    assert status.last_disarm_reason == "FIRE stopped before Go left (the firing process ended)"
    assert arming.arm(go_report(clock)).armed


def test_a_go_that_left_keeps_its_window_firing_for_finish_go(
    store: Store, monkeypatch: pytest.MonkeyPatch
) -> None:
    """Past the grace, a FIRING window whose Go did leave (go-sent-unverified) is not freed for a new ARM."""
    clock = ManualClock(T0)
    arming = controller(store, clock)
    window = arming.arm(go_report(clock)).window
    assert window is not None and arming.windows.start_firing(window.id, arming.holder, clock())
    sent = replace(arming.machine.record(), state=ReleaseState.GO_SENT)
    monkeypatch.setattr(ReleaseStateMachine, "record", lambda machine: sent)
    clock.advance(3600)
    assert arming.status().state is ArmState.FIRING
    with pytest.raises(RefusedError, match="the capsule is firing"):
        arming.arm(go_report(clock))
    arming.finished()
    assert arming.status().state is ArmState.FIRED


ARM_IN_A_CHILD = """
import sys
from datetime import UTC, datetime
from drs_link.errors import RefusedError
from drs_link.store import Store
from tests.clock import ManualClock
from tests.drs_link.ops.test_arming import controller, go_report
path = sys.argv[1]
clock = ManualClock(datetime(2026, 9, 1, 12, 0, tzinfo=UTC))
arming = controller(Store.open(path), clock)  # this process's own holder (session and token)
print("ready", flush=True)
sys.stdin.readline()  # released by the parent once every child is ready
try:
    print("armed" if arming.arm(go_report(clock)).mine else "lost")
except RefusedError as exc:
    print(exc)
"""


def test_four_processes_arming_at_the_same_moment_open_one_window(tmp_path: Path) -> None:
    """Real processes, each with its own holder and connection, released at one moment: each says it is
    ready (imported, store open), and all are released together once all are (a guessed 3 s start was
    not enough for four imports on a loaded machine, and then they armed one after another)."""
    import subprocess
    import sys

    path = tmp_path / "shared.sqlite"
    Store.open(path)
    children = [
        subprocess.Popen(
            [sys.executable, "-c", ARM_IN_A_CHILD, str(path)],
            stdin=subprocess.PIPE,
            stdout=subprocess.PIPE,
            text=True,
        )  # fmt: skip
        for _ in range(4)
    ]
    for child in children:
        assert child.stdout is not None and child.stdout.readline() == "ready\n"
    for child in children:
        assert child.stdin is not None
        child.stdin.write("go\n")
        child.stdin.flush()
    outcomes = [child.communicate(timeout=60)[0].strip() for child in children]
    assert outcomes.count("armed") == 1, outcomes
    assert all("one ARM per capsule" in o for o in outcomes if o != "armed"), outcomes
    assert [row["state"] for row in Store.open(path).query("SELECT state FROM arm_window")] == ["armed"]

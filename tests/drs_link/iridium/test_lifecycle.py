"""Command lifecycle against the simulated gateway and capsule, with the real durable store."""

from __future__ import annotations

import signal
import subprocess
import sys
import threading
import time
from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest

from drs_link.config import CapsuleConfig
from drs_link.errors import RefusedError, StoreError
from drs_link.iridium import lifecycle as lc, reports as report_module
from drs_link.iridium.gateway import RockblockGateway
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import ReportStore
from drs_link.sim.rockblock import Scripted, SimulatedCapsule, SimulatedRockblock
from drs_link.store import Store
from tests.clock import ManualClock

from .helpers import IMEI, T0, fly

CAPSULE = CapsuleConfig(name="DRS1", host="127.0.0.1", imei=IMEI, rockblock_serial=11800)


@pytest.fixture
def rig(
    tmp_path: Path,
) -> Iterator[tuple[Store, ReportStore, SimulatedRockblock, RockblockGateway, ManualClock]]:
    store = Store.open(tmp_path / "drs.sqlite")
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        client = RockblockGateway(gateway.url, "ops", "pw", timeout_s=0.5, retry_delay_s=0.0)
        yield store, ReportStore(store), gateway, client, ManualClock(T0)
    store.close()


def test_interval_command_runs_from_request_to_effect_confirmed(rig) -> None:
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    next_alarm = fly(capsule, gateway, reports, T0, 3)
    life = lc.CommandLifecycle(store, "alice", clock)
    command = life.request(CAPSULE, MtComposer().add("INTERVAL", 5).build())
    assert command.state == lc.REQUESTED
    with pytest.raises(RefusedError, match="must name the capsule 'DRS1'"):
        life.send(command.id, "drs1", client)
    refused = life.get(command.id)
    assert refused.state == lc.NOT_SENT and "refused" in refused.detail and gateway.requests == []
    with pytest.raises(RefusedError, match="never sent twice"):
        life.send(command.id, "DRS1", client)  # a refused command stays refused: the operator asks again
    clock.now = next_alarm - timedelta(seconds=30)
    command = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 5).build()).id, "DRS1", client)
    assert (command.state, command.mt_id) == (lc.QUEUED, 4114652)
    with pytest.raises(RefusedError, match="never sent twice"):
        life.send(command.id, "DRS1", client)
    assert len(gateway.requests) == 1
    fly(capsule, gateway, reports, next_alarm, 1)
    [changed] = life.observe(reports.for_imei(IMEI), IMEI)
    assert changed.state == lc.PROBABLY_DELIVERED and "MOMSN 3" in changed.detail
    assert capsule.interval_min == 5
    fly(capsule, gateway, reports, next_alarm + timedelta(minutes=2), 2)
    assert life.observe(reports.for_imei(IMEI), IMEI) == [], (
        "one spacing at 5 min is not yet the new interval"
    )
    fly(capsule, gateway, reports, next_alarm + timedelta(minutes=12), 1)
    [changed] = life.observe(reports.for_imei(IMEI), IMEI)
    assert changed.state == lc.EFFECT_CONFIRMED
    actions = [record.action for record in store.audit(capsule="DRS1")]
    assert actions == [
        "mt.requested",
        "mt.send",
        "mt.not_sent",
        "mt.requested",
        "mt.confirmed",
        "mt.queued",
        "mt.probably_delivered",
        "mt.effect_confirmed",
    ]


def test_parachute_and_sounder_are_delivered_but_unconfirmable(rig) -> None:
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    life = lc.CommandLifecycle(store, "alice", clock)
    command = life.request(CAPSULE, MtComposer().add("PARACHUTE", (10, 5)).add("SOUNDER", False).build())
    life.send(command.id, "DRS1", client)
    fly(capsule, gateway, reports, T0 + timedelta(minutes=1), 1)
    [changed] = life.observe(reports.for_imei(IMEI), IMEI)
    assert changed.state == lc.UNCONFIRMABLE and "can not be confirmed" in changed.detail
    assert capsule.parachute_open and not capsule.sounder_on


def test_one_mt_per_session_so_two_queued_commands_need_two_reports(rig) -> None:
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    life = lc.CommandLifecycle(store, "alice", clock)
    first = life.send(life.request(CAPSULE, MtComposer().add("SOUNDER", False).build()).id, "DRS1", client)
    second = life.send(life.request(CAPSULE, MtComposer().add("SOUNDER", True).build()).id, "DRS1", client)
    fly(capsule, gateway, reports, T0 + timedelta(minutes=1), 1)
    life.observe(reports.for_imei(IMEI), IMEI)
    assert [life.get(first.id).state, life.get(second.id).state] == [lc.UNCONFIRMABLE, lc.QUEUED]
    fly(capsule, gateway, reports, T0 + timedelta(minutes=3), 1)
    life.observe(reports.for_imei(IMEI), IMEI)
    assert life.get(second.id).state == lc.UNCONFIRMABLE and capsule.sounder_on


def test_gateway_outcomes_other_than_ok_are_recorded_and_never_resent(rig) -> None:
    store, _reports, gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    gateway.script(Scripted("failed", code=13), Scripted("slow", delay_s=1.0))
    failed = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 3).build()).id, "DRS1", client)
    assert failed.state == lc.FAILED and "insufficient credit" in failed.detail
    unknown = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 3).build()).id, "DRS1", client)
    assert unknown.state == lc.DELIVERY_UNKNOWN and "check the RockBLOCK portal" in unknown.detail
    with pytest.raises(RefusedError):
        life.send(unknown.id, "DRS1", client)
    assert len(gateway.requests) == 2


def test_flush_marks_older_queued_commands_flushed(rig) -> None:
    store, _reports, gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    older = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 3).build()).id, "DRS1", client)
    newer = life.send(
        life.request(CAPSULE, MtComposer().add("INTERVAL", 4).build(), flush=True).id, "DRS1", client
    )
    assert life.get(older.id).state == lc.FLUSHED
    assert newer.state == lc.QUEUED
    assert list(gateway.queues[IMEI]) == [b"[INTERVAL=4]"]
    assert any("flush=yes empties" in (r.detail or {}).get("detail", "") for r in store.audit(capsule="DRS1"))


def test_queued_command_with_no_report_for_hours_times_out(rig) -> None:
    store, reports, _gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    command = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 3).build()).id, "DRS1", client)
    assert life.observe(reports.for_imei(IMEI), IMEI) == []
    clock.now = T0 + lc.QUEUE_TIMEOUT + timedelta(minutes=1)
    [changed] = life.observe(reports.for_imei(IMEI), IMEI)
    assert changed.id == command.id and changed.state == lc.TIMED_OUT


def test_interval_whose_spacing_never_shows_times_out(rig) -> None:
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    life = lc.CommandLifecycle(store, "alice", clock)
    command = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 7).build()).id, "DRS1", client)
    gateway.queues[IMEI].clear()
    gateway.queues[IMEI].append(b"[interval=7]")
    fly(capsule, gateway, reports, T0 + timedelta(minutes=1), 7)
    life.observe(reports.for_imei(IMEI), IMEI)
    final = life.get(command.id)
    assert final.state == lc.TIMED_OUT and "[INTERVAL=7]: not seen" in final.detail


def test_request_without_imei_is_refused(rig) -> None:
    store, *_ = rig
    life = lc.CommandLifecycle(store, "alice")
    with pytest.raises(RefusedError, match="no imei configured"):
        life.request(CapsuleConfig(name="DRS2", host="x"), MtComposer().add("INTERVAL", 3).build())


def test_every_audit_record_carries_the_lifecycle_clock_not_the_wall_clock(rig) -> None:
    store, _reports, _gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    command = life.request(CAPSULE, MtComposer().add("INTERVAL", 3).build())
    with pytest.raises(RefusedError):
        life.send(command.id, "DRS2", client)
    life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 3).build()).id, "DRS1", client)
    records = store.audit(capsule="DRS1")
    assert [r.action for r in records][:3] == ["mt.requested", "mt.send", "mt.not_sent"]
    assert {r.time_utc for r in records} == {clock()}


def _race(
    store: Store, command_id: int, client: RockblockGateway, clock: ManualClock, senders: int
) -> list[str]:
    """``senders`` threads, each with its own connection to the store, send one command at once."""
    start = threading.Barrier(senders)
    outcomes: list[str] = []

    def send_it() -> None:
        mine = lc.CommandLifecycle(Store.open(store.path), "alice", clock)
        start.wait()
        try:
            outcomes.append(mine.send(command_id, "DRS1", client).state)
        except RefusedError:
            outcomes.append("refused")

    threads = [threading.Thread(target=send_it) for _ in range(senders)]
    for thread in threads:
        thread.start()
    for thread in threads:
        thread.join()
    return outcomes


def test_the_same_command_sent_from_eight_threads_at_once_reaches_the_gateway_once(rig) -> None:
    """The step from requested to confirmed is a compare-and-set: read-then-write let 30 of 30 such
    races send twice. With it exactly one send gets through, so this cannot fail by chance."""
    store, _, gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    for trial in range(5):
        command = life.request(CAPSULE, MtComposer().add("INTERVAL", 5 + trial).build())
        assert sorted(_race(store, command.id, client, clock, 8)) == ["queued"] + ["refused"] * 7
    assert len(gateway.requests) == 5


SEND_IN_A_CHILD = """
import sys
from drs_link.config import CapsuleConfig
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.gateway import RockblockGateway
from drs_link.iridium.mt import MtComposer
from drs_link.store import Store
capsule = CapsuleConfig(name="DRS1", host="127.0.0.1", imei=sys.argv[3], rockblock_serial=11800)
life = lc.CommandLifecycle(Store.open(sys.argv[1]), "alice")
command = life.request(capsule, MtComposer().add("INTERVAL", 30).build())
life.send(command.id, "DRS1", RockblockGateway(sys.argv[2], "ops", "pw", timeout_s=60, retry_delay_s=0.0))
"""


@pytest.mark.parametrize("stop", [signal.SIGKILL, signal.SIGTERM])
def test_a_send_stopped_after_the_gateway_took_it_is_delivery_unknown_at_once_and_can_be_resolved(
    rig, stop: signal.Signals
) -> None:
    """kill -9 or SIGTERM once left the command 'confirmed' for 15 minutes, which ``drs mt resolve`` refused
    to settle: the sender's lock dies with it, so the next look settles it."""
    store, _, gateway, _, _ = rig
    lc.CommandLifecycle(store, "bob")  # the table exists before the child writes its row
    gateway.script(Scripted("slow", delay_s=30.0))
    child = subprocess.Popen([sys.executable, "-c", SEND_IN_A_CHILD, str(store.path), gateway.url, IMEI])
    try:
        deadline = time.monotonic() + 60
        while not gateway.requests and time.monotonic() < deadline:
            time.sleep(0.05)
        [command] = lc.CommandLifecycle(store, "bob").for_imei(IMEI)
        assert gateway.requests and command.state == lc.CONFIRMED, "a live sender is left alone"
    finally:
        child.send_signal(stop)
        child.wait(timeout=30)
    recovered = lc.CommandLifecycle(store, "bob").get(command.id)
    assert (
        recovered.state == lc.DELIVERY_UNKNOWN and "stopped before the gateway answered" in recovered.detail
    )
    if stop == signal.SIGTERM:
        assert child.returncode == 128 + signal.SIGTERM and "(SIGTERM)" in recovered.detail
    resolved = lc.CommandLifecycle(store, "bob").resolve_not_sent(command.id, "DRS1", "gateway shows nothing")
    assert resolved.state == lc.NOT_SENT


REQUEST_IN_A_CHILD = """
import sys, threading
from drs_link.config import CapsuleConfig
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.mt import MtComposer
from drs_link.store import Store
capsule = CapsuleConfig(name="DRS1", host="127.0.0.1", imei=sys.argv[2], rockblock_serial=11800)
lc.CommandLifecycle(Store.open(sys.argv[1]), "alice").request(capsule, MtComposer().add("INTERVAL", 30).build())
print("requested", flush=True)
threading.Event().wait()  # stopped between the request and the send
"""


def test_a_process_killed_between_request_and_send_leaves_a_command_closed_as_never_sent(rig) -> None:
    """The step before the send: nothing left the machine, so once its process is gone it is closed as not
    sent (it once stayed 'requested' for good) and the same command can be requested again."""
    store, _, gateway, client, _ = rig
    lc.CommandLifecycle(store, "bob")  # the table exists before the child writes its row
    child = subprocess.Popen(
        [sys.executable, "-c", REQUEST_IN_A_CHILD, str(store.path), IMEI], stdout=subprocess.PIPE, text=True
    )
    try:
        assert child.stdout is not None and child.stdout.readline() == "requested\n"
        [command] = lc.CommandLifecycle(store, "bob").for_imei(IMEI)
        assert command.state == lc.REQUESTED, "its process is alive: it may still send it"
    finally:
        child.send_signal(signal.SIGKILL)
        child.wait()
    life = lc.CommandLifecycle(store, "bob")
    closed = life.get(command.id)
    assert closed.state == lc.NOT_SENT and "never reached the gateway" in closed.detail
    with pytest.raises(RefusedError, match="never sent twice"):
        life.send(command.id, "DRS1", client)
    again = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 30).build()).id, "DRS1", client)
    assert again.state == lc.QUEUED and len(gateway.requests) == 1


def test_a_send_that_raises_is_recorded_as_delivery_unknown_not_left_confirmed(rig) -> None:
    store, _, _, _, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    command = life.request(CAPSULE, MtComposer().add("SOUNDER", False).build())

    class BreaksMidSend:
        def send(self, imei: str, data: bytes, flush: bool = False) -> object:
            raise KeyboardInterrupt

    with pytest.raises(KeyboardInterrupt):
        life.send(command.id, "DRS1", BreaksMidSend())  # type: ignore[arg-type]
    assert life.get(command.id).state == lc.DELIVERY_UNKNOWN


def _commands_of(store: Store) -> list[tuple[object, ...]]:
    return [
        (c.id, c.state, c.detail, c.delivered_report_id, c.effects)
        for c in lc.CommandLifecycle(store, "x").for_imei(IMEI)
    ]


@pytest.mark.parametrize("history", [3, 150])
def test_the_work_after_each_post_is_the_open_commands_reports_not_the_flight(
    rig, monkeypatch: pytest.MonkeyPatch, history: int, tmp_path: Path
) -> None:
    """``drs mo serve`` advances the commands after every post; it re-read and re-parsed every stored
    report to do so, work that grew with the flight. Counted here (reports parsed per post), not timed:
    the same whether 3 or 150 reports came before; and after every post the commands are what
    ``observe`` on the whole history makes of a copy of the store."""
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    next_alarm = fly(capsule, gateway, reports, T0, history)
    life = lc.CommandLifecycle(store, "alice", clock)
    parse_hex = report_module.parse_hex
    parsed: list[str] = []
    monkeypatch.setattr(report_module, "parse_hex", lambda text: parsed.append(text) or parse_hex(text))

    def post_then_observe(at) -> list[str]:  # type: ignore[no-untyped-def]
        fly(capsule, gateway, reports, at, 1)
        twin = Store.open(tmp_path / f"twin-{at:%H%M%S}.sqlite")
        store.conn.backup(twin.conn)
        lc.CommandLifecycle(twin, "alice", clock).observe(ReportStore(twin).for_imei(IMEI), IMEI)
        parsed.clear()
        states = [c.state for c in life.observe_store(reports, IMEI)]
        assert _commands_of(store) == _commands_of(twin)
        return [*states, len(parsed)]  # type: ignore[list-item]

    assert post_then_observe(next_alarm) == [0], "no open command: nothing to read"
    clock.now = next_alarm + timedelta(minutes=1, seconds=30)
    command = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 5).build()).id, "DRS1", client)
    outcomes = [post_then_observe(next_alarm + timedelta(minutes=2 * (i + 1))) for i in range(2)]
    outcomes += [post_then_observe(next_alarm + timedelta(minutes=4 + 5 * i)) for i in range(1, 4)]
    assert outcomes == [[lc.PROBABLY_DELIVERED, 1], [2], [3], [lc.EFFECT_CONFIRMED, 4], [5]]
    # A confirmed effect stays open to contradiction for RECHECK_REPORTS reports, then nothing is read.
    last = next_alarm + timedelta(minutes=19)
    rest = [post_then_observe(last + timedelta(minutes=5 * i)) for i in range(1, lc.RECHECK_REPORTS - 2)]
    assert rest == [[1 + after] for after in range(5, lc.RECHECK_REPORTS + 1)] + [[0]], (
        "the delivering report and those after it, until more than RECHECK_REPORTS follow it"
    )
    assert life.get(command.id).state == lc.EFFECT_CONFIRMED


def test_an_interval_is_not_confirmed_by_lost_sessions_and_later_contradicting_spacings_reopen_it(
    rig,
) -> None:
    """#24 item 3: [INTERVAL=30] was called confirmed from one 30-min gap of lost sessions while the capsule
    stayed at 2 min. Here it never takes the command (the download is garbage): one gap of lost sessions is
    not enough, two are (a coincidence no rule can tell), and the 2-min spacing that follows re-opens it."""
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    alarm = fly(capsule, gateway, reports, T0, 3)
    life = lc.CommandLifecycle(store, "alice", clock)
    clock.now = alarm - timedelta(seconds=30)
    command = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 30).build()).id, "DRS1", client)
    gateway.queues[IMEI].clear()
    gateway.queues[IMEI].append(b"[interval=30]")  # not a command the firmware reads: it stays at 2 min

    def state_after(*minutes_from_alarm: float) -> str:
        for minutes in minutes_from_alarm:
            fly(capsule, gateway, reports, alarm + timedelta(minutes=minutes), 1)
        life.observe(reports.for_imei(IMEI), IMEI)
        return life.get(command.id).state

    assert state_after(0, 2) == lc.PROBABLY_DELIVERED
    assert state_after(32) == lc.PROBABLY_DELIVERED, (
        "one 30-min gap: sessions lost at 2 min, or the new value"
    )
    assert state_after(62) == lc.EFFECT_CONFIRMED, "two adjacent 30-min spacings and nothing against them"
    assert state_after(64) == lc.TIMED_OUT
    reopened = life.get(command.id)
    assert "now contradicted by later reports (re-opened)" in reopened.detail
    assert reopened.effects == {"[INTERVAL=30]": "not seen"}


def test_a_single_gap_of_lost_sessions_then_the_old_spacing_is_not_seen(rig) -> None:
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    alarm = fly(capsule, gateway, reports, T0, 3)
    life = lc.CommandLifecycle(store, "alice", clock)
    clock.now = alarm - timedelta(seconds=30)
    command = life.send(life.request(CAPSULE, MtComposer().add("INTERVAL", 30).build()).id, "DRS1", client)
    gateway.queues[IMEI].clear()
    gateway.queues[IMEI].append(b"[interval=30]")
    for minutes in (0, 2, 32, 34):
        fly(capsule, gateway, reports, alarm + timedelta(minutes=minutes), 1)
    life.observe(reports.for_imei(IMEI), IMEI)
    final = life.get(command.id)
    assert final.state == lc.TIMED_OUT and "[INTERVAL=30]: not seen" in final.detail


def test_a_store_failure_after_the_gateway_queued_says_so_with_the_mt_id(
    rig, monkeypatch: pytest.MonkeyPatch
) -> None:
    """#24 item 12: the operator read only the store's error, nothing of the MT the gateway had queued."""
    store, _, gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    command = life.request(CAPSULE, MtComposer().add("INTERVAL", 9).build())
    apply = lc.CommandLifecycle._apply

    def full_disk_at_queued(self: lc.CommandLifecycle, changes: list) -> None:  # type: ignore[type-arg]
        if any(change.state == lc.QUEUED for change in changes):
            raise StoreError("the store drs.sqlite cannot be written: database or disk is full")
        apply(self, changes)

    monkeypatch.setattr(lc.CommandLifecycle, "_apply", full_disk_at_queued)
    with pytest.raises(StoreError) as failed:
        life.send(command.id, "DRS1", client)
    message = str(failed.value)
    assert message.startswith("the gateway queued it as MT 4114652 (command"), message
    assert "do not send it again" in message and "[INTERVAL=9]" in message and len(gateway.requests) == 1
    monkeypatch.undo()
    settled = lc.CommandLifecycle(store, "bob", clock).get(command.id)
    assert settled.state == lc.DELIVERY_UNKNOWN, "the sender is gone: settled once the store takes writes"

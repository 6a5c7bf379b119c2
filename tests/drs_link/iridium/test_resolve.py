"""Resolving a command of unknown delivery from what the RockBLOCK portal shows, and what that does to
the attribution of later commands (one MT per session, oldest first)."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import timedelta
from pathlib import Path

import pytest

from drs_link.config import CapsuleConfig
from drs_link.errors import RefusedError
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.gateway import RockblockGateway
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import ReportStore
from drs_link.sim.rockblock import Scripted, SimulatedCapsule, SimulatedRockblock
from drs_link.store import Store
from tests.clock import ManualClock

from .helpers import IMEI, T0, fly

CAPSULE = CapsuleConfig(name="DRS1", host="127.0.0.1", imei=IMEI, rockblock_serial=11800)
Rig = tuple[Store, ReportStore, SimulatedRockblock, RockblockGateway, ManualClock]


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    store = Store.open(tmp_path / "drs.sqlite")
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        client = RockblockGateway(gateway.url, "ops", "pw", timeout_s=0.3, retry_delay_s=0.0)
        yield store, ReportStore(store), gateway, client, ManualClock(T0)
    store.close()


def send(life: lc.CommandLifecycle, composer: MtComposer, client: RockblockGateway) -> lc.Command:
    return life.send(life.request(CAPSULE, composer.build()).id, "DRS1", client)


def portal_id(gateway: SimulatedRockblock, index: int) -> int:
    """The MT id the gateway gave a request: what the operator reads on the RockBLOCK portal."""
    answer = gateway.requests[index].answered
    assert answer.startswith("OK,"), answer
    return int(answer.split(",")[1])


def delivered_momsn(life: lc.CommandLifecycle, reports: ReportStore, command_id: int) -> int:
    by_id = {r.id: r for r in reports.for_imei(IMEI)}
    return by_id[life.get(command_id).delivered_report_id].delivery.momsn


def unknown_but_queued(rig: Rig) -> tuple[lc.CommandLifecycle, SimulatedCapsule, lc.Command, lc.Command]:
    """SOUNDER_OFF times out after the gateway queued it, then INTERVAL=5 is queued behind it; 4 sessions."""
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    next_alarm = fly(capsule, gateway, reports, T0, 2)
    life = lc.CommandLifecycle(store, "alice", clock)
    clock.now = T0 + timedelta(minutes=3)
    gateway.script(Scripted("slow", delay_s=0.8))
    unknown = send(life, MtComposer().add("SOUNDER", False), client)
    assert unknown.state == lc.DELIVERY_UNKNOWN
    clock.now += timedelta(seconds=10)
    interval = send(life, MtComposer().add("INTERVAL", 5), client)
    assert interval.state == lc.QUEUED
    fly(capsule, gateway, reports, next_alarm, 5)
    clock.now = T0 + timedelta(minutes=25)
    return life, capsule, unknown, interval


def test_resolving_as_queued_moves_the_later_command_one_report_later(rig: Rig) -> None:
    store, reports, gateway, _client, _clock = rig
    life, capsule, unknown, interval = unknown_but_queued(rig)
    assert capsule.effects[0].sounder is False and capsule.effects[1].interval == 5
    life.observe(reports.for_imei(IMEI), IMEI)
    assumed = life.get(interval.id)
    assert delivered_momsn(life, reports, interval.id) == 2
    assert f"uncertain until MT {unknown.id} (delivery unknown" in assumed.detail

    resolved = life.resolve_queued(
        unknown.id, "DRS1", portal_id(gateway, 0), reports.for_imei(IMEI), note="portal shows MT queued"
    )
    assert (resolved.state, resolved.mt_id) == (lc.QUEUED, portal_id(gateway, 0))
    assert "resolved by alice" in resolved.detail and "portal shows MT queued" in resolved.detail
    assert life.get(interval.id).state == lc.QUEUED and life.get(interval.id).delivered_report_id is None

    life.observe(reports.for_imei(IMEI), IMEI)
    assert life.get(unknown.id).state == lc.UNCONFIRMABLE
    assert delivered_momsn(life, reports, unknown.id) == 2
    assert delivered_momsn(life, reports, interval.id) == 3
    assert life.get(interval.id).state == lc.EFFECT_CONFIRMED
    assert "uncertain" not in life.get(interval.id).detail
    actions = [(r.action, r.result) for r in store.audit(capsule="DRS1")]
    assert ("mt.resolved", lc.QUEUED) in actions and ("mt.reattributed", lc.QUEUED) in actions
    resolution = next(r for r in store.audit(capsule="DRS1") if r.action == "mt.resolved")
    assert resolution.operator == "alice" and resolution.detail is not None
    assert resolution.detail["mt_id"] == portal_id(gateway, 0)


def test_a_later_command_whose_report_does_not_change_is_left_alone(rig: Rig) -> None:
    store, reports, gateway, client, clock = rig
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    next_alarm = fly(capsule, gateway, reports, T0, 1)
    life = lc.CommandLifecycle(store, "alice", clock)
    clock.now = T0 + timedelta(minutes=1)
    gateway.script(Scripted("slow", delay_s=0.8))
    unknown = send(life, MtComposer().add("SOUNDER", False), client)
    next_alarm = fly(capsule, gateway, reports, next_alarm, 1)
    clock.now = next_alarm - timedelta(seconds=30)
    later = send(life, MtComposer().add("SOUNDER", True), client)
    fly(capsule, gateway, reports, next_alarm, 1)
    life.observe(reports.for_imei(IMEI), IMEI)
    before = life.get(later.id)
    assert before.state == lc.UNCONFIRMABLE and delivered_momsn(life, reports, later.id) == 2

    life.resolve_queued(unknown.id, "DRS1", portal_id(gateway, 0), reports.for_imei(IMEI))
    life.observe(reports.for_imei(IMEI), IMEI)
    assert delivered_momsn(life, reports, unknown.id) == 1
    assert life.get(later.id) == before
    assert "mt.reattributed" not in [r.action for r in store.audit(capsule="DRS1")]


def test_resolving_as_not_sent_closes_it_and_a_new_request_can_be_sent(rig: Rig) -> None:
    store, reports, gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "bob", clock)
    gateway.script(Scripted("reset"))
    unknown = send(life, MtComposer().add("INTERVAL", 3), client)
    assert unknown.state == lc.DELIVERY_UNKNOWN and gateway.queues.get(IMEI, []) == []
    closed = life.resolve_not_sent(unknown.id, "DRS1", note="nothing in the portal's MT list")
    assert closed.state == lc.NOT_SENT and closed.queued_utc is None
    assert "never reached the gateway" in closed.detail and "nothing in the portal's MT list" in closed.detail
    assert life.observe(reports.for_imei(IMEI), IMEI) == []
    again = send(life, MtComposer().add("INTERVAL", 3), client)
    assert again.state == lc.QUEUED and again.id != unknown.id
    [resolution] = [r for r in store.audit(capsule="DRS1") if r.action == "mt.resolved"]
    assert (resolution.operator, resolution.result) == ("bob", lc.NOT_SENT)


def test_only_a_command_of_unknown_delivery_can_be_resolved_and_only_once(rig: Rig) -> None:
    store, reports, gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    queued = send(life, MtComposer().add("INTERVAL", 3), client)
    gateway.script(Scripted("failed", code=13), Scripted("reset"), Scripted("reset"))
    failed = send(life, MtComposer().add("INTERVAL", 4), client)
    first = send(life, MtComposer().add("INTERVAL", 5), client)
    second = send(life, MtComposer().add("INTERVAL", 6), client)
    history = reports.for_imei(IMEI)
    for command in (queued, failed):
        with pytest.raises(RefusedError, match=f"is {command.state}: only a command in delivery_unknown"):
            life.resolve_not_sent(command.id, "DRS1")
        with pytest.raises(RefusedError, match="only a command in delivery_unknown can be resolved"):
            life.resolve_queued(command.id, "DRS1", 999, history)
    life.resolve_not_sent(first.id, "DRS1")
    with pytest.raises(RefusedError, match="is not_sent: .* and only once"):
        life.resolve_not_sent(first.id, "DRS1")
    with pytest.raises(RefusedError, match="is not_sent"):
        life.resolve_queued(first.id, "DRS1", 999, history)
    life.resolve_queued(second.id, "DRS1", 999, history)
    with pytest.raises(RefusedError, match="is queued: .* and only once"):
        life.resolve_queued(second.id, "DRS1", 1000, history)
    assert [r.action for r in store.audit(capsule="DRS1")].count("mt.resolved") == 2


@pytest.mark.parametrize(
    ("capsule", "mt_id", "note", "message"),
    [
        ("DRS2", 1, "", "was sent to DRS1, not DRS2"),
        ("DRS1", 0, "", "must be a positive number, not 0"),
        ("DRS1", 4114652, "", r"gateway MT id 4114652 already belongs to MT 1 \(\[INTERVAL=3\]\)"),
        ("DRS1", 7, "line one\nline two", "one line of printable text"),
    ],
)
def test_a_bad_resolution_is_refused_and_changes_nothing(
    rig: Rig, capsule: str, mt_id: int, note: str, message: str
) -> None:
    store, reports, gateway, client, clock = rig
    life = lc.CommandLifecycle(store, "alice", clock)
    send(life, MtComposer().add("INTERVAL", 3), client)
    gateway.script(Scripted("reset"))
    unknown = send(life, MtComposer().add("INTERVAL", 4), client)
    with pytest.raises(RefusedError, match=message):
        life.resolve_queued(unknown.id, capsule, mt_id, reports.for_imei(IMEI), note=note)
    assert life.get(unknown.id) == unknown
    assert "mt.resolved" not in [r.action for r in store.audit(capsule="DRS1")]

"""A console's desk through a real operations server (aiohttp on a Unix socket, in this process): its
waivers, checklist ticks, History, session start and loss, the recovery and Iridium views, a PARACHUTE
plan and the overrides, each a verb whose answer is the operations layer's own value after a JSON round
trip, and each rule refused at the server as from any face (issue #29)."""

from __future__ import annotations

import queue
import threading
from collections.abc import Iterator
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from drs_link.config import Config, RockblockConfig
from drs_link.errors import ConfigError, RefusedError
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.ops import ChecklistRun, load_checklists, parachute_override, recovery_view, statuses_of
from drs_link.ops.checklist import PROCEDURE_DIR, StepKind
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.ops_state import SecondOperator
from drs_link.ops.views import iridium_health_from
from drs_link.server import PROTOCOL, Client, Event, InProcessServer
from drs_link.server.desk import Desk
from drs_link.server.protocol import HistoryRequest
from drs_link.sim.rockblock import SimulatedRockblock
from drs_link.store import Store
from predictor.errors import UsageError
from tests.console.conftest import offline_config

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)
PASSWORD = {"DRS_ROCKBLOCK_PASSWORD": "pw"}


def landing(store: Store, imei: str, falling: bool = False) -> None:
    """Reports byte-exact as the firmware writes them: a descent that lands (or, ``falling``, is still
    at 16-20 km), stored as the webhook stores them."""
    reports = ReportStore(store)
    altitudes = (19_900.0, 18_000.0, 16_100.0) if falling else (9000.0, 6000.0, 3000.0, 412.0, 412.0, 412.0)
    for n, alt in enumerate(altitudes):
        at = T0 - timedelta(minutes=2 * (len(altitudes) - n))
        fix = GnssFix(at, 67.70 + (0.001 * n if alt > 412 else 0.003), 21.60, alt, 12.0 if falling else 0.0,
                      90.0, 0.9, 9)  # fmt: skip
        reports.add(Delivery(imei, n, format_mo(fix, 8.7, n).hex(), "webhook", at + timedelta(seconds=20),
                             transmit_utc=at + timedelta(seconds=15)))  # fmt: skip


@pytest.fixture
def served(tmp_path: Path) -> Iterator[tuple[Config, Store, Client]]:
    config = offline_config(tmp_path)
    store = Store.open(config.store_path)
    landing(store, config.capsules[1].imei or "")
    server = InProcessServer(config, clock=lambda: T0)
    client = Client(server.socket)
    try:
        yield config, store, client
    finally:
        client.close()
        server.stop()
        store.close()


def audited(store: Store, action: str) -> list[tuple[str, str]]:
    return [(a.result, a.operator) for a in store.audit(action=action)]


def test_a_waiver_is_held_for_the_account_audited_once_and_arm_and_fire_judge_with_it(
    served: tuple[Config, Store, Client],
) -> None:
    _, store, client = served
    desk = Desk(client)
    [held] = desk.waive("DRS1", "gnss", "no sky in the hangar")
    assert (held.item, held.reason, held.operator, held.at) == ("gnss", "no sky in the hangar", "EL", T0)
    assert desk.waivers("DRS1") == (held,) and desk.waivers("DRS2") == ()
    assert desk.view().waivers == {"DRS1": (held,), "DRS2": (), "DRS3": ()}
    with pytest.raises(RefusedError, match="NO-GO") as refused:  # nobody listens on port 9: link down
        client.capsule("DRS1").arm(say=lambda _: None, held_waivers=True)
    assert "GNSS" not in str(refused.value), "the held waiver judged the GNSS item"
    with pytest.raises(RefusedError):
        client.capsule("DRS1").fire("DRS1", say=lambda _: None, held_waivers=True)
    assert audited(store, "waiver") == [("granted", "EL")], "granted once, not again with each ARM and FIRE"
    assert desk.withdraw("DRS1", "gnss") == () and desk.waivers("DRS1") == ()
    assert audited(store, "waiver") == [("granted", "EL"), ("withdrawn", "EL")]
    desk.waive("DRS1", "sync", "the rest is on the spare card")
    client.capsule("DRS1").reset("DRS1")
    assert desk.waivers("DRS1") == (), "a reset starts the next attempt: the last one's waivers are void"


@pytest.mark.parametrize(
    ("item", "reason", "refusal"),
    [
        (
            "gnss",
            "fine\x1b[2Jreally",
            r"the waiver reason: character 5 is the control or format character \\x1b",
        ),
        ("gnss", "   ", "a waiver needs the operator's name and a reason"),
        ("link", "it is fine", "'link' cannot be waived"),
    ],
)
def test_a_waiver_the_rules_refuse_is_refused_at_the_server_and_nothing_is_held(
    served: tuple[Config, Store, Client], item: str, reason: str, refusal: str
) -> None:
    _, store, client = served
    with pytest.raises(RefusedError, match=refusal):
        Desk(client).waive("DRS1", item, reason)
    assert Desk(client).waivers("DRS1") == ()
    assert ("granted", "EL") not in audited(store, "waiver")


def test_a_tick_and_a_skip_are_recorded_by_the_server_and_a_command_or_automatic_step_is_refused(
    served: tuple[Config, Store, Client],
) -> None:
    _, store, client = served
    desk = Desk(client)
    checklist = next(c for c in load_checklists(PROCEDURE_DIR) if c.id == "preflight")
    manual = [s for s in checklist.steps if s.kind is StepKind.MANUAL]
    [ticked] = desk.tick("DRS1", checklist.id, manual[0].id)
    assert (ticked.checklist, ticked.step, ticked.state.value, ticked.operator, ticked.at) == (
        checklist.id, manual[0].id, "done", "EL", T0,
    )  # fmt: skip
    recorded = desk.skip("DRS1", checklist.id, manual[1].id, "done at the hangar")
    assert sorted((r.step, r.state.value, r.note or "") for r in recorded) == sorted([
        (manual[0].id, "done", ""), (manual[1].id, "skipped", "done at the hangar"),
    ])  # fmt: skip
    facts: dict[str, object] = {}
    local = ChecklistRun(store, checklist, "DRS1").statuses(facts)
    assert statuses_of(checklist, desk.view().checklists["DRS1"], facts) == local, "as the store has them"
    others = [s for s in checklist.steps if s.kind is not StepKind.MANUAL]
    for step in others:
        with pytest.raises(RefusedError, match=step.id):
            desk.tick("DRS1", checklist.id, step.id)
    with pytest.raises(RefusedError, match=r"character 1 is the control or format character \\x07"):
        desk.skip("DRS1", checklist.id, manual[2].id, "\x07")
    with pytest.raises(RefusedError, match="no checklist 'nope'"):
        desk.tick("DRS1", "nope", manual[2].id)
    assert len(desk.view().checklists["DRS1"]) == 2


def test_history_reads_names_another_consoles_entries_and_hands_every_entry_over_for_the_export(
    served: tuple[Config, Store, Client],
) -> None:
    config, store, client = served
    desk = Desk(client)
    desk.waive("DRS1", "sync", "alone on the ridge")
    other = Store.open(config.store_path)
    other.session = "jm@laptop2 pid 7"
    other.append_audit("JM", "DRS1", "arm", "armed", {"note": "\x1b[31mred"})
    other.close()
    newest = desk.history()
    assert [r.action for r in newest.records[:2]] == ["arm", "waiver"], "newest first"
    arm, waiver = newest.records[:2]
    assert newest.elsewhere(arm) == "jm@laptop2 pid 7" and newest.elsewhere(waiver) is None
    assert arm.detail == {"note": "\\x1b[31mred"}, "another's text as it may reach a terminal"
    assert [r.action for r in desk.history("ridge").records] == ["waiver"]
    every = desk.history("DRS1", limit=0)
    assert [r.action for r in every.records] == ["waiver", "arm"], "oldest first, for the export"
    assert every.records[1].detail == {"note": "\x1b[31mred"}, "the export keeps the entry as written"
    assert [r.action for r in desk.after(waiver.id).records] == ["arm"]
    store.append_audit("JM", "DRS1", "disarm", "disarmed", None)  # as the server writes another account's
    [disarm] = desk.after(arm.id).records
    assert desk.after(arm.id).elsewhere(disarm) == "JM through the operations server"
    with pytest.raises(UsageError, match="limit"):
        client.call("POST", "/audit", HistoryRequest(PROTOCOL, limit=10**9), object)


def test_a_sessions_loss_is_recorded_at_the_server_and_told_to_the_next_console(
    served: tuple[Config, Store, Client],
) -> None:
    _, store, client = served
    desk = Desk(client)
    assert desk.session_started() is None
    loss = desk.session_lost("SIGHUP", ["DRS1"], [])
    assert (loss.signal, loss.disarmed, loss.go_in_flight) == ("SIGHUP", ("DRS1",), ())
    told = desk.session_started()
    assert told is not None and told.describe() == loss.describe(), (
        "the next console is told how the last one ended"
    )
    assert desk.session_started() is None, "once: a console started since"
    with pytest.raises(RefusedError, match="the signal"):
        desk.session_lost("SIGHUP\x1b[2J", [], [])
    with pytest.raises(ConfigError, match="DRS9"):
        desk.session_lost("SIGTERM", ["DRS9"], [])
    assert [a.result for a in store.audit(action="session.lost")] == ["disarmed"]


def test_the_recovery_and_iridium_views_cross_the_wire_equal_to_the_stores(
    served: tuple[Config, Store, Client],
) -> None:
    config, store, client = served
    desk = Desk(client)
    ops = OperatorOps(config, store, clock=lambda: T0)
    recovery = desk.recovery("DRS2")
    assert recovery.descent.landing is not None and recovery.descent.track, "the landing, its track"
    assert recovery == recovery_view(ops.iridium, "DRS2", None), "datetimes, tuples and nested values intact"
    iridium = desk.iridium("DRS2")
    assert iridium == iridium_health_from(
        "DRS2", ops.iridium.stored_reports("DRS2"), ops.iridium.commands("DRS2")
    )
    assert iridium.rows[0].fix_time is not None and iridium.rows[0].fix_time.tzinfo is not None
    with pytest.raises(ConfigError, match="DRS9"):
        desk.iridium("DRS9")


@pytest.fixture
def gateway() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password="pw") as gateway:
        yield gateway


def test_a_parachute_plan_comes_with_the_landed_evidence_and_an_override_stays_on_the_desk(
    tmp_path: Path, gateway: SimulatedRockblock
) -> None:
    config = offline_config(tmp_path)
    config = replace(config, rockblock=RockblockConfig(mt_url=gateway.url, username="ops", timeout_s=5.0))
    store = Store.open(config.store_path)
    landing(store, config.capsules[0].imei or "", falling=True)
    landing(store, config.capsules[1].imei or "")
    ops = OperatorOps(config, store, clock=lambda: T0, environ=PASSWORD)
    server = InProcessServer(config, environ=PASSWORD, clock=lambda: T0)
    try:
        with Client(server.socket) as client:
            desk = Desk(client)
            landed = desk.plan_parachute("DRS2", None)
            assert landed.plan == ops.iridium.plan_parachute(
                "DRS2", None
            ) and landed.evidence == ops.iridium.landed("DRS2")
            assert landed.evidence.on_ground and desk.landed("DRS2") == landed.evidence
            falling = desk.plan_parachute("DRS1", None)
            assert not falling.evidence.on_ground, "the operator reads NO LANDED EVIDENCE before sending"
            with pytest.raises(RefusedError, match="would be rejected at the next cycle"):
                desk.plan_parachute("DRS2", ((landed.plan.hour + 6) % 24, landed.plan.minute))
            assert desk.view().overrides == ()
            message = MtComposer().add("PARACHUTE", (falling.plan.hour, falling.plan.minute)).build()
            ops.iridium.send_mt(
                "DRS1", message, "DRS1", SecondOperator(waiver="alone"), override_landed="chase sees it down"
            )
            [override] = desk.view().overrides
            local = parachute_override(
                "DRS1", store.audit("DRS1", action="mt.parachute"), ops.iridium.commands("DRS1")
            )
            assert override == local and "WITHOUT landed evidence" in override.banner()
    finally:
        server.stop()
        store.close()


def test_the_event_stream_says_when_the_audit_moved_on(served: tuple[Config, Store, Client]) -> None:
    """What a console reads its desk again on: every waiver, tick and session is audited."""
    _, store, client = served
    events: queue.Queue[Event] = queue.Queue()

    def follow() -> None:
        for event in Client(client.socket_path).events():
            events.put(event)

    threading.Thread(target=follow, daemon=True).start()
    first = events.get(timeout=30)
    assert first.audit_id == max((r.id for r in store.audit()), default=0)
    Desk(client).waive("DRS1", "gnss", "no sky")
    moved = events.get(timeout=30)
    while moved.audit_id == first.audit_id:
        moved = events.get(timeout=30)
    assert moved.audit_id == max(r.id for r in store.audit(action="waiver"))

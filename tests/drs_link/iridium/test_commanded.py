"""What the console says of the sounder, interval and parachute, from real commands and reports.

Commands go through the real lifecycle to the simulated gateway on loopback; the simulated capsule
downloads them in its sessions and applies them with the firmware's own rules; everything is kept in
the real SQLite store. So each line is checked against what the unit really did, where that is known.
"""

from __future__ import annotations

import socket
from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path

import pytest

from drs_link.config import CapsuleConfig
from drs_link.errors import RefusedError
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.commanded import CommandedSettings, commanded_settings
from drs_link.iridium.gateway import RockblockGateway
from drs_link.iridium.mt import MtComposer, MtMessage
from drs_link.iridium.reports import ReportStore
from drs_link.sim.rockblock import Scripted, SimulatedCapsule, SimulatedRockblock
from drs_link.store import Store
from tests.clock import ManualClock

from .helpers import IMEI, T0, fix_at, fly, to_delivery

CAPSULE = CapsuleConfig(name="DRS1", host="127.0.0.1", imei=IMEI, rockblock_serial=11800)


class Rig:
    """A capsule on its 2-minute grid, its gateway, the store, and the console's lifecycle."""

    def __init__(self, store: Store, gateway: SimulatedRockblock) -> None:
        self.store = store
        self.gateway = gateway
        self.reports = ReportStore(store)
        self.client = RockblockGateway(gateway.url, "ops", "pw", timeout_s=0.5, retry_delay_s=0.0)
        self.clock = ManualClock(T0)
        self.life = lc.CommandLifecycle(store, "alice", self.clock)
        self.capsule = SimulatedCapsule(imei=IMEI, rb_source=11800, sounder_on=False)

    def send(self, message: MtMessage, at: datetime, flush: bool = False) -> lc.Command:
        self.clock.now = at
        command = self.life.request(CAPSULE, message, flush=flush)
        return self.life.send(command.id, "DRS1", self.client)

    def cycle(self, at: datetime, alt: float | None = 500.0) -> None:
        """One session with its fix at ``at`` (no fix when ``alt`` is None); the console then observes."""
        mo = self.capsule.session(
            self.gateway, fix_at(at, alt=alt) if alt is not None else None, at + timedelta(seconds=40)
        )
        self.reports.add(to_delivery(mo))
        self.clock.now = max(self.clock.now, at + timedelta(seconds=45))
        self.life.observe(self.reports.for_imei(IMEI), IMEI)

    def fly(self, start: datetime, cycles: int) -> datetime:
        alarm = fly(self.capsule, self.gateway, self.reports, start, cycles)
        self.clock.now = max(self.clock.now, alarm)
        self.life.observe(self.reports.for_imei(IMEI), IMEI)
        return alarm

    def settings(self) -> CommandedSettings:
        return commanded_settings(self.life.for_imei(IMEI), self.reports.for_imei(IMEI))


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    store = Store.open(tmp_path / "drs.sqlite")
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        yield Rig(store, gateway)
    store.close()


def at(minutes: float) -> datetime:
    return T0 + timedelta(minutes=minutes)


def test_nothing_commanded_is_unknown_and_the_interval_is_only_measured(rig: Rig) -> None:
    empty = rig.settings()
    assert empty.interval.line == (
        "Interval: unknown — never commanded from this console; "
        "spacing not measured yet (needs two adjacent reports with a fix)"
    )
    rig.fly(T0, 3)
    settings = rig.settings()
    assert settings.sounder.line == (
        "Sounder: unknown — never commanded from this console (the unit keeps its last setting in flash)"
    )
    assert settings.interval.line == (
        "Interval: unknown — never commanded from this console; measured spacing 2.0 min"
    )
    assert settings.parachute.line == "Parachute: none — no release commanded from this console"
    assert [s.heading for s in settings.statuses()] == [
        "Sounder: unknown",
        "Interval: unknown",
        "Parachute: none",
    ]


def test_a_no_fix_report_breaks_the_measured_spacing(rig: Rig) -> None:
    rig.cycle(at(0))
    rig.cycle(at(2), alt=None)
    assert "spacing not measured yet" in rig.settings().interval.detail
    rig.cycle(at(4))
    rig.cycle(at(6.5))
    assert rig.settings().interval.detail.endswith("measured spacing 2.5 min")


def test_sounder_on_is_queued_then_probably_delivered_and_never_confirmed(rig: Rig) -> None:
    rig.fly(T0, 3)
    command = rig.send(MtComposer().add("SOUNDER", True).build(), at(5))
    queued = rig.settings().sounder
    assert (queued.value, queued.command_id) == ("ON", command.id)
    assert queued.line == "Sounder: ON — queued 10:05Z, not yet fetched"
    rig.cycle(at(6))
    assert rig.capsule.sounder_on, "the simulated firmware applied it"
    assert rig.settings().sounder.line == (
        "Sounder: ON — probably delivered at the 10:06Z report; cannot be confirmed by telemetry"
    )


def test_a_later_off_supersedes_an_earlier_on_and_says_what_holds_until_then(rig: Rig) -> None:
    rig.send(MtComposer().add("SOUNDER", True).build(), at(1))
    rig.cycle(at(2))
    rig.send(MtComposer().add("SOUNDER", False).build(), at(3))
    pending = rig.settings().sounder
    assert pending.line == (
        "Sounder: OFF — queued 10:03Z, not yet fetched; "
        "until then ON, probably delivered at the 10:02Z report"
    )
    rig.cycle(at(4))
    assert not rig.capsule.sounder_on
    assert rig.settings().sounder.line == (
        "Sounder: OFF — probably delivered at the 10:04Z report; cannot be confirmed by telemetry"
    )


def test_commands_that_never_left_or_were_flushed_change_nothing(rig: Rig) -> None:
    rig.send(MtComposer().add("SOUNDER", True).build(), at(1))
    rig.cycle(at(2))
    delivered_on = rig.settings().sounder.line
    rig.gateway.script(Scripted("failed", code=13))
    assert rig.send(MtComposer().add("SOUNDER", False).build(), at(3)).state == lc.FAILED
    wrong_name = rig.life.request(CAPSULE, MtComposer().add("SOUNDER", False).build())
    with pytest.raises(RefusedError):
        rig.life.send(wrong_name.id, "DRS2", rig.client)
    flushed = rig.send(MtComposer().add("SOUNDER", False).build(), at(4))
    rig.send(MtComposer().add("INTERVAL", 3).build(), at(5), flush=True)
    assert rig.life.get(flushed.id).state == lc.FLUSHED
    with socket.socket() as closed:
        closed.bind(("127.0.0.1", 0))
        port = closed.getsockname()[1]
    unreachable = RockblockGateway(
        f"http://127.0.0.1:{port}/rockblock/MT", "ops", "pw", connect_attempts=1, retry_delay_s=0.0
    )
    not_sent = rig.life.request(CAPSULE, MtComposer().add("SOUNDER", False).build())
    assert rig.life.send(not_sent.id, "DRS1", unreachable).state == lc.NOT_SENT
    assert rig.settings().sounder.line == delivered_on


def test_a_send_the_console_died_in_says_the_gateway_answer_was_never_recorded(rig: Rig) -> None:
    command = rig.life.request(CAPSULE, MtComposer().add("SOUNDER", False).build())
    # What the store holds when the console stops between the operator's confirmation and the
    # gateway's answer: the lifecycle writes "confirmed" before the request goes out.
    rig.store.write("UPDATE mt_command SET state = ? WHERE id = ?", (lc.CONFIRMED, command.id))
    assert rig.settings().sounder.line == (
        "Sounder: OFF — confirmed 10:00Z, the gateway's answer was never recorded: check the RockBLOCK portal"
    )


def test_delivery_unknown_sends_the_operator_to_the_portal_and_shadows_later_attributions(rig: Rig) -> None:
    rig.gateway.script(Scripted("reset"))
    unknown = rig.send(MtComposer().add("SOUNDER", False).build(), at(1))
    assert unknown.state == lc.DELIVERY_UNKNOWN
    assert rig.settings().sounder.line == (
        "Sounder: OFF — sent 10:01Z, delivery unknown (no gateway answer): "
        "check the portal, resolve on the Iridium screen"
    )
    rig.send(MtComposer().add("SOUNDER", True).build(), at(2))
    rig.cycle(at(3))
    assert rig.settings().sounder.line == (
        "Sounder: ON — probably delivered at the 10:03Z report or later "
        f"(MT {unknown.id}, delivery unknown, "
        "may have gone first); cannot be confirmed by telemetry"
    )


def test_a_queued_command_with_no_report_for_hours_is_probably_still_at_the_gateway(rig: Rig) -> None:
    rig.send(MtComposer().add("SOUNDER", False).build(), at(1))
    rig.clock.now = at(1) + lc.QUEUE_TIMEOUT + timedelta(minutes=1)
    rig.life.observe(rig.reports.for_imei(IMEI), IMEI)
    assert rig.settings().sounder.line == (
        "Sounder: OFF — queued 10:01Z, no report for 3 h since: probably still queued at the gateway"
    )


def test_an_interval_is_pending_until_the_spacing_shows_it(rig: Rig) -> None:
    alarm = rig.fly(T0, 3)
    rig.send(MtComposer().add("INTERVAL", 5).build(), at(5))
    assert rig.settings().interval.line == (
        "Interval: 5 min — queued 10:05Z, not yet fetched; pending: measured spacing 2.0 min"
    )
    alarm = rig.fly(alarm, 1)
    assert rig.settings().interval.line == (
        "Interval: 5 min — probably delivered at the 10:06Z report; "
        "pending (takes effect from the cycle after next): measured spacing 2.0 min"
    )
    rig.fly(alarm, 3)  # two spacings at the new value (one could be lost sessions of the old)
    assert rig.settings().interval.line == (
        "Interval: 5 min — commanded 10:05Z, confirmed by the spacing of later reports; "
        "measured spacing 5.0 min"
    )


def test_an_interval_the_spacing_never_shows_is_called_not_seen(rig: Rig) -> None:
    rig.send(MtComposer().add("INTERVAL", 7).build(), at(0.5))
    rig.gateway.queues[IMEI].clear()
    rig.gateway.queues[IMEI].append(b"[interval=7]")
    rig.fly(at(1), 7)
    assert rig.settings().interval.line == (
        "Interval: 7 min — probably delivered at the 10:01Z report, but NOT seen in the spacing since: "
        "rejected, or not downloaded; measured spacing 2.0 min"
    )


def test_an_interval_seen_in_the_same_mt_vouches_for_the_sounder_sent_with_it(rig: Rig) -> None:
    alarm = rig.fly(T0, 2)
    rig.send(MtComposer().add("INTERVAL", 5).add("SOUNDER", False).build(), at(3))
    rig.fly(rig.fly(alarm, 1), 3)
    assert rig.settings().sounder.line == (
        "Sounder: OFF — probably delivered at the 10:04Z report; the change sent with it showed, "
        "so it did go down; cannot be confirmed by telemetry"
    )


def test_a_parachute_delivered_after_landing_is_never_confirmed_and_adds_no_hint(rig: Rig) -> None:
    rig.fly(T0, 3)
    rig.send(MtComposer().add("PARACHUTE", (10, 6)).build(), at(5))
    assert rig.settings().parachute.line == (
        "Parachute: PARACHUTE=10:06 — queued 10:05Z, not yet fetched; "
        "the release cannot be confirmed by telemetry"
    )
    rig.cycle(at(6))
    rig.cycle(at(8))
    assert rig.capsule.parachute_open
    assert rig.settings().parachute.line == (
        "Parachute: PARACHUTE=10:06 — probably delivered at the 10:06Z report; "
        "the release cannot be confirmed by telemetry"
    )


def test_a_change_of_descent_rate_after_delivery_is_given_as_a_hint_only(rig: Rig) -> None:
    for minute, alt in ((0, 3000.0), (2, 2400.0), (4, 1800.0)):
        rig.cycle(at(minute), alt=alt)
    rig.send(MtComposer().add("PARACHUTE", (10, 6)).build(), at(5))
    rig.cycle(at(6), alt=1200.0)
    rig.cycle(at(8), alt=200.0)
    assert rig.capsule.parachute_open
    assert rig.settings().parachute.detail.endswith(
        "the release cannot be confirmed by telemetry; hint only: the descent rate went from 5.0 to "
        "8.3 m/s by the 10:08Z fix (a release or a landing both do that)"
    )


def test_a_steady_descent_after_delivery_adds_no_hint(rig: Rig) -> None:
    for minute, alt in ((0, 3000.0), (2, 2400.0), (4, 1800.0)):
        rig.cycle(at(minute), alt=alt)
    rig.send(MtComposer().add("PARACHUTE", (10, 6)).build(), at(5))
    rig.cycle(at(6), alt=1200.0)
    rig.cycle(at(8), alt=620.0)
    assert rig.settings().parachute.detail.endswith("the release cannot be confirmed by telemetry")


def test_a_parachute_downloaded_in_a_no_fix_cycle_is_called_lost(rig: Rig) -> None:
    rig.fly(T0, 2)
    rig.send(MtComposer().add("PARACHUTE", (10, 4)).build(), at(3))
    rig.cycle(at(4), alt=None)
    assert not rig.capsule.parachute_open
    assert rig.settings().parachute.line == (
        "Parachute: PARACHUTE=10:04 — probably delivered at the 10:04Z report; that report had no fix and "
        "a no-fix cycle ignores PARACHUTE: lost if it went down then; "
        "the release cannot be confirmed by telemetry"
    )


def test_a_parachute_outside_the_window_of_its_fix_is_called_rejected(rig: Rig) -> None:
    rig.fly(T0, 2)
    rig.send(MtComposer().add("PARACHUTE", (10, 30)).build(), at(3))
    rig.cycle(at(4))
    assert not rig.capsule.parachute_open
    assert "the 10:04Z fix is outside its ±14 min window: rejected and lost if it went down then" in (
        rig.settings().parachute.detail
    )

"""The INTERVAL a capsule runs, with the firmware's switch-over, as health, staleness and planning read it.

The capsule is the simulator (its alarm re-armed before the session downloads the MT, drs_protocol.md
3.5/3.8), the command goes through the real lifecycle to the simulated gateway on loopback, and the
reports and commands are in the real store. The rule under test is the one those share.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from datetime import timedelta
from pathlib import Path

import pytest

from drs_link.config import RockblockConfig, parse_config
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.health import assess
from drs_link.iridium.interval import interval_track
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.parachute import plan_parachute
from drs_link.iridium.reports import ReportStore, StoredReport
from drs_link.ops.fleet import CapsuleTelemetry
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.telemetry import ReportSample
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedRockblock
from drs_link.store import Store
from tests.clock import ManualClock

from .helpers import IMEI, T0, fly

PASSWORD_ENV = {"DRS_ROCKBLOCK_PASSWORD": "pw"}


class Rig:
    """DRS1 on its 2-minute grid through the simulated gateway; the console's OperatorOps read the store."""

    def __init__(self, tmp_path: Path, gateway: SimulatedRockblock) -> None:
        config = parse_config({
            "operator": {"name": "alice"}, "data": {"dir": str(tmp_path / "data")},
            "capsule": [{"name": "DRS1", "host": "127.0.0.1", "port": 9, "imei": IMEI, "rockblock_serial": 11800}],
        })  # fmt: skip
        config = replace(config, rockblock=RockblockConfig(mt_url=gateway.url, username="ops", timeout_s=2.0))
        self.store = Store.open(config.store_path)
        self.clock = ManualClock(T0)
        self.ops = OperatorOps(config, self.store, clock=self.clock, environ=PASSWORD_ENV)
        self.gateway = gateway
        self.reports = ReportStore(self.store)
        self.capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
        self.records: list = []  # type: ignore[type-arg]

    def fly(self, start, cycles: int):  # type: ignore[no-untyped-def]
        """Cycles on the simulator's own alarm grid; the console then reads the new reports."""
        alarm = fly(self.capsule, self.gateway, self.reports, start, cycles)
        self.clock.now = alarm
        self.records += self.ops.iridium.new_reports("DRS1")
        return alarm

    def stored(self) -> list[StoredReport]:
        return self.reports.for_imei(IMEI)

    def commands(self) -> list[lc.Command]:
        return self.ops.iridium.commands("DRS1")


@pytest.fixture
def rig(tmp_path: Path) -> Iterator[Rig]:
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        rig = Rig(tmp_path, gateway)
        yield rig
        rig.store.close()


def spacings_min(reports: list[StoredReport]) -> list[float]:
    times = [r.report.fix.time for r in reports if r.report is not None and r.report.fix is not None]
    return [(b - a).total_seconds() / 60 for a, b in zip(times, times[1:], strict=False)]


def test_interval_health_follows_the_simulators_switch_over(rig: Rig) -> None:
    """[INTERVAL=5] downloaded with report k: k→k+1 stays 2 min, 5 min from k+1 on; nothing is flagged."""
    alarm = rig.fly(T0, 4)
    rig.clock.now = alarm - timedelta(seconds=30)
    command = rig.ops.iridium.send_mt("DRS1", MtComposer().add("INTERVAL", 5).build(), "DRS1").command
    assert command.state == lc.QUEUED
    alarm = rig.fly(alarm, 2)  # report 4 downloads it; report 5 still comes after 2 min
    assert spacings_min(rig.stored()) == [2, 2, 2, 2, 2], "the simulator switches over as the firmware does"
    track = interval_track(rig.stored(), rig.commands())
    delivering, following = rig.stored()[4], rig.stored()[5]
    assert rig.ops.iridium.lifecycle.get(command.id).delivered_report_id == delivering.id
    assert track.after(delivering) == {2} and track.after(following) == {2, 5}, "pending: either may come"
    assert assess(rig.stored(), rig.commands()).findings == ()

    rig.fly(alarm, 3)
    assert spacings_min(rig.stored())[-3:] == [5, 5, 5]
    assert rig.ops.iridium.lifecycle.get(command.id).state == lc.EFFECT_CONFIRMED
    track = interval_track(rig.stored(), rig.commands())
    assert track.after(following) == {5} and track.next_spacing == {5}
    health = assess(rig.stored(), rig.commands())
    assert health.findings == (), [f.message for f in health.findings]


def test_a_missed_cycle_on_the_new_interval_is_judged_against_it(rig: Rig) -> None:
    alarm = rig.fly(T0, 3)
    rig.clock.now = alarm - timedelta(seconds=30)
    rig.ops.iridium.send_mt("DRS1", MtComposer().add("INTERVAL", 5).build(), "DRS1")
    alarm = rig.fly(alarm, 4)
    rig.fly(alarm + timedelta(minutes=5), 1)  # the session at ``alarm`` failed: 10 min between fixes
    [finding] = assess(rig.stored(), rig.commands()).findings
    assert finding.message == "reports 10.0 min apart for an INTERVAL of 5 min: about 1 cycle(s) missed"


def test_a_report_is_not_stale_before_the_next_one_is_due_on_the_new_interval(rig: Rig) -> None:
    """The trial: a report 4 min 48 s old was called STALE on a 5-minute interval."""
    alarm = rig.fly(T0, 3)
    rig.clock.now = alarm - timedelta(seconds=30)
    rig.ops.iridium.send_mt("DRS1", MtComposer().add("INTERVAL", 5).build(), "DRS1")
    rig.fly(alarm, 4)
    telemetry = CapsuleTelemetry("DRS1")
    for record in rig.records:
        telemetry.apply(record)
    assert [r.data.interval_min for r in rig.records] == [2, 2, 2, 2, 5, 5, 5]
    last = telemetry.reading(ReportSample)
    assert last.is_fresh(last.received_at + timedelta(minutes=4, seconds=48))  # type: ignore[operator]
    assert last.is_fresh(last.received_at + timedelta(minutes=9, seconds=59))  # type: ignore[operator]
    assert not last.is_fresh(last.received_at + timedelta(minutes=10, seconds=1))  # type: ignore[operator]


def test_the_parachute_plan_uses_the_old_spacing_for_the_next_cycle_and_the_new_one_after(rig: Rig) -> None:
    """INTERVAL=5 went down with the last report: the next cycle is 2 min on, the ones after 5 min apart."""
    alarm = rig.fly(T0, 4)
    rig.clock.now = alarm - timedelta(seconds=30)
    rig.ops.iridium.send_mt("DRS1", MtComposer().add("INTERVAL", 5).build(), "DRS1")
    alarm = rig.fly(alarm, 1)
    last_fix = rig.stored()[-1].report.fix.time  # type: ignore[union-attr]
    plan = plan_parachute(rig.stored(), last_fix + timedelta(seconds=5), rig.commands())
    first, second = plan.cycles[0], plan.cycles[1]
    assert first.fix_earliest <= last_fix + timedelta(minutes=2) <= first.fix_latest
    assert second.fix_earliest <= last_fix + timedelta(
        minutes=4
    ) and second.fix_latest >= last_fix + timedelta(minutes=7), (
        "pending: the second cycle may come on either interval"
    )
    assert "2 or 5 min" in plan.window_text()

"""The recovery screen judges a report's age on the INTERVAL the capsule runs after the console changed it.

The trial: after [INTERVAL=5] was confirmed, recovery called a report 4 min 48 s old STALE. Here the
console sends [INTERVAL=5] through the simulated gateway, the simulated capsule downloads it and keeps
the firmware's switch-over, the reports reach the console's store, and the console reads them as it
does live (its report poll), on a clock the test sets.
"""

from __future__ import annotations

from dataclasses import replace
from datetime import timedelta
from pathlib import Path

import pytest

from console.app import ConsoleSetup
from console.screens.recovery import RecoveryScreen
from drs_link.config import RockblockConfig, parse_config
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import ReportStore
from drs_link.ops.operator_ops import OperatorOps
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedRockblock
from drs_link.store import Store
from tests.clock import ManualClock
from tests.console.conftest import T0, console_on, wait_for
from tests.drs_link.iridium.helpers import fly

IMEI = "300434060000010"
pytestmark = pytest.mark.asyncio


async def test_recovery_does_not_call_a_report_stale_before_the_next_is_due_on_the_new_interval(
    tmp_path: Path,
) -> None:
    config = parse_config({
        "operator": {"name": "EL"}, "data": {"dir": str(tmp_path / "data")},
        "capsule": [{"name": "DRS1", "host": "127.0.0.1", "port": 9, "imei": IMEI, "rockblock_serial": 17001}],
    })  # fmt: skip
    with SimulatedRockblock(username="ops", password="pw", imeis=(IMEI,)) as gateway:
        config = replace(config, rockblock=RockblockConfig(mt_url=gateway.url, username="ops", timeout_s=5.0))
        store = Store.open(config.store_path)
        clock = ManualClock(T0)
        operations = OperatorOps(config, store, clock=clock, environ={"DRS_ROCKBLOCK_PASSWORD": "pw"})
        capsule = SimulatedCapsule(imei=IMEI, rb_source=17001)
        reports = ReportStore(store)
        alarm = fly(capsule, gateway, reports, T0, 3)
        clock.now = alarm - timedelta(seconds=30)
        operations.iridium.send_mt("DRS1", MtComposer().add("INTERVAL", 5).build(), "DRS1")
        fly(capsule, gateway, reports, alarm, 4)  # downloaded, one more 2-min cycle, then 5-min cycles
        last = reports.for_imei(IMEI)[-1]
        clock.now = last.time + timedelta(minutes=4, seconds=48)
        app = console_on(
            operations, ConsoleSetup(mode="live", capsules=["DRS1"], clock=clock), live_timers=False
        )
        async with app.run_test(size=(120, 40)) as pilot:
            app.start_telemetry()  # the server reads the reports and pushes them
            await wait_for(pilot, lambda: len(app.fleet.capsules["DRS1"].reports) == 7)
            await pilot.press("v")
            screen = app.screen
            assert isinstance(screen, RecoveryScreen)
            screen.refresh_view()
            text = str(screen.query_one("#recovery-text").render())
            assert "Last report: VBAT 8.9 V (4m48s)" in text and "STALE" not in text
            clock.now = last.time + timedelta(minutes=10, seconds=1)
            screen.refresh_view()
            assert "STALE" in str(screen.query_one("#recovery-text").render())
        store.close()

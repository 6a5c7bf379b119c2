"""The recovery screen: sounder, interval and parachute as the console knows them, commanded from there.

The console sends through the real lifecycle to the simulated RockBLOCK gateway on loopback; the
simulated capsule then downloads the MT in its session and applies it with the firmware's rules.
"""

from __future__ import annotations

from collections.abc import Callable, Iterator
from dataclasses import replace
from datetime import datetime, timedelta
from pathlib import Path

import pytest
from textual.pilot import Pilot
from textual.widgets import DataTable

from console.app import ConsoleSetup
from console.commands.console import _team
from console.screens.commanding import COMMAND_ACTIONS
from console.screens.iridium import IridiumScreen
from console.screens.modals import TextPromptModal
from console.screens.recovery import RecoveryScreen
from drs_link.config import RockblockConfig
from drs_link.iridium.firmware import GnssFix
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.ops.operator_ops import OperatorOps
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedRockblock
from drs_link.store import Store
from tests.console.conftest import T0, ConsoleUnderTest, console_on, offline_config, seed_reports, wait_for

pytestmark = pytest.mark.asyncio
PASSWORD_ENV = {"DRS_ROCKBLOCK_PASSWORD": "pw"}


@pytest.fixture
def gateway() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password="pw") as gateway:
        yield gateway


@pytest.fixture
def commanding_app(tmp_path: Path, gateway: SimulatedRockblock) -> ConsoleUnderTest:
    """A live console at T0 whose gateway is the simulator; DRS2 landed, reporting every 2 min."""
    config = offline_config(tmp_path)
    config = replace(config, rockblock=RockblockConfig(mt_url=gateway.url, username="ops", timeout_s=5.0))
    store = Store.open(config.store_path)
    operations = OperatorOps(config, store, clock=lambda: T0, environ=PASSWORD_ENV)
    seed_reports(store, config.capsules[1].imei or "", T0 - timedelta(minutes=30), 8)
    setup = ConsoleSetup(
        mode="live", capsules=["DRS1", "DRS2", "DRS3"], clock=lambda: T0, team_position=_team(config),
        export_dir=tmp_path / "exports",
    )  # fmt: skip
    return console_on(operations, setup, live_timers=False)


async def open_recovery(pilot: Pilot[int], app: ConsoleUnderTest) -> RecoveryScreen:
    await pilot.press("down", "v")
    screen = app.screen
    assert isinstance(screen, RecoveryScreen) and screen.capsule == "DRS2"
    await wait_for(pilot, lambda: screen.settings is not None)
    return screen


def shown(screen: RecoveryScreen) -> str:
    return str(screen.query_one("#recovery-text").render())


def deliver_next_report(
    app: ConsoleUnderTest, gateway: SimulatedRockblock, capsule: SimulatedCapsule, at: datetime
) -> None:
    """DRS2's next session: it downloads one MT; the report is stored as the webhook would, then observed."""
    fix = GnssFix(at, 67.705, 21.60, 412.0, 0.0, 90.0, 0.9, 9)
    mo = capsule.session(gateway, fix, at + timedelta(seconds=15))
    received = at + timedelta(seconds=20)
    delivery = Delivery(
        mo.imei, mo.momsn, mo.payload.hex(), "webhook", received, transmit_utc=mo.transmit_time
    )
    ReportStore(app.store).add(delivery)
    assert app.ops is not None
    app.ops.iridium.new_reports("DRS2")


async def test_the_sounder_goes_from_unknown_to_on_with_its_lifecycle_state(
    commanding_app: ConsoleUnderTest, gateway: SimulatedRockblock
) -> None:
    app = commanding_app
    async with app.run_test(size=(80, 24)) as pilot:
        screen = await open_recovery(pilot, app)
        assert "Sounder: unknown — never commanded from this console" in shown(screen)
        await pilot.press("O")
        assert isinstance(app.screen, TextPromptModal)
        await pilot.press(*"DRS9", "enter")
        await wait_for(pilot, lambda: any("must name the capsule" in n.message for n in app._notifications))
        assert screen.settings is not None and screen.settings.sounder.value == "unknown"
        await pilot.press("O", *"DRS2", "enter")
        await wait_for(pilot, lambda: screen.settings is not None and screen.settings.sounder.value == "ON")
        assert "Sounder: ON — queued 12:00Z, not yet fetched" in shown(screen)
        imei = app.ops.state.ops("DRS2").config.imei if app.ops else None
        assert list(gateway.queues[imei or ""]) == [b"[SOUNDER_ON]"]
        capsule = SimulatedCapsule(imei=imei or "", rb_source=17002, momsn=8, iteration=8, sounder_on=False)
        deliver_next_report(app, gateway, capsule, T0 + timedelta(minutes=1))
        assert capsule.sounder_on, "the simulated firmware switched it on"
        screen.ask_for_view()  # the report reached the store through this test, not the app's poll
        delivered = "Sounder: ON — probably delivered at the 12:01Z report; cannot be confirmed by telemetry"
        await wait_for(pilot, lambda: delivered in shown(screen))


async def test_the_interval_line_shows_the_measured_spacing_and_a_command_from_here_reaches_the_iridium_list(
    commanding_app: ConsoleUnderTest, gateway: SimulatedRockblock
) -> None:
    app = commanding_app
    async with app.run_test(size=(160, 48)) as pilot:
        screen = await open_recovery(pilot, app)
        measured = "Interval: unknown — never commanded from this console; measured spacing 2.0 min"
        assert measured in shown(screen)
        await pilot.press("n", "5", "enter")
        assert isinstance(app.screen, TextPromptModal) and "[INTERVAL=5]" in app.screen.title_text
        await pilot.press(*"DRS2", "enter")
        await wait_for(pilot, lambda: "Interval: 5 min" in shown(screen))
        pending = "Interval: 5 min — queued 12:00Z, not yet fetched; pending: measured spacing 2.0 min"
        assert pending in shown(screen)
        await pilot.press("i")
        iridium = app.screen
        assert isinstance(iridium, IridiumScreen) and iridium.capsule == "DRS2"
        table = iridium.query_one("#commands", DataTable)
        await wait_for(pilot, lambda: table.row_count == 1)
        assert [str(cell) for cell in table.get_row_at(0)][1:3] == ["[INTERVAL=5]", "queued at gateway"]


@pytest.mark.parametrize("keys", [("down", "i"), ("down", "v")], ids=["iridium", "recovery"])
async def test_the_parachute_key_refuses_an_out_of_window_time_as_on_the_iridium_screen(
    canned_app: Callable[..., ConsoleUnderTest], keys: tuple[str, str]
) -> None:
    app = canned_app(now=T0)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press(*keys)
        screen = app.screen
        await app.workers.wait_for_complete()
        await pilot.press("C")
        assert isinstance(app.screen, TextPromptModal)
        await pilot.press(*f"{T0 + timedelta(hours=3):%H:%M}", "enter")
        await wait_for(pilot, lambda: bool(app._notifications))
        [message] = [n.message for n in app._notifications]
        assert message == (
            "PARACHUTE refused: 15:00 would be rejected at the next cycle (fix 12:01-12:03Z accepts "
            "11:49-12:15) and the command lost"
        )
        assert app.screen is screen
        assert app.ops is not None and app.ops.iridium.commands("DRS2") == []


async def test_replay_shows_no_command_keys_on_the_recovery_screen(
    canned_app: Callable[..., ConsoleUnderTest],
) -> None:
    app = canned_app(mode="replay")
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("down", "v")
        screen = app.screen
        assert isinstance(screen, RecoveryScreen)
        await app.workers.wait_for_complete()
        await pilot.pause()
        for action in COMMAND_ACTIONS:
            assert screen.check_action(action, ()) is None
        await pilot.press("o", "n", "c")
        assert app.screen is screen
        assert "Sounder, interval, parachute: not known in replay" in shown(screen)

"""After a PARACHUTE override in flight the console stays loud: a banner on the fleet, release and
recovery screens, no tick on "Landing confirmed", and Recovery says when release B opens (issue #23).

The override goes through the real gate (``authorize_mt``, inside ``OperatorOps.send_mt``) and the MT
through the real lifecycle to the simulated RockBLOCK on loopback, as `drs mt send --override-landed`
from another terminal does.
"""

from __future__ import annotations

from collections.abc import Iterator
from dataclasses import replace
from datetime import timedelta
from pathlib import Path

import pytest
from textual.pilot import Pilot

from console.app import ConsoleSetup
from console.screens.recovery import RecoveryScreen
from console.screens.release import ReleaseScreen
from drs_link.config import RockblockConfig
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.ops_state import SecondOperator
from drs_link.sim.rockblock import SimulatedRockblock
from drs_link.store import Store
from tests.console.conftest import T0, ConsoleUnderTest, console_on, offline_config, wait_for

pytestmark = pytest.mark.asyncio
BANNER = (
    "⚠ DRS1: PARACHUTE queued WITHOUT landed evidence (override by EL, approved by nobody: "
    "single-operator waiver “alone”)"
)


@pytest.fixture
def gateway() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password="pw") as gateway:
        yield gateway


def overridden_app(tmp_path: Path, gateway: SimulatedRockblock, override: bool = True) -> ConsoleUnderTest:
    """DRS1 falling through 16 km at 16 m/s, every 2 min, and PARACHUTE=12:00 queued (with the override)."""
    config = offline_config(tmp_path)
    config = replace(config, rockblock=RockblockConfig(mt_url=gateway.url, username="ops", timeout_s=5.0))
    store = Store.open(config.store_path)
    operations = OperatorOps(config, store, clock=lambda: T0, environ={"DRS_ROCKBLOCK_PASSWORD": "pw"})
    imei = config.capsules[0].imei or ""
    for n, alt in enumerate((19_900.0, 18_000.0, 16_100.0)):
        at = T0 - timedelta(minutes=6 - 2 * n)
        fix = GnssFix(at, 67.70, 21.60 + 0.01 * n, alt, 12.0, 90.0, 0.9, 9)
        ReportStore(store).add(
            Delivery(
                imei,
                n,
                format_mo(fix, 8.7, n).hex(),
                "webhook",
                at + timedelta(seconds=20),
                transmit_utc=at + timedelta(seconds=15),
            )
        )
    if override:
        message = MtComposer().add("PARACHUTE", (12, 0)).build()
        alone = SecondOperator(waiver="alone")
        operations.iridium.send_mt("DRS1", message, "DRS1", alone, override_landed="chase sees it down")
    setup = ConsoleSetup(
        mode="live", capsules=["DRS1", "DRS2", "DRS3"], clock=lambda: T0, export_dir=tmp_path / "exports"
    )
    return console_on(operations, setup, live_timers=False)


def banner(app: ConsoleUnderTest) -> str:
    widget = app.screen.query_one("#override-banner")
    return str(widget.render()) if widget.display else ""


async def until_banner(pilot: Pilot[int], app: ConsoleUnderTest) -> None:
    app.refresh_screen()
    await wait_for(pilot, lambda: banner(app) == BANNER)


async def test_the_override_banner_stays_on_the_fleet_release_and_recovery_screens(
    tmp_path: Path, gateway: SimulatedRockblock
) -> None:
    app = overridden_app(tmp_path, gateway)
    async with app.run_test(size=(80, 24)) as pilot:
        await until_banner(pilot, app)
        await pilot.press("enter")
        assert isinstance(app.screen, ReleaseScreen)
        await until_banner(pilot, app)
        await pilot.press("escape", "v")
        screen = app.screen
        assert isinstance(screen, RecoveryScreen) and screen.capsule == "DRS1"
        await until_banner(pilot, app)
        await wait_for(pilot, lambda: screen.drop is not None)
        text = str(screen.query_one("#recovery-text").render())
        assert (
            "⚠ [PARACHUTE=12:00] queued WITHOUT landed evidence: scheduled drop at the end of the next "
            "cycle, expected 12:00:00Z (accepted until 12:14Z)"
        ) in text
        assert "from 12:00:00Z it falls WITHOUT its parachute" in text


async def test_no_banner_without_an_override(tmp_path: Path, gateway: SimulatedRockblock) -> None:
    app = overridden_app(tmp_path, gateway, override=False)
    async with app.run_test(size=(80, 24)) as pilot:
        app.refresh_screen()
        await pilot.pause()
        assert banner(app) == ""
        assert not app.screen.query_one("#override-banner").display


async def test_the_checklist_does_not_tick_landing_confirmed_after_an_override(
    tmp_path: Path, gateway: SimulatedRockblock
) -> None:
    app = overridden_app(tmp_path, gateway)
    ticked = app.store.query("SELECT step, state FROM checklist_step WHERE capsule = 'DRS1'")
    assert [(row["step"], row["state"]) for row in ticked if row["step"] == "parachute"] == []


def wrapped_rows(text: str, width: int) -> int:
    """Rows ``text`` takes when wrapped at ``width`` columns, as a Static wraps it."""
    from rich.console import Console
    from rich.text import Text

    return len(Text(text).wrap(Console(width=width), width))


async def test_the_override_banner_is_whole_at_80x24_and_after_a_resize_during_a_screen_change(
    tmp_path: Path, gateway: SimulatedRockblock
) -> None:
    """It was cut at 80×24, and once went blank after a resize during a screen change (an SSH drop and a
    reattach from another terminal size) until the next switch."""
    app = overridden_app(tmp_path, gateway)
    async with app.run_test(size=(80, 24)) as pilot:
        await until_banner(pilot, app)
        widget = app.screen.query_one("#override-banner")
        assert widget.region.height == wrapped_rows(BANNER, widget.content_region.width) >= 2
        await pilot.press("enter")
        await pilot.resize_terminal(130, 30)
        await pilot.resize_terminal(80, 24)
        await until_banner(pilot, app)
        await pilot.pause()
        widget = app.screen.query_one("#override-banner")
        assert widget.display and widget.region.height == wrapped_rows(BANNER, widget.content_region.width)

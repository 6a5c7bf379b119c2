"""A replay shows Recovery and Iridium health from the reports it has played; a live console shows a store
change on them when the store changes, not by the screens polling it.

Both screens read the store from their render method before, so a replay (no store behind it, no
operations) showed "No GNSS fix received yet" and "no Iridium reports" for a capsule whose descent
and landing were in the recording. Now the app hands both screens their views from ``RecordedViews``.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta
from pathlib import Path

import pytest
from textual.widgets import DataTable

from console.app import ConsoleSetup, DrsConsole
from console.context import REPLAY_REFUSAL, ReplayContext
from console.screens.iridium import IridiumScreen
from console.screens.recovery import RecoveryScreen
from console.screens.release import ReleaseScreen
from drs_link.errors import LinkError
from drs_link.ops import ReportSample, TelemetryRecord
from drs_link.store import Store
from tests.console.conftest import T0, offline_config, offline_server, seed_reports, wait_for

pytestmark = pytest.mark.asyncio
ALTITUDES = (19_900.0, 18_000.0, 16_100.0, 500.0, 500.0, 500.0, 500.0)
"""Falling at ~16 m/s, then still on the ground: the landing the recovery pipeline looks for."""


def recorded_reports() -> list[TelemetryRecord]:
    start = T0 - timedelta(minutes=2 * len(ALTITUDES))
    return [
        TelemetryRecord(start + timedelta(minutes=2 * n), "DRS1", ReportSample(
            momsn=40 + n, has_fix=True, lat=67.70, lon=21.60, uncertainty_m=5.0, position_source="gnss",
            alt_m=alt, speed_ms=0.0, sats=9, vbat=8.7 - 0.1 * n, iteration=n, interval_min=2,
        ))
        for n, alt in enumerate(ALTITUDES)
    ]  # fmt: skip


async def test_a_replay_shows_the_landing_and_the_reports_it_played(
    tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    played = [recorded_reports()]
    setup = ConsoleSetup(
        mode="replay", capsules=["DRS1"], server=offline_server(offline_config(tmp_path), request), clock=lambda: T0,
        replay_feed=lambda: played.pop() if played else [],
    )  # fmt: skip
    app = DrsConsole(setup, live_timers=False)
    async with app.run_test(size=(120, 40)) as pilot:
        app.replay_step()
        await wait_for(pilot, lambda: len(app.fleet.capsules["DRS1"].reports) == len(ALTITUDES))
        await pilot.press("v")
        recovery = app.screen
        assert isinstance(recovery, RecoveryScreen) and recovery.capsule == "DRS1"
        await wait_for(pilot, lambda: recovery.landing is not None)
        text = str(recovery.query_one("#recovery-text").render())
        landed_at = T0 - timedelta(minutes=2 * len(ALTITUDES)) + timedelta(minutes=6)
        assert f"Landed {landed_at:%H:%M:%S}Z at 67.70000, 21.60000" in text
        assert "Sounder, interval, parachute: not known in replay" in text
        await pilot.press("i")
        iridium = app.screen
        assert isinstance(iridium, IridiumScreen)
        await wait_for(pilot, lambda: iridium.view is not None)
        health = str(iridium.query_one("#health").render())
        assert health == "DRS1: 7 reports, battery 8.10 V. health flags not judged in a replay"
        table = iridium.query_one("#reports", DataTable)
        assert table.row_count == len(ALTITUDES)
        assert [str(c) for c in table.get_row_at(0)[:2]] == ["46", f"{T0 - timedelta(minutes=2):%H:%M:%S}Z"]


async def test_the_recovery_screen_shows_what_another_console_stored_when_the_store_changes_not_by_polling(
    canned_app: Callable[..., DrsConsole], tmp_path: Path
) -> None:
    app = canned_app()
    config = offline_config(tmp_path)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("v")
        recovery = app.screen
        assert isinstance(recovery, RecoveryScreen) and recovery.capsule == "DRS1"
        await wait_for(pilot, lambda: recovery.view is not None)
        other = Store.open(config.store_path)  # another connection: the webhook, or a second console
        seed_reports(other, config.capsules[0].imei or "", T0 - timedelta(minutes=30), 8)
        other.close()
        recovery.refresh_view()  # rendering alone reads nothing
        await pilot.pause(0.2)
        text = str(recovery.query_one("#recovery-text").render())
        assert recovery.track == () and "No GNSS fix received yet" in text
        app.start_telemetry()  # the server's report read pushes them; their arrival reads the view again
        await wait_for(pilot, lambda: recovery.landing is not None)
        assert "Landed " in str(recovery.query_one("#recovery-text").render()) and len(recovery.track) == 8


async def test_a_replay_has_no_commanding_side_it_refuses_in_one_sentence_and_dims_keys(
    tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    """Replay was ``operations=None`` with asserts behind it; now its context has no commanding side."""
    config = offline_config(tmp_path)
    store = Store.open(config.store_path)
    setup = ConsoleSetup(
        mode="replay", capsules=["DRS1"], server=offline_server(config, request), clock=lambda: T0
    )
    app = DrsConsole(setup, live_timers=False)
    context = app.context
    assert isinstance(context, ReplayContext) and not context.commanding
    for call in (context.client, lambda: context.arm("DRS1")):
        with pytest.raises(LinkError, match=f"^{REPLAY_REFUSAL}$"):
            call()
    assert context.waiting_approvals("DRS1") == [] and context.parachute_overrides() == []
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter")
        release = app.screen
        assert isinstance(release, ReleaseScreen)
        keys = ("arm", "fire", "power_on", "tick", "waive", "disarm", "cancel_approval")
        assert [key for key in keys if release.check_action(key, ())] == []
        await pilot.press("a", "o", "space")  # dimmed keys: nothing happens, nothing is written
        await pilot.pause()
        assert store.audit() == [] and app.is_running

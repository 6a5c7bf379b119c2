"""Quitting: a commanding console asks first, never mid-Go, and closes an open ARM window on the record."""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta

import pytest

from console.app import DrsConsole
from console.screens.fleet import FleetScreen
from console.screens.modals import ConfirmModal
from drs_link.ops.arming import ArmState
from tests.console.conftest import wait_for

pytestmark = pytest.mark.asyncio


async def test_q_asks_before_quitting_and_escape_keeps_the_console_running(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("q")
        assert isinstance(app.screen, ConfirmModal)
        await pilot.press("enter")
        assert app.is_running and isinstance(app.screen, FleetScreen), "Enter on a reflex is Cancel"
        await pilot.press("q", "escape")
        assert app.is_running and isinstance(app.screen, FleetScreen)
        await pilot.press("q", "tab", "enter")
        await wait_for(pilot, lambda: not app.is_running)
        assert app.return_value == 0


async def test_quitting_while_armed_says_so_and_disarms_on_the_record(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter", "a")
        arming = app.ops.ops("DRS1").arming  # type: ignore[union-attr]
        await wait_for(pilot, lambda: arming.status().armed)  # the ARM is written off the UI thread
        await pilot.press("q")
        body = str(app.screen.query_one(".dialog-body").render())
        assert "ARMED, will be disarmed: DRS1." in body and "Powered on and waiting for Go: DRS1." in body
        await pilot.press("tab", "enter")
        await wait_for(pilot, lambda: not app.is_running)  # it ends once the disarm is on the record
        assert arming.status().state is ArmState.DISARMED
        assert ("disarm", "console closed") in [(a.action, a.result) for a in app.store.audit("DRS1")]


async def test_no_quitting_while_go_is_being_sent(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        arming = app.ops.ops("DRS1").arming  # type: ignore[union-attr]
        now = arming.clock()  # the worker is inside fire(): the modal's flow cannot hold it here
        window, _ = arming.windows.open(
            "DRS1", arming.holder, arming.session, "EL", now, now + timedelta(minutes=1), ""
        )
        assert window is not None and arming.windows.start_firing(window.id, arming.holder, now)
        await pilot.press("q")
        await pilot.pause()
        assert app.is_running and not isinstance(app.screen, ConfirmModal)
        assert any("Go is being sent to DRS1" in n.message for n in app._notifications)


async def test_replay_quits_at_once(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app(mode="replay")
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("q")
        await pilot.pause()
        assert app.return_value == 0 and not app.is_running

"""Quitting: a commanding console asks first, never mid-Go, and closes an open ARM window on the record."""

from __future__ import annotations

from collections.abc import Callable

import pytest

from console.app import DrsConsole
from console.screens.fleet import FleetScreen
from console.screens.modals import ConfirmModal
from tests.console.conftest import wait_for, window_of_this_account

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
        await pilot.press("enter")
        window_of_this_account(app)  # as the server's ARM writes it (nobody polls the canned capsules GO)
        await wait_for(pilot, lambda: getattr(app.context.arm_state("DRS1"), "state", None) == "armed")
        await pilot.press("q")
        body = str(app.screen.query_one(".dialog-body").render())
        assert "ARMED, will be disarmed: DRS1." in body and "Powered on and waiting for Go: DRS1." in body
        await pilot.press("tab", "enter")
        await wait_for(pilot, lambda: not app.is_running)  # it ends once the server's disarm is on record
        assert ("disarm", "console closed") in [(a.action, a.result) for a in app.store.audit("DRS1")]


async def test_no_quitting_while_go_is_being_sent(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        window_of_this_account(app, firing=True)  # the server is inside fire(), for this account
        await wait_for(pilot, lambda: getattr(app.context.arm_state("DRS1"), "state", None) == "firing")
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

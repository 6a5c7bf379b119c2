"""Resolving an MT of unknown delivery from the Iridium screen (``u``), as ``drs mt resolve`` does: the
team reads the RockBLOCK portal and records what it shows without leaving the console."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from textual.pilot import Pilot
from textual.widgets import DataTable

from console.app import DrsConsole
from console.screens.iridium import IridiumScreen
from drs_link.iridium.gateway import SendResult
from drs_link.iridium.mt import MtComposer
from tests.console.conftest import wait_for


class _Refusing:
    """The gateway refused it: its delivery is known (failed), nothing to resolve."""

    def send(self, imei: str, payload: bytes, flush: bool = False) -> SendResult:
        return SendResult("failed", "gateway refused it: FAILED 10 (invalid login credentials)", code=10)


class _Unanswered:
    """The gateway's answer never came: the command's delivery is unknown until someone looks."""

    def send(self, imei: str, payload: bytes, flush: bool = False) -> SendResult:
        return SendResult("unknown", "the gateway did not answer within 30 s: it may have queued it")


def _command(app: DrsConsole, gateway: _Refusing | _Unanswered) -> int:
    assert app.ops is not None
    lifecycle = app.ops.iridium.lifecycle
    command = lifecycle.request(app.ops.state.config.capsules[1], MtComposer().add("INTERVAL", 5).build())
    return lifecycle.send(command.id, "DRS2", gateway).id  # type: ignore[arg-type]  # a stand-in gateway


async def _resolve(app: DrsConsole, pilot: Pilot[int], answer: str) -> None:
    await pilot.press("down", "i")
    screen = app.screen
    assert isinstance(screen, IridiumScreen)
    table = screen.query_one("#commands", DataTable)
    await wait_for(pilot, lambda: table.row_count == 1)
    await pilot.press("u")
    await pilot.press(*answer, "enter")


@pytest.mark.asyncio
async def test_u_records_what_the_portal_shows_and_the_audit_names_the_operator(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    command_id = _command(app, _Unanswered())
    assert app.ops is not None and app.ops.iridium.lifecycle.get(command_id).state == "delivery_unknown"
    async with app.run_test(size=(120, 40)) as pilot:
        await _resolve(app, pilot, "not sent")
        lifecycle = app.ops.iridium.lifecycle
        await wait_for(pilot, lambda: lifecycle.get(command_id).state == "not_sent")
        [row] = app.store.audit("DRS2", action="mt.resolved")
        assert row.operator == "EL" and "never reached the gateway" in str(row.detail)
        await wait_for(pilot, lambda: any("not_sent" in n.message for n in app._notifications))


@pytest.mark.asyncio
async def test_u_on_a_command_whose_delivery_is_known_is_refused_and_changes_nothing(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    command_id = _command(app, _Refusing())
    async with app.run_test(size=(120, 40)) as pilot:
        await _resolve(app, pilot, "not sent")
        await wait_for(pilot, lambda: any(n.severity == "error" for n in app._notifications))
        assert app.ops is not None and app.ops.iridium.lifecycle.get(command_id).state == "failed"
        assert app.store.audit("DRS2", action="mt.resolved") == []


@pytest.mark.asyncio
async def test_u_with_an_answer_that_is_neither_an_id_nor_not_sent_says_so(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    command_id = _command(app, _Unanswered())
    async with app.run_test(size=(120, 40)) as pilot:
        await _resolve(app, pilot, "sent")
        await wait_for(pilot, lambda: any("MT id or 'not sent'" in n.message for n in app._notifications))
        assert app.ops is not None and app.ops.iridium.lifecycle.get(command_id).state == "delivery_unknown"

"""The PARACHUTE dialog at 80×24: it fits, scrolls to whatever has the focus, Enter walks the fields and
never lands on Cancel, and a cancel says that nothing was sent (issue #23, item 7)."""

from __future__ import annotations

from pathlib import Path

import pytest
from textual.app import App
from textual.containers import VerticalScroll
from textual.widgets import Button, Input

import console.app
from console.app import DrsConsole
from console.screens.modals import HazardConfirmation, HazardModal
from tests.console.conftest import wait_for

pytestmark = pytest.mark.asyncio

CONSEQUENCE = (
    "Queues [PARACHUTE=12:06] at the gateway for DRS1. The capsule downloads it at its next report and, if "
    "the fix minute is within ±14 min, opens release B at the end of that cycle: the parachute is dropped."
)
OVERRIDE = (
    "NO LANDED EVIDENCE (NOT LANDED: last fix 12:02:07Z at 14,600 m, falling 16 m/s). Overriding drops the "
    "parachute in flight: give the reason the reports are wrong."
)


class _Host(App[None]):
    CSS_PATH = [str(Path(console.app.__file__).parent / path) for path in DrsConsole.CSS_PATH]
    """The console's own stylesheet: the dialog's size is what this test is about."""

    def __init__(self) -> None:
        super().__init__()
        self.answers: list[HazardConfirmation | None] = []

    def on_mount(self) -> None:
        modal = HazardModal(
            "DRS1",
            "PARACHUTE",
            CONSEQUENCE,
            False,
            override_prompt=OVERRIDE,
            countdown=lambda: "queue before 12:20:00Z — 840 s left",
        )
        self.push_screen(modal, self.answers.append)


def visible(widget: Input | Button, pane: VerticalScroll) -> bool:
    return pane.region.contains_region(widget.region) and widget.region.height > 0


async def test_the_parachute_dialog_fits_80x24_and_scrolls_to_the_focused_field_and_buttons() -> None:
    app = _Host()
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, HazardModal))
        pane = app.screen.query_one(VerticalScroll)
        assert pane.region.bottom <= 24 and pane.region.y >= 0, "the dialog is inside the screen"
        assert pane.max_scroll_y > 0, "taller than the screen: this test checks the scrolling"
        assert pane.max_scroll_x == 0, (
            "every line wraps inside the dialog (the override prompt ran to 161 columns)"
        )
        visited = []
        for _ in range(3):
            await pilot.press("enter")
            await pilot.pause()
            focused = app.screen.focused
            assert isinstance(focused, Input), f"Enter moved to {focused!r}, not to a field"
            visited.append(focused.id)
            assert visible(focused, pane), f"{focused.id} is out of sight"
        assert visited == ["second", "waiver", "override"]
        for button in ("cancel", "approval", "confirm"):
            await pilot.press("tab")
            await pilot.pause()
            focused = app.screen.focused
            assert isinstance(focused, Button) and focused.id == button
            assert visible(focused, pane), f"the {button} button is out of sight"


async def test_a_cancel_says_nothing_was_sent() -> None:
    app = _Host()
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: isinstance(app.screen, HazardModal))
        await pilot.press("escape")
        await wait_for(pilot, lambda: bool(app.answers))
        assert app.answers == [None]
        assert [n.message for n in app._notifications] == ["PARACHUTE DRS1 cancelled: nothing sent"]

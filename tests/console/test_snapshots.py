"""How each screen looks, at 80×24 and 160×48, from a fixed-time console (SVG snapshots).

Behaviour is tested elsewhere with Pilot; these catch layout regressions a person would see.
Refresh them with ``pytest tests/console/test_snapshots.py --snapshot-update`` and look at the diff.
"""

from __future__ import annotations

from collections.abc import Callable

import pytest
from textual.pilot import Pilot
from textual.widgets import Input

from console.app import DrsConsole

SCREENS = {
    "fleet": [],
    "release": ["enter"],
    "predictions": ["p"],
    "iridium": ["down", "i"],
    "recovery": ["down", "v"],
    "history": ["h"],
    "help": ["question_mark"],
}


async def settle(pilot: Pilot[int]) -> None:
    await pilot.app.workers.wait_for_complete()
    for widget in pilot.app.screen.query(Input):
        widget.cursor_blink = False
    await pilot.pause()


@pytest.mark.parametrize("size", [(80, 24), (160, 48)], ids=["80x24", "160x48"])
@pytest.mark.parametrize("screen", list(SCREENS))
def test_screen_snapshot(
    snap_compare: Callable[..., bool],
    canned_app: Callable[..., DrsConsole],
    screen: str,
    size: tuple[int, int],
) -> None:
    async def open_screen(pilot: Pilot[int]) -> None:
        await pilot.press(*SCREENS[screen])
        await settle(pilot)
        if hasattr(pilot.app.screen, "refresh_view"):
            pilot.app.screen.refresh_view()
        await settle(pilot)

    assert snap_compare(canned_app(), terminal_size=size, run_before=open_screen)

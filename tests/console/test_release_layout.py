"""The release screen at 80×24: checklist and go/no-go stacked, no reason cut off, the whole step in words."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from textual.pilot import Pilot
from textual.widgets import DataTable

from console.app import DrsConsole
from console.screens.release import ReleaseScreen

pytestmark = pytest.mark.asyncio


async def open_release(pilot: Pilot[int]) -> ReleaseScreen:
    await pilot.press("enter")
    await pilot.pause()
    screen = pilot.app.screen
    assert isinstance(screen, ReleaseScreen)
    return screen


async def test_at_80_columns_every_go_no_go_reason_is_readable_without_scrolling(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        screen = await open_release(pilot)
        assert screen.has_class("-narrow")
        gonogo = screen.query_one("#gonogo", DataTable)
        assert gonogo.virtual_size.width <= gonogo.scrollable_content_region.width
        assert gonogo.virtual_size.height <= gonogo.scrollable_content_region.height, "an item is hidden"
        report = app.gonogo("DRS1")
        shown = " ".join(str(gonogo.get_row_at(i)[2]) for i in range(gonogo.row_count))
        for item in report.items:
            assert item.detail in shown


async def test_the_highlighted_step_is_shown_whole_below_the_checklist(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        screen = await open_release(pilot)
        checklist = app.checklists[screen.checklist_index]
        detail = screen.query_one("#step-detail")
        for row in range(4):
            if row:
                await pilot.press("down")
            step = checklist.steps[row]
            words = " ".join(str(detail.render()).split())
            assert " ".join(step.text.split()) in words, (step.text, words)


async def test_wide_terminals_keep_the_checklist_and_go_no_go_side_by_side(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(160, 48)) as pilot:
        screen = await open_release(pilot)
        assert screen.has_class("-wide")
        assert screen.query_one("#checklist-pane").region.y == screen.query_one("#gonogo-pane").region.y

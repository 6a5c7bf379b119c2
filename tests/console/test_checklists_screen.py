"""The checklists overview: every capsule's procedures in one read-only table, fed by the store."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from textual.widgets import DataTable, Markdown, Static

from console.app import DrsConsole
from console.screens.checklists import ChecklistsScreen
from drs_link.ops import ChecklistRun
from drs_link.store import Store
from tests.console.conftest import T0, wait_for

pytestmark = pytest.mark.asyncio


def finished(app: DrsConsole, capsule: str, checklist_id: str) -> tuple[int, int, str]:
    """What the release screen's statuses say of one checklist: finished, total, the next open step."""
    checklist = next(c for c in app.checklists if c.id == checklist_id)
    statuses = app.context.step_statuses(capsule, checklist, app.fleet.capsules[capsule].facts(app.now()))
    open_steps = [s.step.id for s in statuses if not s.finished]
    return len(statuses) - len(open_steps), len(statuses), open_steps[0]


async def test_c_shows_every_capsules_checklists_with_their_progress_and_next_step(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("c")
        screen = app.screen
        assert isinstance(screen, ChecklistsScreen)
        table = screen.query_one("#checklists", DataTable)
        assert table.row_count == 3 * len(app.checklists)
        done, total, next_step = finished(app, "DRS1", "release-day")
        row = [str(cell) for cell in table.get_row("DRS1/release-day")]
        assert row[:3] == ["DRS1", "Release day", f"{done}/{total}"] and row[4] == next_step
        assert table.virtual_size.width <= table.scrollable_content_region.width, "a column is off screen"


async def test_a_step_ticked_by_another_console_shows_without_a_key(
    canned_app: Callable[..., DrsConsole],
) -> None:
    """The overview is read-only and follows the server: the app redraws it when the audit moves on."""
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("c")
        screen = app.screen
        assert isinstance(screen, ChecklistsScreen)
        table = screen.query_one("#checklists", DataTable)
        detail = screen.query_one("#checklists-detail", Static)
        done, total, next_step = finished(app, "DRS1", "preflight")
        checklist = next(c for c in app.checklists if c.id == "preflight")
        assert str(table.get_row("DRS1/preflight")[2]) == f"{done}/{total}"
        shown = str(detail.render())
        assert f"▸ DRS1 · {checklist.title}" in shown and checklist.step(next_step).text in shown, (
            "the first row is highlighted"
        )
        audit = len(app.store.audit())
        await pilot.press("space", "x", "enter")
        await app.workers.wait_for_complete()  # a key's write runs in a worker (write_off_ui)
        await pilot.pause()
        assert app.screen is screen and len(app.store.audit()) == audit, "a key changed a checklist"
        other = Store.open(app.store.path)  # another writer of the store: no key, no call of this console
        ChecklistRun(other, checklist, "DRS1", lambda: T0).tick(next_step, "JR")
        await wait_for(pilot, lambda: str(table.get_row("DRS1/preflight")[2]) == f"{done + 1}/{total}")
        assert checklist.step(next_step).text not in str(detail.render())


async def test_the_palette_and_the_help_offer_the_checklists_from_the_registry(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app(now=T0)
    async with app.run_test(size=(120, 40)) as pilot:
        assert "Checklists" in [command.title for command in app.get_system_commands(app.screen)]
        await pilot.press("question_mark")
        help_text = " ".join(str(block.source) for block in app.screen.query(Markdown))
        assert "`c` checklists" in help_text and "**Checklists**:" in help_text

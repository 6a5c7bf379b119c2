"""No text cut off: the banner's operator and every footer key at 80×24, the MT detail at 120×40.

(The checklist's "By / when" column is in test_screens.py, beside the other release tests.)
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

import pytest
from textual.widgets import DataTable
from textual.widgets._footer import FooterKey

from console.app import DrsConsole
from console.screens.iridium import IridiumScreen
from console.widgets.banner import ModeBanner, banner_line
from drs_link.iridium.gateway import SendResult
from drs_link.iridium.mt import MtComposer
from tests.console.conftest import T0, wait_for

DEMO = "DEMO — simulated capsules, gateway and weather"


@pytest.mark.parametrize("width", [160, 80, 60, 50])
def test_the_banner_gives_up_the_description_before_the_mode_note_or_operator(width: int) -> None:
    line = banner_line(DEMO, "×4 time", datetime(2026, 9, 1, 12, 0), "Elin Lund", width)
    assert len(line) <= width
    assert line.startswith(" DEMO") and "×4 time" in line and line.endswith("│ operator Elin Lund")
    assert "12:00:00Z" in line


def test_a_banner_that_cannot_fit_is_cut_at_its_end_with_an_ellipsis() -> None:
    line = banner_line(DEMO, "×4 time", datetime(2026, 9, 1, 12, 0), "Elin Lund", 24)
    assert line == " DEMO ×4 time │ 12:00:0…"


@pytest.mark.asyncio
async def test_the_demo_banner_shows_the_operator_at_80_columns(
    canned_app: Callable[..., DrsConsole],
) -> None:
    """The demo's line ran past 80 columns, and the terminal cut the operator's name."""
    app = canned_app(mode="demo")
    async with app.run_test(size=(80, 24)) as pilot:
        banner = app.screen.query_one(ModeBanner)
        await wait_for(pilot, lambda: str(banner.render()).endswith(f"│ operator {app.operator}"))
        shown = str(banner.render())
        assert shown.startswith(" DEMO") and len(shown) <= 80


class _Refusing:
    """A gateway that refuses, as RockBLOCK does for a wrong password: its answer is the detail."""

    def send(self, imei: str, payload: bytes, flush: bool = False) -> SendResult:
        return SendResult(
            "failed",
            "gateway refused it: FAILED 10 (invalid login credentials): check [rockblock] username and the "
            "password in the environment variable it names, then request the command again",
            code=10,
        )


@pytest.mark.asyncio
async def test_the_mt_detail_is_shown_whole_at_120x40(canned_app: Callable[..., DrsConsole]) -> None:
    """It was cut at 60 characters: a refusal's reason lost its second half."""
    app = canned_app(now=T0)
    assert app.ops is not None
    lifecycle = app.ops.iridium.lifecycle
    command = lifecycle.request(app.ops.state.config.capsules[1], MtComposer().add("INTERVAL", 5).build())
    failed = lifecycle.send(command.id, "DRS2", _Refusing())  # type: ignore[arg-type]
    assert len(failed.detail) > 120
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("down", "i")
        screen = app.screen
        assert isinstance(screen, IridiumScreen)
        table = screen.query_one("#commands", DataTable)
        await wait_for(pilot, lambda: table.row_count == 1)
        assert " ".join(str(table.get_row_at(0)[-1]).split()) == failed.detail
        assert table.virtual_size.width <= table.scrollable_content_region.width, "a column is off screen"
        assert table.rows[next(iter(table.rows))].height > 1, "the detail wraps instead of being cut"


@pytest.mark.parametrize(
    "keys",
    [[], ["enter"], ["p"], ["down", "i"], ["down", "v"], ["h", "enter"]],
    ids=["fleet", "release", "predictions", "iridium", "recovery", "history"],
)
@pytest.mark.asyncio
async def test_every_footer_key_is_whole_at_80x24(
    canned_app: Callable[..., DrsConsole], keys: list[str]
) -> None:
    """The palette hint, docked right, covered "q Quit" on release and Iridium, "Help" on recovery.

    The footer is looked at once it is laid out (its "Quit" has a width): under two CPU hogs one pause
    after the keys once found no key laid out yet."""
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press(*keys)
        await app.workers.wait_for_complete()
        await wait_for(
            pilot,
            lambda: any(k.description == "Quit" and k.region.width for k in app.screen.query(FooterKey)),
        )
        shown = [key for key in app.screen.query(FooterKey) if key.display and key.region.width]
        palette = [key for key in shown if key.has_class("-command-palette")]
        edge = palette[0].region.x if palette else 80
        keys_shown = [key for key in shown if key not in palette]
        assert keys_shown and all(key.region.right <= edge for key in keys_shown), [
            (key.description, key.region) for key in keys_shown if key.region.right > edge
        ]
        assert keys_shown[-1].description == "Quit", "the last key is hidden"

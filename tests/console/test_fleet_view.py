"""The fleet view at 80×24 and larger: a table that never scrolls sideways, and the full words below it.

Pilot runs the real app on the canned fleet (DRS1 powered with a fix and a prediction, DRS2 idle and
half synced with landed Iridium reports from the store, DRS3 with a link and release state 95 s old,
so stale). Expected words are derived from the telemetry records, never copied from the screen.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import timedelta
from pathlib import Path

import pytest
from rich.cells import cell_len
from rich.text import Text
from textual.geometry import Region
from textual.widget import Widget
from textual.widgets import Footer

from console.app import ConsoleSetup, DrsConsole
from console.screens.fleet import FleetScreen
from console.widgets.capsule_detail import CapsuleDetail
from console.widgets.cells import FIELDS, age_shown
from console.widgets.fleet_table import FleetTable
from drs_link.ops.staleness import STALE_GLYPH, format_age
from drs_link.ops.telemetry import (
    GnssSample,
    LinkSample,
    PredictionSample,
    ReportSample,
    SyncSample,
    TelemetryRecord,
)
from tests.console.conftest import T0, canned_records, offline_config, offline_server, wait_for

pytestmark = pytest.mark.asyncio
SIZES = [(80, 24), (160, 48)]


def painted(widget: Widget) -> str:
    """What the widget shows on screen, wrapped lines joined and runs of spaces collapsed."""
    width, height = widget.outer_size
    lines = [strip.text for strip in widget.render_lines(Region(0, 0, width, height))]
    return " ".join(" ".join(lines).split())


def with_reports(app: DrsConsole) -> DrsConsole:
    """DRS2's landed Iridium reports, read from the store as the console's report poll reads them."""
    assert app.ops is not None
    reports = app.ops.iridium.new_reports("DRS2")
    assert reports
    for record in reports:
        app.fleet.apply(record)
    return app


def table_of(app: DrsConsole) -> FleetTable:
    return app.screen.query_one("#fleet", FleetTable)


def detail_of(app: DrsConsole) -> CapsuleDetail:
    return app.screen.query_one("#fleet-detail", CapsuleDetail)


def shown_kinds(table: FleetTable) -> list[str]:
    return [str(column.key.value) for column in table.ordered_columns]


def assert_fits(table: FleetTable) -> None:
    """No sideways scrolling: the columns are no wider than what the table shows, and no cell is cut."""
    assert table.virtual_size.width <= table.scrollable_content_region.width
    assert table.max_scroll_x == 0
    for row in range(table.row_count):
        for column, value in zip(table.ordered_columns, table.get_row_at(row), strict=True):
            text = value.plain if isinstance(value, Text) else str(value)
            assert cell_len(text) <= column.content_width, (column.key.value, text)


@pytest.mark.parametrize("size", SIZES, ids=["80x24", "160x48"])
async def test_the_table_fits_its_width_and_shows_every_column_that_fits(
    canned_app: Callable[..., DrsConsole], size: tuple[int, int]
) -> None:
    app = with_reports(canned_app())
    async with app.run_test(size=size) as pilot:
        table = table_of(app)
        await wait_for(pilot, lambda: table.shown is not None)
        assert_fits(table)
        kinds = shown_kinds(table)
        assert kinds == ["capsule", *(f.kind for f in FIELDS[: len(kinds) - 1])]
        if len(kinds) - 1 < len(FIELDS):
            following = FIELDS[len(kinds) - 1]
            room = table.scrollable_content_region.width - table.virtual_size.width
            assert following.width + 2 * table.cell_padding > room
        if size == (160, 48):
            assert kinds == ["capsule", *(f.kind for f in FIELDS)]
        else:
            assert {"link", "release", "gnss"} <= set(kinds) and "prediction" not in kinds


async def test_every_part_of_the_screen_shows_at_80x24_with_eight_capsules(
    tmp_path: Path, canned_prediction: list[TelemetryRecord], request: pytest.FixtureRequest
) -> None:
    names = [f"DRS{n}" for n in range(1, 9)]
    server = offline_server(offline_config(tmp_path), request)
    setup = ConsoleSetup(mode="replay", capsules=names, server=server, clock=lambda: T0)
    app = DrsConsole(setup, live_timers=False)
    for record in canned_records(canned_prediction):
        app.fleet.apply(record)
    async with app.run_test(size=(80, 24)) as pilot:
        table = table_of(app)
        await wait_for(pilot, lambda: table.shown is not None)
        screen = app.screen.region
        for widget in (
            app.screen.query_one("#banner"),
            table,
            detail_of(app),
            app.screen.query_one("#balloon"),
        ):
            assert widget.region.height > 0 and screen.contains_region(widget.region), widget.id
        footer = app.screen.query_one(Footer)
        assert footer.region.height > 0 and screen.contains_region(footer.region)
        assert table.region.height - table.header_height >= 6
        shown = painted(detail_of(app))
        prediction = app.fleet.capsules["DRS1"].reading(PredictionSample).value
        assert prediction is not None
        assert all(field.label in shown for field in FIELDS)
        assert f"model {prediction.model} —" in shown, "the last line of the detail is cut"
        assert_fits(table)


async def test_the_detail_shows_the_prediction_and_battery_of_the_highlighted_capsule_in_full(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = with_reports(canned_app())
    async with app.run_test(size=(80, 24)) as pilot:
        detail = detail_of(app)
        prediction = app.fleet.capsules["DRS1"].reading(PredictionSample).value
        assert prediction is not None
        landing = (
            f"Prediction landing {prediction.landing_lat:.3f}, {prediction.landing_lon:.3f}, "
            f"{prediction.distance_km:.1f} km at {prediction.bearing_deg:.0f}° from release"
        )
        age = format_age(app.fleet.capsules["DRS1"].reading(PredictionSample).age_s(app.now()) or 0.0)
        sigmas = (
            f"σ∥ {prediction.sigma_par_km:.2f} σ⊥ {prediction.sigma_perp_km:.2f} km;"
            f" position from {prediction.origin_source}; model {prediction.model} — {age} ago"
        )
        await wait_for(pilot, lambda: landing in painted(detail))
        assert sigmas in painted(detail)
        assert "Battery/MO — nothing received yet" in painted(detail)

        await pilot.press("down")
        report = app.fleet.capsules["DRS2"].reading(ReportSample).value
        assert report is not None
        battery = f"Battery/MO {report.vbat:.2f} V, {report.alt_m / 1000:.1f} km, landed"
        await wait_for(pilot, lambda: battery in painted(detail))
        assert f"MO #{report.momsn}" in painted(detail)


async def test_moving_the_cursor_changes_the_detail(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        detail = detail_of(app)
        await wait_for(pilot, lambda: detail.border_title == "DRS1")
        before = painted(detail)
        assert "Release powered, NMEA arriving" in before
        await pilot.press("down")
        await wait_for(pilot, lambda: detail.border_title == "DRS2")
        after = painted(detail)
        sync = app.fleet.capsules["DRS2"].reading(SyncSample).value
        assert sync is not None
        assert f"Sync {sync.fraction:.0%} synced" in after and "Release idle, not powered" in after
        assert after != before
        assert isinstance(app.screen, FleetScreen) and app.screen.selected() == "DRS2"


async def test_a_stale_value_shows_the_glyph_in_the_table_and_stale_in_words_below(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    now = app.now()
    link = app.fleet.capsules["DRS3"].reading(LinkSample)
    assert not link.is_fresh(now) and app.fleet.capsules["DRS1"].reading(LinkSample).is_fresh(now)
    async with app.run_test(size=(80, 24)) as pilot:
        table = table_of(app)
        await wait_for(pilot, lambda: table.shown is not None)
        stale = table.get_cell("DRS3", "link")
        fresh = table.get_cell("DRS1", "link")
        assert isinstance(stale, Text) and isinstance(fresh, Text)
        assert stale.plain.startswith(STALE_GLYPH) and not fresh.plain.startswith(STALE_GLYPH)
        assert stale.style != fresh.style
        await pilot.press("down", "down")
        detail = detail_of(app)
        await wait_for(pilot, lambda: detail.border_title == "DRS3")
        shown = painted(detail)
        age = format_age(age_shown(link.age_s(now) or 0.0))  # an old age is shown in 10 s steps
        assert f"Link up — {STALE_GLYPH}STALE {age} ago" in shown
        assert f"RAID degraded — {age} ago" in shown, "storage is as old, but within twice its longer period"


async def test_a_resize_from_160_to_80_columns_rebuilds_the_columns(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(160, 48)) as pilot:
        table = table_of(app)
        await wait_for(pilot, lambda: table.shown is not None)
        wide = shown_kinds(table)
        await pilot.press("down")
        await pilot.resize_terminal(80, 24)
        await wait_for(pilot, lambda: shown_kinds(table) != wide)
        narrow = shown_kinds(table)
        assert len(narrow) < len(wide) and narrow == wide[: len(narrow)]
        assert_fits(table)
        assert isinstance(app.screen, FleetScreen) and app.screen.selected() == "DRS2"
        assert all(table.get_cell(name, "link").plain != "—" for name in ("DRS1", "DRS2", "DRS3"))
        await pilot.resize_terminal(160, 48)
        await wait_for(pilot, lambda: shown_kinds(table) == wide)
        assert_fits(table)


async def test_the_cell_colours_follow_the_theme(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        table = table_of(app)
        await wait_for(pilot, lambda: table.shown is not None)

        def colour() -> str:
            cell = table.get_cell("DRS2", "link")
            assert isinstance(cell, Text) and cell.style and not isinstance(cell.style, str)
            assert cell.style.color is not None and cell.style.color.triplet is not None
            return cell.style.color.triplet.hex.upper()

        assert colour() == app.get_css_variables()["text-success"].upper()
        await pilot.press("t")
        await wait_for(pilot, lambda: colour() == app.get_css_variables()["text-success"].upper())
        assert app.theme == "textual-light"


async def test_an_unreadable_value_is_named_and_the_view_keeps_running(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    app.fleet.apply(
        TelemetryRecord(T0 - timedelta(seconds=1), "DRS2", GnssSample(has_fix=True, hdop="0.9"))  # type: ignore[arg-type]
    )
    async with app.run_test(size=(80, 24)) as pilot:
        table = table_of(app)
        await wait_for(pilot, lambda: table.shown is not None)
        assert table.get_cell("DRS2", "gnss").plain == "BAD DATA 1s"
        await pilot.press("down")
        detail = detail_of(app)
        await wait_for(pilot, lambda: detail.border_title == "DRS2")
        assert "GNSS unreadable gnss data (" in painted(detail)
        assert isinstance(app.screen, FleetScreen) and table.get_cell("DRS1", "gnss").plain.startswith("9sv")

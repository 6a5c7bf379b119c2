"""The fleet view: a status table that fits the terminal, and every field of the highlighted capsule below it."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Static

from console.screens.base import ConsoleScreen
from console.screens.registry import SCREENS, screen_entry
from console.widgets import CapsuleDetail, FleetTable, balloon_lines, set_content


class FleetScreen(ConsoleScreen):
    BINDINGS = [
        Binding(
            entry.key, f"open({entry.title!r})", entry.footer or entry.title, show=entry.footer is not None
        )
        for entry in SCREENS
    ]
    """A key for every screen in the registry (``console.screens.registry``), in its order."""

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        yield FleetTable(self.context.setup.capsules, id="fleet")
        yield CapsuleDetail(id="fleet-detail")
        yield Static(id="balloon", markup=False)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        table = self.query_one("#fleet", FleetTable)
        table.zebra_stripes = not self.context.setup.low_bandwidth  # a colour that carries no meaning
        table.focus()
        self.watch(self.app, "theme", self._theme_changed, init=False)
        self.refresh_view()

    def _theme_changed(self) -> None:
        """Cells carry colours resolved from the stylesheet: redraw them once the new theme applies."""
        self.call_after_refresh(self.refresh_view)

    def update_view(self) -> None:
        context = self.context
        now = context.view_time()
        self.query_one("#fleet", FleetTable).show(context.fleet.capsules, now)
        self.show_detail()
        feed = context.setup.balloon_feed
        lines = balloon_lines(context.fleet.balloon, feed.status() if feed else None, now)
        set_content(self.query_one("#balloon", Static), "\n".join(lines))

    def show_detail(self) -> None:
        telemetry = self.context.fleet.capsules[self.selected()]
        self.query_one("#fleet-detail", CapsuleDetail).show(telemetry, self.context.view_time())

    def selected(self) -> str:
        table = self.query_one("#fleet", FleetTable)
        return self.context.setup.capsules[max(0, table.cursor_row)]

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if self.ready:
            self.show_detail()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        """Enter on a row reaches the table first: it opens the release screen, as the footer says."""
        self.action_open("Release")

    def action_open(self, title: str) -> None:
        """Open the registry's screen called ``title``, for the highlighted capsule if it shows one."""
        self.app.push_screen(screen_entry(title).build(self.context, self.selected()))

"""The fleet view: a status table that fits the terminal, and every field of the highlighted capsule below it."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Static

from console.screens.base import ConsoleScreen
from console.widgets.capsule_detail import CapsuleDetail
from console.widgets.cells import balloon_lines
from console.widgets.fleet_table import FleetTable
from console.widgets.quiet import set_content


class FleetScreen(ConsoleScreen):
    BINDINGS = [
        Binding("enter,r", "release", "Release"),
        Binding("p", "predictions", "Predict"),
        Binding("i", "iridium", "Iridium"),
        Binding("v", "recovery", "Recovery"),
        Binding("h", "history", "History"),
        Binding("A", "approvals", "Approvals", show=False),
    ]

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        yield FleetTable(self.console.setup.capsules, id="fleet")
        yield CapsuleDetail(id="fleet-detail")
        yield Static(id="balloon", markup=False)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        table = self.query_one("#fleet", FleetTable)
        table.zebra_stripes = not self.console.setup.low_bandwidth  # a colour that carries no meaning
        table.focus()
        self.watch(self.app, "theme", self._theme_changed, init=False)
        self.refresh_view()

    def _theme_changed(self) -> None:
        """Cells carry colours resolved from the stylesheet: redraw them once the new theme applies."""
        self.call_after_refresh(self.refresh_view)

    def update_view(self) -> None:
        app = self.console
        now = app.view_time()
        self.query_one("#fleet", FleetTable).show(app.fleet.capsules, now)
        self.show_detail()
        feed = app.setup.balloon_feed
        lines = balloon_lines(app.fleet.balloon, feed.status() if feed else None, now)
        set_content(self.query_one("#balloon", Static), "\n".join(lines))

    def show_detail(self) -> None:
        telemetry = self.console.fleet.capsules[self.selected()]
        self.query_one("#fleet-detail", CapsuleDetail).show(telemetry, self.console.view_time())

    def selected(self) -> str:
        table = self.query_one("#fleet", FleetTable)
        return self.console.setup.capsules[max(0, table.cursor_row)]

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if self.ready:
            self.show_detail()

    def on_data_table_row_selected(self, event: DataTable.RowSelected) -> None:
        self.action_release()

    def action_release(self) -> None:
        from console.screens.release import ReleaseScreen

        self.app.push_screen(ReleaseScreen(self.selected()))

    def action_predictions(self) -> None:
        from console.screens.predictions import PredictionScreen

        self.app.push_screen(PredictionScreen(self.selected()))

    def action_iridium(self) -> None:
        from console.screens.iridium import IridiumScreen

        self.app.push_screen(IridiumScreen(self.selected()))

    def action_approvals(self) -> None:
        from console.screens.approvals import ApprovalScreen

        self.app.push_screen(ApprovalScreen())

    def action_recovery(self) -> None:
        from console.screens.recovery import RecoveryScreen

        self.app.push_screen(RecoveryScreen(self.selected()))

    def action_history(self) -> None:
        from console.screens.history import HistoryScreen

        self.app.push_screen(HistoryScreen())

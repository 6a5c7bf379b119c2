"""The fleet view: one row per capsule, every value with its age, stale values marked in words."""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Static

from console.screens.base import ConsoleScreen
from console.widgets.cells import COLUMNS


class FleetScreen(ConsoleScreen):
    BINDINGS = [
        Binding("enter,r", "release", "Release"),
        Binding("p", "predictions", "Predict"),
        Binding("i", "iridium", "Iridium"),
        Binding("v", "recovery", "Recovery"),
        Binding("h", "history", "History"),
    ]

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        yield DataTable(id="fleet", cursor_type="row", zebra_stripes=True)
        yield Static(id="balloon", markup=False)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        table = self.query_one("#fleet", DataTable)
        for title, _, width in COLUMNS:
            table.add_column(title, key=title, width=width)
        for name in self.console.setup.capsules:
            table.add_row(name, *["—"] * (len(COLUMNS) - 1), key=name)
        table.focus()
        self.refresh_view()

    def update_view(self) -> None:
        app = self.console
        now = app.now()
        table = self.query_one("#fleet", DataTable)
        for name in app.setup.capsules:
            telemetry = app.fleet.capsules[name]
            for title, render, _ in COLUMNS[1:]:
                table.update_cell(name, title, render(telemetry, now))
        balloon = app.fleet.balloon
        text = "Balloon: " + balloon.label(
            now, lambda v: f"{v['lat']:.4f}, {v['lon']:.4f} at {v['alt_m'] / 1000:.1f} km"
        )
        self.query_one("#balloon", Static).update(text)

    def selected(self) -> str:
        table = self.query_one("#fleet", DataTable)
        return self.console.setup.capsules[max(0, table.cursor_row)]

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

    def action_recovery(self) -> None:
        from console.screens.recovery import RecoveryScreen

        self.app.push_screen(RecoveryScreen(self.selected()))

    def action_history(self) -> None:
        from console.screens.history import HistoryScreen

        self.app.push_screen(HistoryScreen())

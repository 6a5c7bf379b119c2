"""The audit log: every step anyone took, searchable, exportable as JSON lines."""

from __future__ import annotations

import json

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Input

from console.screens.base import ConsoleScreen
from drs_link.store import iso_utc

HISTORY_ROWS = 500


class HistoryScreen(ConsoleScreen):
    BINDINGS = [Binding("escape", "app.pop_screen", "Back"), Binding("e", "export", "Export")]

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        yield Input(placeholder="search the audit log (action, result, operator, detail)", id="search")
        yield DataTable(id="audit", cursor_type="row", zebra_stripes=True)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        self.query_one("#audit", DataTable).add_columns("Time (UTC)", "Operator", "Capsule", "Action", "Result")
        self.fill("")
        self.query_one("#audit", DataTable).focus()

    def fill(self, text: str) -> None:
        table = self.query_one("#audit", DataTable)
        table.clear()
        for record in reversed(self.console.store.audit(text=text or None, limit=HISTORY_ROWS)):
            table.add_row(
                f"{record.time_utc:%m-%d %H:%M:%S}", record.operator, record.capsule or "", record.action,
                record.result,
            )  # fmt: skip

    def on_input_changed(self, event: Input.Changed) -> None:
        self.fill(event.value)

    def action_export(self) -> None:
        text = self.query_one("#search", Input).value or None
        directory = self.console.setup.export_dir
        directory.mkdir(parents=True, exist_ok=True)
        path = directory / f"audit-{self.console.now():%Y%m%dT%H%M%SZ}.jsonl"
        with path.open("w", encoding="utf-8") as out:
            for r in self.console.store.audit(text=text):
                out.write(json.dumps({"time_utc": iso_utc(r.time_utc), "operator": r.operator, "capsule": r.capsule,
                                      "action": r.action, "result": r.result, "detail": r.detail}) + "\n")  # fmt: skip
        self.app.notify(f"audit exported to {path}")

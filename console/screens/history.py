"""The audit log: every step anyone took, searchable, exportable as JSON lines.

The search box has the focus on entry, so whatever the operator types searches: a stray letter
must never fire a key (typing "alone" once wrote an export through its ``e``). ``↓``, ``Enter``
or ``Tab`` move to the entries, where ``e`` exports; the highlighted entry's detail (a waiver's
reason, a refusal's reason) is shown in full below them. The entries come from the operations server
(a replay: this machine's ``drs_link.ops.AuditLog``), never from the store itself; the export is
written by the console, so the file is the operator's own.
"""

from __future__ import annotations

import json
from typing import Any

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Input, Static

from console.context import ConsoleContext
from console.screens.base import ConsoleScreen
from drs_link.errors import LinkError
from drs_link.ops import AuditRecord

COLUMNS = ("Time (UTC)", "Operator", "Capsule", "Action", "Result")
DETAIL_MIN_WIDTH = 12
"""Narrower than this, the table has no detail column: the pane below the table shows it in full."""


def detail_words(detail: dict[str, Any] | None) -> str:
    """An entry's detail as ``key: value`` pairs, nested values as compact JSON."""
    if not detail:
        return "no detail"
    return " · ".join(
        f"{key}: {value if isinstance(value, str) else json.dumps(value, separators=(',', ':'))}"
        for key, value in detail.items()
    )


HELP = """\
type to search (the search box has the focus) · `↓`/`Enter` the entries, the highlighted
one's detail (reasons) below · `e` export JSONL (from the entries)"""
"""The keys, as the help screen lists them (``console.screens.registry``)."""


class HistoryScreen(ConsoleScreen):
    BINDINGS = [
        Binding("escape", "app.pop_screen", "Back"),
        Binding("e", "export", "Export"),
        Binding("down", "entries", "Entries", show=False),
    ]

    def __init__(self, context: ConsoleContext) -> None:
        super().__init__(context)
        self.records: dict[int, AuditRecord] = {}

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        yield Input(placeholder="type to search the audit log · ↓ or Enter: the entries (e exports)",
                    id="search")  # fmt: skip
        yield DataTable(id="audit", cursor_type="row", zebra_stripes=True)
        yield Static(id="audit-detail", markup=False)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        # set_focus now, not focus(): that is queued, so a ↓ read meanwhile moved to the entries and the
        # queued focus then took it back to the search box (the tmux test, a quiet fresh clone).
        self.set_focus(self.query_one("#search", Input))
        self.call_after_refresh(self.fill, "")  # once laid out: the detail column's width needs the table's

    def on_resize(self) -> None:
        if self.ready:
            self.fill(self.query_one("#search", Input).value)

    def fill(self, text: str) -> None:
        """The entries matching ``text``, newest first, in columns as wide as their words.

        The detail column takes the width that is left (so the table never scrolls sideways); each
        entry's detail is also shown whole below the table when it is highlighted.
        """
        table = self.query_one("#audit", DataTable)
        try:
            self.records = {r.id: r for r in self.context.history.newest(text)}
        except LinkError as exc:
            self.app.notify(f"the audit log cannot be read: {exc}", severity="error")
            return
        rows = [
            (f"{r.time_utc:%m-%d %H:%M:%S}", r.operator, r.capsule or "", r.action, r.result)
            for r in self.records.values()
        ]
        widths = [max([len(title), *(len(row[i]) for row in rows)]) for i, title in enumerate(COLUMNS)]
        padding = 2 * table.cell_padding * (len(COLUMNS) + 1) + table.styles.scrollbar_size_vertical
        detail_width = table.size.width - sum(widths) - padding
        table.clear(columns=True)
        for title, width in zip(COLUMNS, widths, strict=True):
            table.add_column(title, width=width)
        if detail_width >= DETAIL_MIN_WIDTH:
            table.add_column("Detail", width=detail_width)
        for row, record in zip(rows, self.records.values(), strict=True):
            details = (detail_words(record.detail),) if detail_width >= DETAIL_MIN_WIDTH else ()
            table.add_row(*row, *details, key=str(record.id))
        self.show_detail()

    def show_detail(self) -> None:
        """The highlighted entry in full: the table's detail column is cut to one line."""
        table = self.query_one("#audit", DataTable)
        if not table.row_count:
            self.query_one("#audit-detail", Static).update("no entry matches")
            return
        row_key = table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value
        record = self.records[int(str(row_key))]
        # Another console's entry names that console (account@host pid): two consoles once ARMED one
        # capsule and History could not tell their entries apart (#23).
        session = self.context.history.elsewhere(record)
        elsewhere = f" · from another console: {session}" if session else ""
        self.query_one("#audit-detail", Static).update(
            f"▸ {record.time_utc:%Y-%m-%d %H:%M:%S}Z {record.operator} {record.capsule or '—'} {record.action} "
            f"{record.result}{elsewhere}\n  {detail_words(record.detail)}"
        )

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if self.ready:
            self.show_detail()

    def on_input_changed(self, event: Input.Changed) -> None:
        self.fill(event.value)

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.action_entries()

    def action_entries(self) -> None:
        # Focus moves now, not after the keys already read: Widget.focus() is queued behind them, so a
        # quick ↓ q typed together put the q in the search box (seen in the tmux test under load). A q
        # read before ↓ has bubbled up to this binding still goes to the search box, where it only searches.
        self.set_focus(self.query_one("#audit", DataTable))

    def action_export(self) -> None:
        text = self.query_one("#search", Input).value or None
        path = self.context.setup.export_dir / f"audit-{self.context.now():%Y%m%dT%H%M%SZ}.jsonl"
        try:
            self.context.history.export(path, text)
        except (OSError, LinkError) as exc:
            self.app.notify(f"audit export failed: {exc}", severity="error")
            return
        self.app.notify(f"audit exported to {path}")

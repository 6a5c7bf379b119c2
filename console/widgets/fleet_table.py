"""The fleet table: one row per capsule, as many status columns as its width holds, never scrolling sideways.

Operators work over SSH at 80×24, where a table that scrolls sideways hides the columns to the right
and crops the cells at its edge. So the columns are taken in priority order (``FIELDS``) while they
fit, each at a fixed width that holds its widest stale short form, and re-chosen whenever the table
is resized; what does not fit is in the detail pane below.
"""

from __future__ import annotations

from collections.abc import Mapping, Sequence
from datetime import datetime

from rich.cells import cell_len
from rich.text import Text
from textual import events
from textual.widgets import DataTable

from console.widgets.cells import FIELDS, LEVEL_CLASSES, Field
from console.widgets.quiet import set_cell
from drs_link.ops import MISSING_TEXT, CapsuleTelemetry

NAME_TITLE = "Capsule"


def fitting_fields(available: int, name_width: int, cell_padding: int) -> tuple[Field, ...]:
    """The longest prefix of ``FIELDS`` that fits beside the capsule name in ``available`` cells."""
    used = name_width + 2 * cell_padding
    shown: list[Field] = []
    for field in FIELDS:
        used += field.width + 2 * cell_padding
        if used > available:
            break
        shown.append(field)
    return tuple(shown)


class FleetTable(DataTable[Text | str]):
    """Rows keyed by capsule name and columns by telemetry kind, so cells are addressed by meaning."""

    COMPONENT_CLASSES = set(LEVEL_CLASSES)

    def __init__(self, capsules: Sequence[str], *, id: str | None = None) -> None:
        super().__init__(id=id, cursor_type="row", zebra_stripes=True)
        self.capsules = list(capsules)
        self.shown: tuple[Field, ...] | None = None
        """Fields shown as columns; None until the first layout gives the table a width."""
        self._telemetry: Mapping[str, CapsuleTelemetry] = {}
        self._now: datetime | None = None

    @property
    def name_width(self) -> int:
        return max([cell_len(NAME_TITLE), *(cell_len(name) for name in self.capsules)])

    def available_width(self) -> int:
        """Cells for columns: the width, less the vertical scrollbar when the rows overflow."""
        rows = len(self.capsules) + (self.header_height if self.show_header else 0)
        scrollbar = self.styles.scrollbar_size_vertical if rows > self.size.height else 0
        return self.size.width - scrollbar

    def on_resize(self, event: events.Resize) -> None:
        self.fit_columns()

    def fit_columns(self) -> None:
        fields = fitting_fields(self.available_width(), self.name_width, self.cell_padding)
        if fields != self.shown:
            self._rebuild(fields)

    def _rebuild(self, fields: tuple[Field, ...]) -> None:
        """New columns: the rows are re-added with their cells, the cursor stays on its capsule."""
        row = self.cursor_row
        self.shown = fields
        self.clear(columns=True)
        self.add_column(NAME_TITLE, key="capsule", width=self.name_width)
        for field in fields:
            self.add_column(field.title, key=field.kind, width=field.width)
        for name in self.capsules:
            self.add_row(name, *self._cells(name, fields), key=name)
        if self.capsules:
            self.move_cursor(row=min(max(row, 0), len(self.capsules) - 1))

    def _cells(self, name: str, fields: tuple[Field, ...]) -> list[Text | str]:
        telemetry = self._telemetry.get(name)
        if telemetry is None or self._now is None:
            return [Text(MISSING_TEXT) for _ in fields]
        return [field.cell(telemetry, self._now).styled(self) for field in fields]

    def show(self, telemetry: Mapping[str, CapsuleTelemetry], now: datetime) -> None:
        """Every shown cell from the fleet state at ``now`` (kept, so a rebuild can refill the rows)."""
        self._telemetry = telemetry
        self._now = now
        if not self.shown:
            return
        for name in self.capsules:
            for field, cell in zip(self.shown, self._cells(name, self.shown), strict=True):
                set_cell(self, name, field.kind, cell)

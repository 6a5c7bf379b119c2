"""Redraw only what changed: every byte the console writes crosses the operator's SSH link.

Textual repaints a widget's whole region when it is refreshed, and a refresh with layout repaints the
whole screen. The screens re-render from the fleet state every second and on every poll, so handing
Textual the same text again, or a new text with a layout it does not need, once cost 26 kB/s on an
idle fleet screen (measured with ``make bench-bytes``: 2–3 full-screen repaints a second). These
helpers hand a widget only a change, ask for layout only when the change can move other widgets, and
repaint one table cell instead of the table.
"""

from __future__ import annotations

from collections.abc import Hashable, Sequence

from rich.cells import cell_len
from rich.console import RenderableType
from rich.segment import Segment
from rich.text import Text
from textual.coordinate import Coordinate
from textual.geometry import Region
from textual.widget import Widget
from textual.widgets import DataTable, Label, Static
from textual.widgets.data_table import ColumnKey, RowKey

_SHOWN = "_quiet_shown"


def _key(content: str | Text) -> Hashable:
    """What decides whether two contents draw alike: the text and, for rich text, its styles."""
    if isinstance(content, Text):
        return (
            content.plain,
            tuple((s.start, s.end, str(s.style)) for s in content.spans),
            str(content.style),
        )
    return content


def _key_of(content: RenderableType, key: Hashable | None) -> Hashable:
    """The given key, or the content's own when it is text (a rich renderable cannot be compared)."""
    if key is not None:
        return key
    if not isinstance(content, str | Text):
        raise TypeError("a rich renderable needs the key that decides how it draws")
    return _key(content)


def _rendered(widget: Widget, content: RenderableType) -> list[list[Segment]] | None:
    """``content`` as rich wraps it at the widget's content width (None before the widget has one)."""
    width = widget.content_region.width or widget.size.width
    if width <= 0:
        return None
    console = widget.app.console
    renderable = Text(content) if isinstance(content, str) else content
    return console.render_lines(renderable, console.options.update_width(width), pad=False)


def shows(widget: Static | Label, key: Hashable) -> bool:
    """Whether the widget already shows what ``key`` describes (build nothing new if so)."""
    shown = getattr(widget, _SHOWN, None)
    return shown is not None and shown[0] == key


def set_content(widget: Static | Label, content: RenderableType, key: Hashable | None = None) -> bool:
    """Show ``content`` unless it is already shown; True when the widget was redrawn.

    A rich renderable (a grid) cannot be compared: give its ``key`` (what decides how it draws).
    Layout is asked for only when the content's height at the widget's width changes, the one way a
    new content can move other widgets.
    """
    key = _key_of(content, key)
    if shows(widget, key):
        return False
    shown = getattr(widget, _SHOWN, None)
    lines = _rendered(widget, content)
    height = -1 if lines is None else len(lines)  # not laid out yet: the first update lays it out anyway
    setattr(widget, _SHOWN, (key, height))
    widget.update(content, layout=shown is None or shown[1] != height)
    return True


def set_cell(table: DataTable, row_key: str, column_key: ColumnKey | str, value: str | Text) -> None:
    """Change one cell and repaint only that cell's region.

    ``DataTable.update_cell`` repaints the whole table; on a fleet of five rows whose ages tick every
    second that was most of the fleet screen's output. The table's caches are keyed by its update
    count, which this bumps as ``update_cell`` does (textual is pinned in pyproject.toml).
    """
    row = table.rows.get(RowKey(row_key))
    if row is None:
        table.update_cell(row_key, column_key, value)
        return
    current = table.get_cell(row_key, column_key)
    if _key(current) == _key(value):
        return
    column = table.columns[ColumnKey(column_key) if isinstance(column_key, str) else column_key]
    table._data[row.key][column.key] = value  # noqa: SLF001 - see the docstring
    table._update_count += 1  # noqa: SLF001
    row_index = table.get_row_index(row_key)
    column_index = table.get_column_index(column_key)
    table.refresh_coordinate(Coordinate(row_index, column_index))


def fill_rows(
    table: DataTable, rows: Sequence[tuple[str, Sequence[str | Text]]], auto_height: bool = False
) -> bool:
    """Show ``rows`` (key, cells) in ``table``; True when the table had to be refilled.

    With the same row keys in the same order only the changed cells are repainted (``set_cell``);
    otherwise, or when a changed cell of an ``auto_height`` table may wrap to another height, the rows
    are cleared and added again (the caller puts the cursor back).
    """
    columns = list(table.ordered_columns)
    if [key for key, _ in rows] == [str(row.key.value) for row in table.ordered_rows]:
        changed = [
            (key, column, value, current)
            for key, cells in rows
            for column, value in zip(columns, cells, strict=True)
            if _key(value) != _key(current := table.get_cell(key, column.key))
        ]
        wraps = auto_height and any(
            max(cell_len(_plain(value)), cell_len(_plain(current))) > column.content_width
            for _, column, value, current in changed
        )
        if not wraps:
            for key, column, value, _ in changed:
                set_cell(table, key, column.key, value)
            return False
    table.clear()
    for key, cells in rows:
        table.add_row(*cells, key=key, height=None if auto_height else 1)
    return True


def _plain(value: object) -> str:
    return value.plain if isinstance(value, Text) else str(value)


class LineQuietStatic(Widget):
    """A block of text or a rich renderable that repaints only its lines that changed.

    A pane whose ages tick every second (the capsule detail: one "— 7s ago" per line) repainted all of
    its region on each tick, blank rows included. This one renders the new content at its width,
    compares it line by line with what it shows, and marks only the changed lines dirty; a change of
    height asks for layout.
    """

    def __init__(self, *, id: str | None = None, classes: str | None = None) -> None:
        super().__init__(id=id, classes=classes)
        self._content: RenderableType = ""
        self._key: Hashable = None
        self._lines: list[tuple[tuple[str, str], ...]] | None = None

    def render(self) -> RenderableType:
        return self._content

    def shows(self, key: Hashable) -> bool:
        """Whether what ``key`` describes is on screen already (build nothing new if so)."""
        return self._lines is not None and key == self._key

    def show_content(self, content: RenderableType, key: Hashable | None = None) -> bool:
        """Show ``content`` (a rich renderable needs its ``key``); True when anything was repainted."""
        key = _key_of(content, key)
        if self.shows(key):
            return False
        rendered = _rendered(self, content)
        lines = (
            None if rendered is None else [tuple((s.text, str(s.style)) for s in line) for line in rendered]
        )
        previous, self._content, self._key = self._lines, content, key
        self._lines = lines
        if previous is None or lines is None or len(previous) != len(lines):
            self.refresh(layout=True)
            return True
        top = int(self.scroll_y)
        changed = [y - top for y, (old, new) in enumerate(zip(previous, lines, strict=True)) if old != new]
        width = self.content_region.width or self.size.width
        self.refresh(*(Region(0, y, width, 1) for y in changed if 0 <= y < self.content_region.height))
        return True

"""Everything known about one capsule in full words, one field a line: what the narrow table leaves out.

The fleet table shows short forms and only the columns that fit; this pane shows every field of
the highlighted capsule, each with its age and STALE spelled out, so nothing is hidden at 80×24.
"""

from __future__ import annotations

from datetime import datetime

from rich.table import Table

from console.widgets.cells import FIELDS, LEVEL_CLASSES
from console.widgets.quiet import LineQuietStatic
from drs_link.ops import CapsuleTelemetry


class CapsuleDetail(LineQuietStatic):
    COMPONENT_CLASSES = set(LEVEL_CLASSES) | {"capsule-detail--label"}

    def show(self, telemetry: CapsuleTelemetry, now: datetime) -> None:
        """A label column and a wrapping value column, so a long line wraps under its value."""
        if self.border_title != telemetry.name:
            self.border_title = telemetry.name
        lines = [(field.label, field.line(telemetry, now)) for field in FIELDS]
        label = self.get_component_rich_style("capsule-detail--label", partial=True)
        levels = tuple(str(self.get_component_rich_style(c, partial=True)) for c in sorted(LEVEL_CLASSES))
        key = (tuple(lines), str(label), levels)
        if self.shows(key):
            return
        grid = Table.grid(padding=(0, 1), expand=True)
        grid.add_column(no_wrap=True, style=label)
        grid.add_column(ratio=1, overflow="fold")
        for name, cell in lines:
            grid.add_row(name, cell.styled(self))
        self.show_content(grid, key)

"""Every capsule's checklists at a glance: how far each one has got, and what comes next.

The release screen works one checklist of one capsule; a flight director with several capsules asks
where each of them stands in its procedure, and had to open every release screen and page through
its lists to find out. Here it is one table, read-only (ticks and skips stay on the release screen,
where the step is in front of the operator who does it): a row per capsule and checklist with the
steps finished, the automatic steps the telemetry does not meet, and the next open step; below
it, every open step of the highlighted row in full words. The statuses are the release screen's
(``ChecklistRun.statuses``), redrawn on the app's one-second refresh and whenever the store changes
(another console ticked a step), and only the cells that changed are repainted (``fill_rows``).
"""

from __future__ import annotations

from textual.app import ComposeResult
from textual.binding import Binding
from textual.widgets import DataTable, Static

from console.context import ConsoleContext
from console.screens.base import ConsoleScreen
from console.screens.release import STATE_GLYPH
from console.widgets import fill_rows, set_content
from drs_link.ops import StepState

COLUMNS = ("Capsule", "Checklist", "Finished", "Not met", "Next step")
COMPLETE = "— complete"
HELP = "every capsule's checklists, read-only: steps finished, automatic steps not met, the next step · `↑`/`↓` a row, all its open steps below"
"""The keys, as the help screen lists them (``console.screens.registry``)."""


class ChecklistsScreen(ConsoleScreen):
    DEFAULT_CSS = """
    #checklists {
        height: 1fr;
    }

    #checklists-detail {
        height: auto;
        max-height: 50%;
        border-top: solid $primary;
        color: $text-muted;
    }
    """
    """Its own layout, beside the screen: the one stylesheet stays the other screens'."""
    BINDINGS = [Binding("escape", "app.pop_screen", "Back")]

    def __init__(self, context: ConsoleContext) -> None:
        super().__init__(context)
        self.open_steps: dict[str, str] = {}
        """Each row's open steps in words, by row key, for the pane below the table."""

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        yield DataTable(id="checklists", cursor_type="row")
        yield Static(id="checklists-detail", markup=False)
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        table = self.query_one("#checklists", DataTable)
        lists = self.context.checklists
        widths = (
            max(len(COLUMNS[0]), *(len(name) for name in self.context.setup.capsules)),
            max(len(COLUMNS[1]), *(len(c.title) for c in lists)),
            len(COLUMNS[2]),
            len(COLUMNS[3]),
            max(len(COLUMNS[4]), len(COMPLETE), *(len(s.id) for c in lists for s in c.steps)),
        )
        for title, width in zip(COLUMNS, widths, strict=True):  # fixed: a cell repainted alone never widens
            table.add_column(title, width=width)
        table.focus()
        self.refresh_view()

    def update_view(self) -> None:
        context = self.context
        now = context.now()
        rows = []
        for capsule in context.setup.capsules:
            facts = context.fleet.capsules[capsule].facts(now)
            for checklist in context.checklists:
                statuses = context.step_statuses(capsule, checklist, facts)
                unfinished = [s for s in statuses if not s.finished]
                not_met = sum(s.state is StepState.NOT_MET for s in statuses)
                key = f"{capsule}/{checklist.id}"
                rows.append(
                    (
                        key,
                        (
                            capsule,
                            checklist.title,
                            f"{len(statuses) - len(unfinished)}/{len(statuses)}",
                            str(not_met) if not_met else "",
                            unfinished[0].step.id if unfinished else COMPLETE,
                        ),
                    )
                )
                steps = [f"  {STATE_GLYPH[s.state]:<10} {s.step.text}" for s in unfinished] or [
                    "  every step finished"
                ]
                self.open_steps[key] = "\n".join([f"▸ {capsule} · {checklist.title}", *steps])  # fmt: skip
        fill_rows(self.query_one("#checklists", DataTable), rows)
        self.show_detail()

    def show_detail(self) -> None:
        table = self.query_one("#checklists", DataTable)
        row = table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value if table.row_count else None
        set_content(self.query_one("#checklists-detail", Static), self.open_steps.get(str(row), ""))

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if self.ready:
            self.show_detail()

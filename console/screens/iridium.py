"""Iridium for one capsule: compose MT commands, the parachute window helper, the lifecycle, reports, health.

Every send names the capsule (the command lifecycle refuses otherwise) and shows the exact ASCII
and hex first; PARACHUTE also goes through the two-person rule. The window helper computes the
HH:MM from the report history; a time the capsule would reject is refused before anything is sent.
That flow is ``console.screens.commanding``, shared with the recovery screen. What it lists comes as
one ``IridiumHealthView`` from the app's worker (``drs_link.ops.views``), read by the operations server
or played from a replay.
"""

from __future__ import annotations

from rich.text import Text
from textual import on
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.widgets import DataTable, Label, Static

from console.context import ConsoleContext
from console.messages import ViewRead, ViewWanted
from console.screens.commanding import CommandingScreen, command_bindings
from console.screens.modals import TextPromptModal
from drs_link.errors import LinkError
from drs_link.ops import Command, IridiumHealthView
from drs_link.server import MtView

COMMAND_COLUMNS = ("#", "Text", "State", "Updated", "Detail")
LIFECYCLE_WORDS = {
    "queued": "queued at gateway",
    "probably_delivered": "probably delivered",
    "effect_confirmed": "effect confirmed",
    "unconfirmable": "delivered?, effect not visible",
}


HELP = """\
`n` INTERVAL · `o`/`O` sounder off/on · `c` parachute (helper picks HH:MM) ·
`C` parachute at a time you type (checked against the window) · `R` refresh ·
`u` resolve the highlighted command of unknown delivery from the RockBLOCK portal (its id, or `not sent`)"""
"""The keys, as the help screen lists them (``console.screens.registry``)."""


class IridiumScreen(CommandingScreen):
    BINDINGS = [
        Binding("escape", "app.pop_screen", "Back"),
        *command_bindings(paired=True),
        Binding("R", "reload", "Refresh"),
        Binding("u", "resolve", "Resolve", show=False),
    ]

    def __init__(self, context: ConsoleContext, capsule: str) -> None:
        super().__init__(context)
        self.capsule = capsule
        self.shows = ("iridium", capsule)
        """The view the app delivers to this screen (``console.messages.ViewRead``)."""
        self.view: IridiumHealthView | None = None

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        with Vertical(id="iridium-body"):
            yield Static(id="health", markup=False)
            yield Label("Commands (MT)", classes="pane-title", markup=False)
            yield DataTable(id="commands", cursor_type="row")
            yield Label("Reports (MO), newest first", classes="pane-title", markup=False)
            yield DataTable(id="reports", cursor_type="row")
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        self.query_one("#reports", DataTable).add_columns(
            "MOMSN", "Fix time", "Position", "Alt", "VBAT", "Iter"
        )
        self.action_reload()

    def action_reload(self) -> None:
        """Ask the app for this capsule's Iridium view now (it re-reads it whenever the store changes too)."""
        self.post_message(ViewWanted(*self.shows))

    @on(ViewRead)
    def show_view(self, message: ViewRead) -> None:
        if isinstance(message.view, IridiumHealthView):
            self.show(message.view)

    def show(self, view: IridiumHealthView) -> None:
        self.view = view
        self.query_one("#health", Static).update(view.summary)
        self.show_commands(list(view.commands))
        table = self.query_one("#reports", DataTable)
        table.clear()
        for row in view.rows:
            position = row.position
            where = f"{position[0]:.4f},{position[1]:.4f} ({position[2]})" if position else "—"
            table.add_row(
                "?" if row.momsn is None else str(row.momsn),
                f"{row.fix_time:%H:%M:%S}Z" if row.fix_time else "NO FIX", where,
                f"{row.alt_m:.0f} m" if row.fix_time and row.alt_m is not None else "—",
                f"{row.vbat:.2f}" if row.vbat is not None else "?",
                str(row.iteration) if row.iteration is not None else "?",
            )  # fmt: skip

    def show_commands(self, commands: list[Command]) -> None:
        """Newest first; the detail (a refusal's reason, the gateway's answer) wraps in the width left.

        It used to be cut at 60 characters, and the table ran off the right edge even at 120×40.
        """
        table = self.query_one("#commands", DataTable)
        rows = [
            (str(c.id), c.text, LIFECYCLE_WORDS.get(c.state, c.state.replace("_", " ")), f"{c.updated_utc:%H:%M:%S}Z",
             c.detail)
            for c in reversed(commands)
        ]  # fmt: skip
        widths = [
            max([len(title), *(len(row[i]) for row in rows)]) for i, title in enumerate(COMMAND_COLUMNS[:-1])
        ]
        padding = 2 * table.cell_padding * len(COMMAND_COLUMNS) + table.styles.scrollbar_size_vertical
        widths.append(max(20, table.size.width - sum(widths) - padding))
        table.clear(columns=True)
        for title, width in zip(COMMAND_COLUMNS, widths, strict=True):
            table.add_column(title, width=width)
        for row in rows:
            table.add_row(*row[:-1], Text(row[-1]), height=None, key=row[0])

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "resolve" and not self.context.commanding:
            return None
        return super().check_action(action, parameters)

    def action_resolve(self) -> None:
        """What the portal shows for the highlighted command whose delivery is unknown (``drs mt resolve``):
        the lifecycle refuses any other command, and audits the answer with the operator's name."""
        table = self.query_one("#commands", DataTable)
        if not table.row_count:
            return
        command_id = int(str(table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value))
        context, capsule = self.context, self.capsule

        def answered(answer: str | None) -> None:
            text = (answer or "").strip().lower()
            if not text:
                return
            if text not in ("not sent", "not-sent") and not text.isdigit():
                self.app.notify(f"MT {command_id}: type the portal's MT id or 'not sent'", severity="error")
                return
            gateway_id = int(text) if text.isdigit() else None

            def resolve() -> list[MtView]:
                return context.resolve_mt(capsule, command_id, gateway_id, "console")

            self.write_off_ui(resolve, shown, refused)

        def refused(exc: LinkError) -> None:
            self.app.notify(str(exc), severity="error", timeout=10)

        def shown(commands: list[MtView]) -> None:
            for command in commands[:1]:
                self.app.notify(f"MT {command.id} {command.text}: {command.state}: {command.detail}")
            self.action_reload()

        question = "What does the RockBLOCK portal show? Its MT id if queued, or 'not sent' (logged):"
        self.app.push_screen(TextPromptModal(f"Resolve MT {command_id} of {capsule}", question), answered)

    def reload_after_send(self) -> None:
        self.action_reload()

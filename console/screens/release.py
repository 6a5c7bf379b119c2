"""The release flow of one capsule: its checklists, the go/no-go poll, ARM with a countdown, FIRE.

FIRE is a different key from ARM and is disabled (``check_action``) unless the domain layer says
the capsule is armed; the footer greys it out. Pressing it only opens the confirmation: the
operations server re-checks everything (a fresh poll, the window, the two-person rule) when the worker
asks it to FIRE. The ARM state shown is the server's, pushed to the console (``CommandingContext``).
"""

from __future__ import annotations

from collections.abc import Callable
from typing import Any

from rich.text import Text
from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical
from textual.widgets import DataTable, Label, Static

from console.context import ARMED, FIRED, FIRING, ConsoleContext
from console.messages import OperatorNotice, TelemetryArrived
from console.screens.base import FOOTER_ROOM, ConsoleScreen
from console.screens.modals import ConfirmModal, HazardConfirmation, HazardModal, TextPromptModal
from console.widgets import fill_rows, set_content
from drs_link.errors import LinkError
from drs_link.ops import WAIVABLE, GoNoGoReport, StepKind, StepState, Verdict
from drs_link.server import ApprovalView, Pending, Second

POWER_ON_TEXT = (
    "Power-on runs DRS_on.py: it latches the battery relay and boots the microcontroller and GNSS.\n"
    "Software CANNOT switch it off again: only the OFF button on the unit can."
)
FIRE_TEXT = (
    "FIRE runs DRS_GoGoGo.py: Go is sent, the Pi shuts down, release A opens 30 s later.\n"
    "This cannot be undone."
)
STATE_GLYPH = {
    StepState.DONE: "✔ done",
    StepState.SKIPPED: "↷ skipped",
    StepState.MET: "✔ met",
    StepState.NOT_MET: "✘ not met",
    StepState.NO_DATA: "? no data",
    StepState.PENDING: "· pending",
}
VERDICT_GLYPH = {Verdict.GO: "✔ GO", Verdict.NO_GO: "✘ NO-GO", Verdict.WAIVED: "⚑ WAIVED",
                 Verdict.RELEASED: "■ RELEASED", Verdict.NOT_APPLICABLE: "· n/a"}  # fmt: skip
GONOGO_WIDTHS = (9, 26)
"""Verdict and item columns; the detail takes the rest of the width and wraps, so no reason is cut."""
CHECKLIST_STATE_WIDTH = 9
BY_TITLE = "By / when"


BEFORE_RELEASE_ONLY = ("power_on", "sync", "arm", "fire", "waive")
"""Keys that only mean something before the drop; after Go they are hidden (``reset`` stays, for recovery)."""


HELP = """\
`[` `]` switch checklist · `Space` tick a manual step · `x` skip (reason) ·
`o` power on (confirm; cannot be undone by software) · `s` sync data · `w` waive a go/no-go item
(GNSS fix or sync only; logged): the first `w` moves onto one, `↑`/`↓` another, `w` again asks
why · `a` ARM (only on GO; opens a countdown) · `d` disarm ·
`f` FIRE (only while armed; type the capsule's name; second operator or a logged waiver, or with
`require_second_operator` another login's approval) · `c` cancel the approval request that waits ·
`R` reset after recovery (type the name)"""
"""The keys, as the help screen lists them (``console.screens.registry``)."""


class ReleaseScreen(ConsoleScreen):
    HORIZONTAL_BREAKPOINTS = [(0, "-narrow"), (FOOTER_ROOM, "-stacked"), (140, "-wide")]
    """Below 140 columns the checklist and the go/no-go stack, so neither loses its words; below
    ``FOOTER_ROOM`` the footer also drops its palette hint, as on every screen."""
    BINDINGS = [
        Binding("a", "arm", "ARM"),
        Binding("f", "fire", "FIRE"),
        Binding("o", "power_on", "Power"),
        Binding("space", "tick", "Tick"),
        Binding("s", "sync", "Sync"),
        Binding("w", "waive", "Waive"),
        Binding("escape", "app.pop_screen", "Back"),
        Binding("left_square_bracket", "checklist(-1)", "Prev list", show=False),
        Binding("right_square_bracket", "checklist(1)", "Next list", show=False),
        Binding("x", "skip", "Skip", show=False),
        Binding("d", "disarm", "Disarm", show=False),
        Binding("c", "cancel_approval", "Cancel approval"),
        Binding("R", "reset", "Reset", show=False),
    ]

    def __init__(self, context: ConsoleContext, capsule: str) -> None:
        super().__init__(context)
        self.capsule = capsule
        self.checklist_index = 0
        self.step_texts: dict[str, str] = {}
        self.detail_width = 0
        self.checklist_widths = (0, 0)
        self.gonogo_titles: dict[str, str] = {}
        self.binding_states: tuple[bool | None, ...] = ()
        """What check_action said of each key at the last refresh: the footer is redrawn only on a change."""

    def compose(self) -> ComposeResult:
        yield from self.compose_banner()
        with Horizontal(id="release-body"):
            with Vertical(id="checklist-pane"):
                yield Label(id="checklist-title", classes="pane-title", markup=False)
                yield DataTable(id="checklist", cursor_type="row")
                yield Static(id="step-detail", markup=False)
            with Vertical(id="gonogo-pane"):
                yield Static(id="arm-status", markup=False)
                yield Label(
                    f"Go/no-go: {self.capsule}", id="gonogo-title", classes="pane-title", markup=False
                )
                yield Static(id="gonogo-hint", markup=False)
                yield DataTable(id="gonogo", cursor_type="row")
        yield from self.compose_footer()

    def on_mount(self) -> None:
        self.ready = True
        checklist = self.query_one("#checklist", DataTable)
        ids = [c.id for c in self.context.checklists]
        self.checklist_index = ids.index("release-day") if "release-day" in ids else 0
        checklist.focus()
        self.refresh_view()

    # Rendering --------------------------------------------------------------------------------

    def update_view(self) -> None:
        context = self.context
        now = context.now()
        checklist = context.checklists[self.checklist_index]
        set_content(
            self.query_one("#checklist-title", Label),
            f"{checklist.title} ({self.checklist_index + 1}/{len(context.checklists)}) — {self.capsule}",
        )
        table = self.query_one("#checklist", DataTable)
        row = table.cursor_row
        facts = context.fleet.capsules[self.capsule].facts(now)
        statuses = context.step_statuses(self.capsule, checklist, facts)
        whos = [f"{s.operator} {s.at:%H:%M:%S}Z" if s.operator and s.at else "" for s in statuses]
        self.fit_checklist_columns(table, max((len(who) for who in whos), default=0))
        self.step_texts.clear()
        rows = []
        for status, who in zip(statuses, whos, strict=True):
            kind = {StepKind.MANUAL: "", StepKind.AUTO: "(auto) ", StepKind.COMMAND: "(cmd) "}[
                status.step.kind
            ]
            step = Text(f"{kind}{status.step.text}", no_wrap=True, overflow="ellipsis")
            by = Text(who, no_wrap=True, overflow="ellipsis")
            rows.append((status.step.id, (Text(STATE_GLYPH[status.state]), step, by)))
            self.step_texts[status.step.id] = f"▸ {kind}{status.step.text}" + (f" — {who}" if who else "")
        if fill_rows(table, rows) and table.row_count:
            table.move_cursor(row=min(row, table.row_count - 1))
        self.show_step_detail()
        report = context.gonogo(self.capsule)
        gonogo = self.query_one("#gonogo", DataTable)
        grow = gonogo.cursor_row
        self.fit_gonogo_columns(gonogo)
        self.gonogo_titles = {item.key: item.title for item in report.items}
        rows = []
        for item in report.items:
            style = "dim" if item.verdict is Verdict.NOT_APPLICABLE else ""  # greyed: no longer applies
            cells = (Text(VERDICT_GLYPH[item.verdict], style=style), Text(item.title, style=style),
                     Text(item.detail, style=style))  # fmt: skip
            rows.append((item.key, cells))
        if fill_rows(gonogo, rows, auto_height=True) and gonogo.row_count:
            gonogo.move_cursor(row=min(grow, gonogo.row_count - 1))
        approval = self.approval_text()
        arm = self.arm_text(report.go) + (f"\n{approval}" if approval else "")
        set_content(self.query_one("#arm-status", Static), arm)
        self.show_waive_hint()
        keys = tuple(self.check_action(b.action, ()) for b in self.BINDINGS if isinstance(b, Binding))
        if keys != self.binding_states:  # the footer recomposes on each call: only when a key comes or goes
            self.binding_states = keys
            self.refresh_bindings()

    def fit_checklist_columns(self, table: DataTable[Any], by_width: int) -> None:
        """State and "by / when" keep their width, the step takes the rest (in full below the table).

        Left to size itself, the step column pushed "by / when" off the right edge at every width.
        """
        padding = 2 * table.cell_padding * 3 + table.styles.scrollbar_size_vertical
        by = min(max(by_width, len(BY_TITLE)), max(len(BY_TITLE), table.size.width // 3))
        widths = (max(20, table.size.width - CHECKLIST_STATE_WIDTH - by - padding), by)
        if widths == self.checklist_widths:
            return
        self.checklist_widths = widths
        table.clear(columns=True)
        for title, width in zip(("State", "Step", BY_TITLE), (CHECKLIST_STATE_WIDTH, *widths), strict=True):
            table.add_column(title, width=width)

    def fit_gonogo_columns(self, gonogo: DataTable[Any]) -> None:
        """Give the detail column the width that is left, so its words wrap instead of scrolling away."""
        padding = 2 * gonogo.cell_padding * 3 + gonogo.styles.scrollbar_size_vertical
        width = max(20, gonogo.size.width - sum(GONOGO_WIDTHS) - padding)
        if width == self.detail_width:
            return
        self.detail_width = width
        gonogo.clear(columns=True)
        for title, column_width in zip(("Verdict", "Item", "Detail"), (*GONOGO_WIDTHS, width), strict=True):
            gonogo.add_column(title, width=column_width)

    def show_step_detail(self) -> None:
        step = self._selected_step()
        set_content(self.query_one("#step-detail", Static), self.step_texts.get(step, "") if step else "")

    def on_data_table_row_highlighted(self, event: DataTable.RowHighlighted) -> None:
        if self.ready and event.data_table.id == "checklist":
            self.show_step_detail()
        elif self.ready:
            self.show_waive_hint()

    def on_descendant_focus(self) -> None:
        if self.ready:
            self.show_waive_hint()

    def show_waive_hint(self) -> None:
        """Say on screen how ``w`` picks its item: the trial found it only by tabbing into the table."""
        hint = self.query_one("#gonogo-hint", Static)
        hint.display = self.context.commanding and not self.released()
        set_content(hint, self.waive_hint())

    def waive_hint(self) -> str:
        item = self._highlighted_item()
        if not self.query_one("#gonogo", DataTable).has_focus or item is None:
            return "w picks a go/no-go item to waive (only the GNSS fix and sync can be)"
        title = self.gonogo_titles.get(item, item)
        if item in WAIVABLE:
            return f"w waives {title} · ↑/↓ another item · Tab: checklist"
        return f"{title} cannot be waived: ↑/↓ to the GNSS fix or sync"

    def arm_text(self, go: bool) -> str:
        if not self.context.commanding:
            return "REPLAY: commanding disabled"
        status = self.context.arm_state(self.capsule)
        poll = "GO" if go else "NO-GO"
        state = status.state if status is not None else "disarmed"
        left = self.context.remaining_s(status) if status is not None else 0.0
        if status is not None and state == ARMED and not status.mine:
            return (
                f"▶ ARMED by another console ({status.holder}) — {left:.0f} s left; "
                f"FIRE here is refused. Poll: {poll}. d disarms it."
            )
        if state == ARMED:
            return f"▶ ARMED — {left:.0f} s left to FIRE (f). Poll: {poll}. d disarms."
        if state == FIRING:
            return "… FIRING: Go is being sent"
        if state == FIRED:
            return "■ FIRED: Go sent; watch for the first Iridium report"
        reason = f" (last: {status.reason})" if status is not None and status.reason else ""
        return f"○ DISARMED{reason}. Poll: {poll}. a = ARM"

    def armed_here(self) -> bool:
        """An open window this account holds, with time left on this console's clock."""
        status = self.context.arm_state(self.capsule)
        return (status is not None and status.state == ARMED and status.mine
                and self.context.remaining_s(status) > 0)  # fmt: skip

    def approval_text(self) -> str:
        """A request this login made that waits for another login: a live line with its own countdown."""
        now = self.context.now()
        return " ".join(
            f"⧗ approval #{r.id} ({r.summary}) waits for another login: drs approve {r.id} — "
            f"{max(0.0, (r.expires - now).total_seconds()) if r.expires else 0.0:.0f} s left · c cancels"
            for r in self.context.waiting_approvals(self.capsule)
        )

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action == "cancel_approval":
            return bool(self.context.waiting_approvals(self.capsule))
        commanding = ("power_on", "sync", "waive", "arm", "disarm", "fire", "tick", "skip", "reset")
        if action in commanding and not self.context.commanding:
            return None
        if action in BEFORE_RELEASE_ONLY and self.released():
            return False  # the Pi is shut down: these keys leave the footer (None would only dim them)
        if action == "fire":
            return True if self.armed_here() else None
        return True

    def released(self) -> bool:
        status = self.context.arm_state(self.capsule)
        return self.context.fleet.capsules[self.capsule].released or (
            status is not None and status.state in (FIRING, FIRED)
        )

    # Actions ----------------------------------------------------------------------------------

    def action_checklist(self, step: int) -> None:
        self.checklist_index = (self.checklist_index + step) % len(self.context.checklists)
        self.query_one("#checklist", DataTable).move_cursor(row=0)
        self.refresh_view()

    def _selected_step(self) -> str | None:
        table = self.query_one("#checklist", DataTable)
        if not table.row_count:
            return None
        return str(table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value)

    def _refused(self, exc: Exception) -> None:
        self.app.notify(str(exc), severity="error", timeout=10)

    def _write(self, write: Callable[[], object]) -> None:
        """A key's write to the server off the UI thread (``write_off_ui``); the screen shows what it left."""

        def refused(exc: LinkError) -> None:
            self._refused(exc)
            self.refresh_view()

        self.write_off_ui(write, lambda _: self.refresh_view(), refused)

    def action_tick(self) -> None:
        step = self._selected_step()
        if step is None:
            return
        context, capsule, checklist = (
            self.context,
            self.capsule,
            self.context.checklists[self.checklist_index].id,
        )
        self._write(lambda: context.tick(capsule, checklist, step))

    def action_skip(self) -> None:
        step = self._selected_step()
        if step is None:
            return

        def done(reason: str | None) -> None:
            if reason is None:
                return
            context, capsule = self.context, self.capsule
            checklist = context.checklists[self.checklist_index].id
            self._write(lambda: context.tick(capsule, checklist, step, reason))

        self.app.push_screen(TextPromptModal("Skip step", f"Why skip {step}? (logged)"), done)

    def action_power_on(self) -> None:
        def confirmed(yes: bool | None) -> None:
            if yes:
                self.power_on_worker()

        self.app.push_screen(ConfirmModal(f"Power on {self.capsule}?", POWER_ON_TEXT, "Power on"), confirmed)

    @work(thread=True, exit_on_error=False, group="release")
    def power_on_worker(self) -> None:
        self.app.post_message(OperatorNotice(f"{self.capsule}: powering on; waiting for NMEA (~25 s)"))
        try:
            done = self.context.power_on(self.capsule)
        except LinkError as exc:
            self.app.post_message(OperatorNotice(str(exc), "error"))
            return
        for line in done.lines:
            self.app.post_message(OperatorNotice(line, "information" if done.ok else "warning"))

    @work(thread=True, exit_on_error=False, group="release")
    def action_sync(self) -> None:
        try:
            self.app.post_message(OperatorNotice(f"{self.capsule}: syncing data…"))
            self.context.sync(self.capsule)
            self.app.post_message(OperatorNotice(f"{self.capsule}: sync finished and verified"))
        except LinkError as exc:
            self.app.post_message(OperatorNotice(str(exc), "error"))

    def _highlighted_item(self) -> str | None:
        table = self.query_one("#gonogo", DataTable)
        if not table.row_count:
            return None
        return str(table.coordinate_to_cell_key(table.cursor_coordinate).row_key.value)

    def choose_waivable(self, report: GoNoGoReport) -> None:
        """Move into go/no-go onto the first waivable item, one that is NO-GO if there is one."""
        table = self.query_one("#gonogo", DataTable)
        keys = [item.key for item in report.items]
        no_go = [item.key for item in report.items if item.key in WAIVABLE and item.verdict is Verdict.NO_GO]
        candidates = no_go or [key for key in keys if key in WAIVABLE]
        if candidates:
            table.move_cursor(row=keys.index(candidates[0]))
        table.focus()
        self.show_waive_hint()

    def action_waive(self) -> None:
        """Waive the highlighted go/no-go item; from anywhere else, first take the operator to one."""
        table = self.query_one("#gonogo", DataTable)
        item = self._highlighted_item()
        if item is None:
            return
        if not table.has_focus:
            self.choose_waivable(self.context.gonogo(self.capsule))
            return
        if item not in WAIVABLE:
            self.app.notify(self.waive_hint(), severity="warning")
            return

        def done(reason: str | None) -> None:
            if reason is None:
                return
            context, capsule = self.context, self.capsule
            self._write(lambda: context.waive(capsule, item, reason))

        self.app.push_screen(
            TextPromptModal(
                f"Waive '{item}'", "Reason (logged with your name; only GNSS and sync can be waived):"
            ),
            done,
        )

    def action_arm(self) -> None:
        status = self.context.arm_state(self.capsule)
        if status is not None and self.armed_here():  # `a` again once silently restarted the window: ask
            left = self.context.remaining_s(status)
            body = f"{self.capsule} is ARMED, {left:.0f} s left. ARM again starts a new window."
            restart = ConfirmModal("ARM again?", body, "Restart the window")
            self.app.push_screen(restart, lambda yes: self._arm() if yes else None)
            return
        self._arm()

    def _arm(self) -> None:
        """ARM through the server, off the UI thread: the server takes the go/no-go poll it judges."""
        context, capsule = self.context, self.capsule
        self._write(lambda: context.arm(capsule))

    def action_disarm(self) -> None:
        context, capsule = self.context, self.capsule
        self._write(lambda: context.disarm(capsule, "operator disarmed"))

    def action_cancel_approval(self) -> None:
        context, capsule = self.context, self.capsule

        def shown(cancelled: list[ApprovalView]) -> None:
            for request in cancelled:
                self.app.notify(f"{capsule}: approval #{request.id} cancelled: nothing will be sent on it")
            self.refresh_view()

        self.write_off_ui(lambda: context.cancel_waiting(capsule), shown, self._refused)

    def action_fire(self) -> None:
        second = self.context.require_second_operator

        def confirmed(answer: HazardConfirmation | None) -> None:
            if answer is not None:
                self.fire_worker(answer)

        self.app.push_screen(
            HazardModal(self.capsule, "FIRE", FIRE_TEXT, second, countdown=self.fire_countdown), confirmed
        )

    def fire_countdown(self) -> str:
        """The ARM window as the FIRE dialog shows it; FIRE is checked against it again on submit."""
        status = self.context.arm_state(self.capsule)
        if status is not None and status.state == ARMED and status.armed_until is not None:
            left = self.context.remaining_s(status)
            return f"ARMED — {left:.0f} s left (window closes {status.armed_until:%H:%M:%S}Z)"
        reason = (status.reason or status.state) if status is not None else "disarmed"
        return f"NOT ARMED ({reason}): FIRE will be refused"

    def action_reset(self) -> None:
        def typed(answer: str | None) -> None:
            if answer is not None:
                self.reset_worker(answer.strip())

        self.app.push_screen(
            TextPromptModal(
                f"Reset {self.capsule} after recovery",
                "Only once the Gone flag is cleared on the unit (four-button reset) and the relay is off.\n"
                f"Type the capsule's name ({self.capsule}) to allow a new release:",
            ),
            typed,
        )

    @work(thread=True, exit_on_error=False, group="release")
    def reset_worker(self, typed_name: str) -> None:
        try:
            self.context.reset(self.capsule, typed_name)
        except LinkError as exc:
            self.app.post_message(OperatorNotice(str(exc), "error"))
            return
        self.app.post_message(OperatorNotice(f"{self.capsule}: reset; a new release can be prepared"))

    @work(thread=True, exit_on_error=False, group="release")
    def fire_worker(self, answer: HazardConfirmation) -> None:
        second = Second(answer.second_operator or None, answer.single_operator_waiver or None,
                        answer.await_approval)  # fmt: skip

        def pending(request: Pending) -> None:
            self.context.warn(f"{self.capsule}: {request.line}")

        try:
            done = self.context.fire(self.capsule, answer.typed_name, second, pending)
        except LinkError as exc:
            self.app.post_message(OperatorNotice(str(exc), "error"))
            return
        self.app.post_message(TelemetryArrived(self.context.poll(self.capsule)))
        self.app.post_message(OperatorNotice(f"{self.capsule}: RELEASED — Go sent, Pi shut down"))
        for line in done.lines:
            self.app.post_message(OperatorNotice(line))

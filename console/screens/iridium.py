"""Iridium for one capsule: compose MT commands, the parachute window helper, the lifecycle, reports, health.

Every send names the capsule (the command lifecycle refuses otherwise) and shows the exact ASCII
and hex first; PARACHUTE also goes through the two-person rule. The window helper computes the
HH:MM from the report history; a time the capsule would reject is refused before anything is sent.
"""

from __future__ import annotations

import time

from textual import work
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Vertical
from textual.widgets import DataTable, Label, Static

from console.screens.base import ConsoleScreen
from console.screens.modals import HazardConfirmation, HazardModal, TextPromptModal
from drs_link.arming import check_second_operator
from drs_link.errors import LinkError
from drs_link.iridium.health import assess
from drs_link.iridium.mt import MtComposer, MtMessage, parse_hhmm
from drs_link.iridium.parachute import ParachutePlan, plan_parachute
from drs_link.operations import report_position

RELOAD_S = 2.0
LIFECYCLE_WORDS = {
    "queued": "queued at gateway",
    "probably_delivered": "probably delivered",
    "effect_confirmed": "effect confirmed",
    "unconfirmable": "delivered?, effect not visible",
}


class IridiumScreen(ConsoleScreen):
    BINDINGS = [
        Binding("escape", "app.pop_screen", "Back"),
        Binding("n", "interval", "INTERVAL"),
        Binding("o", "sounder(False)", "Sounder off"),
        Binding("O", "sounder(True)", "Sounder on", show=False),
        Binding("c", "parachute", "Parachute"),
        Binding("C", "parachute_at", "Parachute at…", show=False),
        Binding("R", "reload", "Refresh"),
    ]

    def __init__(self, capsule: str) -> None:
        super().__init__()
        self.capsule = capsule
        self.loaded_at = time.monotonic()

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
        self.query_one("#commands", DataTable).add_columns("#", "Text", "State", "Updated", "Detail")
        self.query_one("#reports", DataTable).add_columns("MOMSN", "Fix time", "Position", "Alt", "VBAT", "Iter")
        self.action_reload()

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        if action in ("interval", "sounder", "parachute", "parachute_at") and not self.console.commanding:
            return None
        return True

    @work(thread=True, exit_on_error=False, group="iridium-read")
    def action_reload(self) -> None:
        ops = self.console.ops
        if ops is None:
            return
        reports = ops.stored_reports(self.capsule)
        commands = ops.commands(self.capsule)
        self.app.call_from_thread(self.show, reports, commands)

    def update_view(self) -> None:
        """Re-read the store every few seconds: reports and command states change underneath."""
        if time.monotonic() - self.loaded_at >= RELOAD_S:
            self.loaded_at = time.monotonic()
            self.action_reload()

    def show(self, reports: list, commands: list) -> None:  # type: ignore[type-arg]
        health = assess(reports) if reports else None
        if health is None:
            text = f"{self.capsule}: no Iridium reports yet"
        else:
            flags = "; ".join(f"{f.kind}: {f.message}" for f in health.findings[-4:]) or "no health flags"
            vbat = f"{health.last_vbat:.2f} V" if health.last_vbat is not None else "?"
            text = f"{self.capsule}: {health.reports} reports, battery {vbat}. {flags}"
        self.query_one("#health", Static).update(text)
        table = self.query_one("#commands", DataTable)
        table.clear()
        for c in reversed(commands):
            table.add_row(str(c.id), c.text, LIFECYCLE_WORDS.get(c.state, c.state.replace("_", " ")),
                          f"{c.updated_utc:%H:%M:%S}Z", c.detail[:60])  # fmt: skip
        table = self.query_one("#reports", DataTable)
        table.clear()
        for r in reversed(reports[-50:]):
            fix = r.report.fix if r.report else None
            position = report_position(r)
            where = f"{position[0]:.4f},{position[1]:.4f} ({position[3]})" if position else "—"
            table.add_row(
                str(r.delivery.momsn), f"{fix.time:%H:%M:%S}Z" if fix else "NO FIX", where,
                f"{fix.alt_m} m" if fix else "—", f"{r.report.vbat:.2f}" if r.report else "?",
                str(r.report.iteration) if r.report else "?",
            )  # fmt: skip

    # Composing and sending -----------------------------------------------------------------------

    def _send_after_name(self, message: MtMessage, why: str) -> None:
        def typed(answer: str | None) -> None:
            if answer is not None:
                self.send_worker(message, answer.strip(), None)

        self.app.push_screen(
            TextPromptModal(
                f"Send {message.text} to {self.capsule}",
                f"{why}\nASCII {message.text} ({len(message.payload)} B) hex {message.hex}\n"
                f"Type the capsule's name ({self.capsule}) to queue it at the gateway:",
            ),
            typed,
        )

    def action_interval(self) -> None:
        def chosen(answer: str | None) -> None:
            if answer is None:
                return
            try:
                message = MtComposer().interval(int(answer.strip())).build()
            except ValueError:
                self.app.notify(f"INTERVAL {answer!r} is not a whole number of minutes", severity="error")
                return
            except LinkError as exc:
                self.app.notify(str(exc), severity="error")
                return
            self._send_after_name(message, "Changes the report interval from the next cycle on.")

        self.app.push_screen(TextPromptModal("INTERVAL", "Minutes between reports (1-1440):", "2"), chosen)

    def action_sounder(self, on: bool) -> None:
        message = MtComposer().sounder(on).build()
        self._send_after_name(message, "The sounder change is never confirmed by telemetry.")

    def _plan(self, requested: tuple[int, int] | None) -> ParachutePlan | None:
        ops = self.console.ops
        try:
            return plan_parachute(ops.stored_reports(self.capsule), self.console.now(), requested=requested)
        except LinkError as exc:
            self.app.notify(f"PARACHUTE refused: {exc}", severity="error", timeout=12)
            return None

    def _confirm_parachute(self, plan: ParachutePlan) -> None:
        message = MtComposer().parachute(plan.hour, plan.minute).build()
        text = plan.window_text() + "\n" + "\n".join(f"! {w}" for w in plan.warnings)
        second = self.console.ops.config.console.require_second_operator

        def confirmed(answer: HazardConfirmation | None) -> None:
            if answer is None:
                return
            try:
                people = check_second_operator(
                    self.console.operator, answer.second_operator, answer.single_operator_waiver, second
                )
            except LinkError as exc:
                self.app.notify(f"PARACHUTE refused: {exc}", severity="error")
                return
            self.send_worker(message, answer.typed_name, people)

        self.app.push_screen(HazardModal(self.capsule, "PARACHUTE", text, second), confirmed)

    def action_parachute(self) -> None:
        plan = self._plan(None)
        if plan is not None:
            self._confirm_parachute(plan)

    def action_parachute_at(self) -> None:
        def chosen(answer: str | None) -> None:
            if answer is None:
                return
            try:
                requested = parse_hhmm(answer)
            except LinkError as exc:
                self.app.notify(str(exc), severity="error")
                return
            plan = self._plan(requested)
            if plan is not None:
                self._confirm_parachute(plan)

        self.app.push_screen(TextPromptModal("PARACHUTE at", "HH:MM (UTC) to check against the window:"), chosen)

    @work(thread=True, exit_on_error=False, group="iridium-send")
    def send_worker(self, message: MtMessage, confirmation: str, people: dict[str, str] | None) -> None:
        from console.app import OperatorNotice

        ops = self.console.ops
        try:
            if people:
                ops.store.append_audit(ops.operator, self.capsule, "mt.two-person", "ok", {"text": message.text, **people})
            command = ops.send_mt(self.capsule, message, confirmation)
        except LinkError as exc:
            self.app.post_message(OperatorNotice(str(exc), "error"))
            return
        self.app.post_message(OperatorNotice(f"{self.capsule}: {message.text} {command.state}: {command.detail}"))
        key = {"[INTERVAL": "mt-interval", "[PARACHUTE": "mt-parachute", "[SOUNDER_OFF": "mt-sounder-off"}
        if command.state == "queued":
            for prefix, name in key.items():
                if message.text.startswith(prefix):
                    self.app.call_from_thread(self._command_done, name, f"{message.text} queued")
        self.app.call_from_thread(self.action_reload)

    def _command_done(self, command: str, result: str) -> None:
        for checklist in self.console.checklists:
            for step in checklist.steps:
                if step.command == command:
                    self.console.checklist_run(self.capsule, checklist).command_done(
                        step.id, self.console.operator, result
                    )

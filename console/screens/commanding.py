"""Commanding one capsule over Iridium from whichever screen the operator is on: one confirmation flow.

The Iridium screen and the recovery screen both send INTERVAL, SOUNDER and PARACHUTE; a team in the
field must not meet a second, subtly different set of confirmations. Every send shows the exact
ASCII and hex and needs the capsule's name (the command lifecycle refuses otherwise); PARACHUTE
also goes through the window helper, which refuses a time the capsule would reject, and the
two-person rule. The refusals themselves are ``drs_link``'s; this only asks and reports.
"""

from __future__ import annotations

from datetime import datetime

from textual import work
from textual.binding import Binding

from console.screens.base import ConsoleScreen
from console.screens.modals import HazardConfirmation, HazardModal, TextPromptModal
from drs_link.errors import LinkError
from drs_link.iridium import MtComposer, MtMessage, ParachutePlan, landed_evidence, parse_hhmm, plan_parachute
from drs_link.ops import authorize_mt

COMMAND_ACTIONS = ("interval", "sounder", "parachute", "parachute_at")


def command_bindings(paired: bool) -> list[Binding]:
    """The same keys on every screen that commands.

    ``paired`` gives the narrow footer one entry per key pair (``o/O`` sounder off/on, ``c/C``
    parachute by the helper / at a typed time) so that all of them fit at 80 columns.
    """
    if not paired:
        return [
            Binding("n", "interval", "INTERVAL"),
            Binding("o", "sounder(False)", "Sounder off"),
            Binding("O", "sounder(True)", "Sounder on", show=False),
            Binding("c", "parachute", "Parachute"),
            Binding("C", "parachute_at", "Parachute at…", show=False),
        ]
    return [
        Binding("n", "interval", "INTERVAL"),
        Binding("o", "sounder(False)", "Sounder off/on", key_display="o/O"),
        Binding("O", "sounder(True)", "Sounder on", show=False),
        Binding("c", "parachute", "Parachute", key_display="c/C"),
        Binding("C", "parachute_at", "Parachute at…", show=False),
    ]


class CommandingScreen(ConsoleScreen):
    """A screen of one capsule whose keys queue its MT commands (see ``command_bindings``)."""

    capsule: str

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """Replay has nothing to send with: the command keys are disabled (shown dimmed in the footer)."""
        if action in COMMAND_ACTIONS and not self.console.commanding:
            return None
        return True

    def reload_after_send(self) -> None:
        """Re-read what a send changed; each screen shows the commands its own way."""

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
            self._send_after_name(
                message,
                "The next report keeps the old spacing; the new interval spaces the reports after it.",
            )

        self.app.push_screen(TextPromptModal("INTERVAL", "Minutes between reports (1-1440):", "2"), chosen)

    def action_sounder(self, on: bool) -> None:
        message = MtComposer().sounder(on).build()
        self._send_after_name(message, "The sounder change is never confirmed by telemetry.")

    def _plan(self, requested: tuple[int, int] | None) -> ParachutePlan | None:
        ops = self.console.ops
        try:
            return plan_parachute(
                ops.stored_reports(self.capsule), self.console.now(), ops.commands(self.capsule), requested
            )
        except LinkError as exc:
            self.app.notify(f"PARACHUTE refused: {exc}", severity="error", timeout=12)
            return None

    def _confirm_parachute(self, plan: ParachutePlan) -> None:
        message = MtComposer().parachute(plan.hour, plan.minute).build()
        evidence = landed_evidence(self.console.ops.stored_reports(self.capsule))
        verdict = "Landed evidence" if evidence.on_ground else "NO LANDED EVIDENCE"
        text = "\n".join(
            [f"{verdict}: {evidence.summary}", plan.window_text(), *(f"! {w}" for w in plan.warnings)]
        )
        second = self.console.ops.config.console.require_second_operator
        override = (
            None
            if evidence.on_ground
            else (
                "Override (drops the parachute in flight if it is still falling): a reason, with a second operator "
                "or a waiver above"
            )
        )

        def confirmed(answer: HazardConfirmation | None) -> None:
            if answer is not None:
                self.send_worker(message, answer.typed_name, answer, plan.queue_by)

        def countdown() -> str:
            left = (plan.queue_by - self.console.now()).total_seconds()
            if left <= 0:
                return (
                    f"queue-before {plan.queue_by:%H:%M:%S}Z has PASSED: sending will be refused; plan again"
                )
            return f"queue before {plan.queue_by:%H:%M:%S}Z — {left:.0f} s left"

        self.app.push_screen(
            HazardModal(self.capsule, "PARACHUTE", text, second, override, countdown), confirmed
        )

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

        self.app.push_screen(
            TextPromptModal("PARACHUTE at", "HH:MM (UTC) to check against the window:"), chosen
        )

    @work(thread=True, exit_on_error=False, group="mt-send")
    def send_worker(
        self,
        message: MtMessage,
        confirmation: str,
        hazard: HazardConfirmation | None,
        queue_by: datetime | None = None,
    ) -> None:
        from console.app import OperatorNotice

        ops = self.console.ops
        try:
            approval = (
                self.console.approval(self.capsule, "parachute", message.text)
                if hazard is not None and hazard.await_approval else None
            )  # fmt: skip
            authorize_mt(
                ops.store, self.capsule, ops.operator, message, ops.stored_reports(self.capsule),
                second_operator=hazard.second_operator if hazard else None,
                single_operator_waiver=hazard.single_operator_waiver if hazard else None,
                require_second_operator=ops.config.console.require_second_operator,
                override_landed=hazard.override_reason if hazard else None,
                queue_by=queue_by, now=self.console.now(), approval=approval,
            )  # fmt: skip
            command = ops.send_mt(self.capsule, message, confirmation)
        except LinkError as exc:
            self.app.post_message(OperatorNotice(str(exc), "error"))
            return
        self.app.post_message(
            OperatorNotice(f"{self.capsule}: {message.text} {command.state}: {command.detail}")
        )
        self.app.call_from_thread(self.reload_after_send)

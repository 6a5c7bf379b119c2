"""Commanding one capsule over Iridium from whichever screen the operator is on: one confirmation flow.

The Iridium screen and the recovery screen both send the catalogue's commands that have console
keys (``drs_link.iridium.commands``: INTERVAL, SOUNDER and PARACHUTE); a team in the field must not
meet a second, subtly different set of confirmations. Every send shows the exact
ASCII and hex and needs the capsule's name (the command lifecycle refuses otherwise); PARACHUTE
also goes through the window helper, which refuses a time the capsule would reject, and the
two-person rule. The refusals themselves are ``drs_link``'s; this only asks and reports, and the send
itself goes to the operations server as the command's ``drs mt send`` option (``option_of``), which
composes, gates and queues it there (the PARACHUTE plan and the landed evidence shown before it are asked of
the server too, through the context).
"""

from __future__ import annotations

from textual import work
from textual.binding import Binding

from console.messages import OperatorNotice
from console.screens.base import ConsoleScreen
from console.screens.modals import HazardConfirmation, HazardModal, TextPromptModal
from drs_link.errors import LinkError
from drs_link.ops import LISTED, PARACHUTE, Hazard, MtCommand, MtComposer, MtMessage, by_name
from drs_link.server import ParachuteView, Pending, Second

COMMAND_ACTIONS = ("command",)


def option_of(command: MtCommand, value: object) -> int | str:
    """A console key's value as the command's ``drs mt send`` option, which the server reads: a choice
    whose parsed value it is (the sounder's ``on``/``off``), a PARACHUTE time as HH:MM, else the value."""
    if command is PARACHUTE and isinstance(value, tuple):
        return f"{value[0]:02d}:{value[1]:02d}"
    for choice in command.option.get("choices", ()):
        if command.from_option(choice) == value:
            return str(choice)
    if isinstance(value, int | str):
        return value
    raise LinkError(f"{command.name}: no option for {value!r}")


def command_bindings(paired: bool, listed: tuple[MtCommand, ...] = LISTED) -> list[Binding]:
    """The same keys on every screen that commands: each catalogue command's ``keys``, as listed.

    ``paired`` gives the narrow footer one entry per command (``o/O`` sounder off/on, ``c/C``
    parachute by the helper / at a typed time) so that all of them fit at 80 columns.
    """
    bindings = []
    for command in listed:
        for index, key in enumerate(command.keys):
            action = f"command({command.name!r}, {key.value!r})"
            if index > 0:
                bindings.append(Binding(key.key, action, key.description, show=False))
            elif paired and len(command.keys) > 1:
                display = "/".join(k.key for k in command.keys)
                bindings.append(Binding(key.key, action, command.pair_label, key_display=display))
            else:
                bindings.append(Binding(key.key, action, key.description))
    return bindings


class CommandingScreen(ConsoleScreen):
    """A screen of one capsule whose keys queue its MT commands (see ``command_bindings``)."""

    capsule: str

    def check_action(self, action: str, parameters: tuple[object, ...]) -> bool | None:
        """Replay has nothing to send with: the command keys are disabled (shown dimmed in the footer)."""
        if action in COMMAND_ACTIONS and not self.context.commanding:
            return None
        return True

    def reload_after_send(self) -> None:
        """Re-read what a send changed; each screen shows the commands its own way."""

    def _send_after_name(self, message: MtMessage, options: dict[str, int | str], why: str) -> None:
        def typed(answer: str | None) -> None:
            if answer is not None:
                self.send_worker(message, options, answer.strip(), None)

        self.app.push_screen(
            TextPromptModal(
                f"Send {message.text} to {self.capsule}",
                f"{why}\nASCII {message.text} ({len(message.payload)} B) hex {message.hex}\n"
                f"Type the capsule's name ({self.capsule}) to queue it at the gateway:",
            ),
            typed,
        )

    def action_command(self, name: str, given: object = None) -> None:
        """One key of a catalogue command: its fixed value, or the value the operator types at its prompt.

        A critical command (PARACHUTE) goes through the window helper (``next``: the helper picks the time)
        and the hazard confirmation; every other command shows its text and hex and asks for the capsule's
        name.
        """
        command = by_name()[name]
        if given is None and command.prompt is not None and command.read is not None:
            prompt, read = command.prompt, command.read

            def typed(answer: str | None) -> None:
                if answer is None:
                    return
                try:
                    value = read(answer)
                except LinkError as exc:
                    self.app.notify(str(exc), severity="error")
                    return
                self._send_value(command, value)

            self.app.push_screen(TextPromptModal(prompt.title, prompt.question, prompt.default), typed)
            return
        self._send_value(command, given)

    def _send_value(self, command: MtCommand, value: object) -> None:
        if command.hazard is Hazard.CRITICAL:
            plan = self._plan(value if isinstance(value, tuple) else None)  # "next": the helper picks
            if plan is not None:
                self._confirm_parachute(plan)
            return
        try:
            message = MtComposer().add(command.name, value).build()
            options = {command.dest: option_of(command, value)}
        except LinkError as exc:
            self.app.notify(str(exc), severity="error")
            return
        self._send_after_name(message, options, command.note)

    def _plan(self, requested: tuple[int, int] | None) -> ParachuteView | None:
        try:
            return self.context.plan_parachute(self.capsule, requested)
        except LinkError as exc:
            self.app.notify(f"PARACHUTE refused: {exc}", severity="error", timeout=12)
            return None

    def _confirm_parachute(self, planned: ParachuteView) -> None:
        plan, evidence = planned.plan, planned.evidence
        message = MtComposer().add("PARACHUTE", (plan.hour, plan.minute)).build()
        verdict = "Landed evidence" if evidence.on_ground else "NO LANDED EVIDENCE"
        text = "\n".join(
            [f"{verdict}: {evidence.summary}", plan.window_text(), *(f"! {w}" for w in plan.warnings)]
        )
        second = self.context.require_second_operator
        override = (
            None
            if evidence.on_ground
            else (
                "Override (drops the parachute in flight if it is still falling): a reason, with a second operator "
                "or a waiver above"
            )
        )

        options = {PARACHUTE.dest: option_of(PARACHUTE, (plan.hour, plan.minute))}

        def confirmed(answer: HazardConfirmation | None) -> None:
            if answer is not None:
                self.send_worker(message, options, answer.typed_name, answer)

        def countdown() -> str:
            """The deadline, and the landed evidence as it is now when a report has changed it since the
            dialog opened (#23: the evidence was frozen at opening while the operator typed)."""
            left = (plan.queue_by - self.context.now()).total_seconds()
            if left <= 0:
                deadline = (
                    f"queue-before {plan.queue_by:%H:%M:%S}Z has PASSED: sending will be refused; plan again"
                )
            else:
                deadline = f"queue before {plan.queue_by:%H:%M:%S}Z — {left:.0f} s left"
            try:
                now = self.context.landed(self.capsule)
            except LinkError as exc:
                return f"{deadline}\nevidence NOW unknown: {exc}"
            if now.summary == evidence.summary:
                return deadline
            return f"{deadline}\nevidence NOW ({'landed' if now.on_ground else 'NOT landed'}): {now.summary}"

        self.app.push_screen(
            HazardModal(self.capsule, "PARACHUTE", text, second, override, countdown), confirmed
        )

    @work(thread=True, exit_on_error=False, group="mt-send")
    def send_worker(
        self,
        message: MtMessage,
        options: dict[str, int | str],
        confirmation: str,
        hazard: HazardConfirmation | None,
    ) -> None:
        """The send, through the server (which plans a PARACHUTE time again and holds every gate)."""
        second = Second(hazard.second_operator or None, hazard.single_operator_waiver or None,
                        hazard.await_approval) if hazard is not None else Second()  # fmt: skip

        def pending(request: Pending) -> None:
            self.context.warn(f"{self.capsule}: {request.line}")

        try:
            done = self.context.send_mt(
                self.capsule, options, confirmation, second,
                override_landed=hazard.override_reason or None if hazard else None, on_pending=pending,
            )  # fmt: skip
        except LinkError as exc:
            self.app.post_message(OperatorNotice(str(exc), "error"))
            return
        sent = next((line for line in done.lines if line.startswith("MT ")), "")
        state = sent.split(": ", 2)[1:] if sent else []
        said = ": ".join(state) if state else " ".join(done.lines)
        self.app.post_message(OperatorNotice(f"{self.capsule}: {message.text} {said}"))
        self.app.call_from_thread(self.reload_after_send)

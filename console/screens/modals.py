"""Confirmations: Cancel has the focus, hazardous ones make the operator type the capsule's name.

These only collect what the operator says; whether it is enough is decided by ``drs_link``
(the arming controller, the state machine, the command lifecycle), which refuse otherwise.
"""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import dataclass, replace

from textual.actions import SkipAction
from textual.app import ComposeResult
from textual.binding import Binding
from textual.containers import Horizontal, Vertical, VerticalScroll
from textual.screen import ModalScreen
from textual.widgets import Button, Input, Label, Static

from drs_link.ops import WAIVER_REASON_MAX


class ConfirmModal(ModalScreen[bool]):
    """Yes/No with *Cancel* focused: Enter on a reflex never confirms."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(self, title: str, body: str, confirm_label: str = "Confirm") -> None:
        super().__init__()
        self.title_text = title
        self.body = body
        self.confirm_label = confirm_label

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Label(self.title_text, classes="dialog-title", markup=False)
            yield Static(self.body, classes="dialog-body", markup=False)
            with Horizontal(classes="dialog-buttons"):
                yield Button("Cancel", id="cancel", variant="primary")
                yield Button(self.confirm_label, id="confirm", variant="warning")

    def on_mount(self) -> None:
        self.query_one("#cancel", Button).focus()

    def on_button_pressed(self, event: Button.Pressed) -> None:
        self.dismiss(event.button.id == "confirm")

    def action_cancel(self) -> None:
        self.dismiss(False)


class TextPromptModal(ModalScreen[str | None]):
    """One line of text (a waiver reason, a skip reason, an INTERVAL); Escape cancels."""

    BINDINGS = [Binding("escape", "cancel", "Cancel")]

    def __init__(
        self, title: str, prompt: str, placeholder: str = "", max_length: int = WAIVER_REASON_MAX
    ) -> None:
        super().__init__()
        self.title_text = title
        self.prompt = prompt
        self.placeholder = placeholder or f"at most {max_length} characters"
        self.max_length = max_length
        """Characters the answer may have, said in the empty field: every answer here is a reason or a value,
        and a reason of thousands of characters pushed go/no-go and the checklist off the screen."""

    def compose(self) -> ComposeResult:
        with Vertical(classes="dialog"):
            yield Label(self.title_text, classes="dialog-title", markup=False)
            yield Static(self.prompt, classes="dialog-body", markup=False)
            yield Input(placeholder=self.placeholder, id="answer", max_length=self.max_length)

    def on_mount(self) -> None:
        self.query_one("#answer", Input).focus()

    def on_input_submitted(self, event: Input.Submitted) -> None:
        self.dismiss(event.value)

    def action_cancel(self) -> None:
        self.dismiss(None)


@dataclass(frozen=True)
class HazardConfirmation:
    typed_name: str
    second_operator: str
    single_operator_waiver: str
    override_reason: str = ""
    await_approval: bool = False
    """Ask another login to approve (``drs approve``) instead of a typed second name."""


SECOND_LOGIN_ONLY = (
    "Second operator: another login must approve (require_second_operator): Enter or Ask another login "
    "files the request; they approve with drs approve or the Approvals screen."
)


class HazardModal(ModalScreen[HazardConfirmation | None]):
    """FIRE or PARACHUTE: type the capsule's name; a second operator or a single-operator waiver.

    With ``second_required`` (``[console] require_second_operator``) only another login's approval counts,
    so the dialog offers only that: the typed name and waiver fields, always refused there, are not shown,
    and submitting asks another login."""

    BINDINGS = [
        Binding("escape", "cancel", "Cancel"),
        Binding("enter", "next_field", show=False, priority=True),
    ]
    """Enter moves to the next field as a priority binding: the app runs it in the order the keys
    arrived, before it routes the next key. Moved on a field's own Submitted message instead, keys
    that reached the console in one burst (a slow SSH link, a busy console) were routed to the old
    field first, and a waiver reason was once recorded as the second operator's name."""

    def __init__(
        self,
        capsule: str,
        action: str,
        consequence: str,
        second_required: bool,
        override_prompt: str | None = None,
        countdown: Callable[[], str] | None = None,
    ) -> None:
        super().__init__()
        self.capsule = capsule
        self.action_name = action
        self.consequence = consequence
        self.second_required = second_required
        self.override_prompt = override_prompt
        """When a safety check does not hold (PARACHUTE without landed evidence): what the override means."""
        self.countdown = countdown
        """The deadline this action must meet, as text, read every second (the ARM window, PARACHUTE's
        queue-before): the dialog covers the screen that shows it, so it shows it itself."""

    def compose(self) -> ComposeResult:
        need = "required" if self.second_required else "optional"
        # It scrolls: at 80×24 the PARACHUTE dialog with its override field is taller than the screen, and
        # a field or button that Tab or Enter reaches is scrolled into sight.
        with VerticalScroll(classes="dialog hazard"):
            yield Label(f"{self.action_name} {self.capsule}", classes="dialog-title", markup=False)
            if self.countdown is not None:
                yield Label(self.countdown(), id="countdown", classes="dialog-warning", markup=False)
            yield Static(self.consequence, classes="dialog-body", markup=False)
            yield Label(f"Type the capsule's name ({self.capsule}) to confirm:", markup=False)
            yield Input(id="typed", placeholder="capsule name")
            if self.second_required:
                yield Static(SECOND_LOGIN_ONLY, classes="dialog-body", markup=False)
            else:
                yield Label(f"Second operator ({need}; a different person):", markup=False)
                yield Input(id="second", placeholder="name")
                yield Label("…or single-operator waiver (why you are alone):", markup=False)
                yield Input(id="waiver", placeholder="reason (logged)", max_length=WAIVER_REASON_MAX)
            if self.override_prompt is not None:
                # A Static wraps; the Label it was ran to 161 columns and scrolled sideways.
                yield Static(self.override_prompt, markup=False, classes="dialog-warning")
                yield Input(
                    id="override",
                    placeholder="override reason (logged with the evidence)",
                    max_length=WAIVER_REASON_MAX,
                )
            with Horizontal(classes="dialog-buttons"):
                yield Button("Cancel", id="cancel", variant="primary")
                yield Button(
                    "Ask another login",
                    id="approval",
                    tooltip="the second operator approves with drs approve",
                )
                if not self.second_required:
                    yield Button(self.action_name, id="confirm", variant="error")

    def on_mount(self) -> None:
        self.query_one("#typed", Input).focus()
        if self.countdown is not None:
            self.set_interval(1.0, self.tick)

    def tick(self) -> None:
        if self.countdown is not None:
            self.query_one("#countdown", Label).update(self.countdown())

    def _field(self, field_id: str) -> str:
        found = self.query(f"#{field_id}")
        return found.first(Input).value.strip() if found else ""

    def _answer(self) -> HazardConfirmation:
        return HazardConfirmation(
            self._field("typed"), self._field("second"), self._field("waiver"), self._field("override"),
            await_approval=self.second_required,
        )  # fmt: skip

    def _last_field(self) -> str:
        if self.override_prompt is not None:
            return "override"
        return "typed" if self.second_required else "waiver"

    def action_next_field(self) -> None:
        """On the last field (or a button) Enter goes on to the widget: the last field's Submitted
        comes after the characters queued before it, so the answer is read whole. Elsewhere Enter moves
        to the next FIELD, never to a button: once it landed on Cancel and the next Enter closed the
        dialog unseen."""
        focused = self.focused
        if not isinstance(focused, Input) or focused.id == self._last_field():
            raise SkipAction()
        fields = list(self.query(Input))
        self.set_focus(fields[fields.index(focused) + 1])  # at once, not after the keys already queued

    def on_input_submitted(self, event: Input.Submitted) -> None:
        if event.input.id == self._last_field():
            self.dismiss(self._answer())

    def on_button_pressed(self, event: Button.Pressed) -> None:
        if event.button.id == "approval":
            self.dismiss(replace(self._answer(), await_approval=True))
            return
        if event.button.id == "confirm":
            self.dismiss(self._answer())
        else:
            self.action_cancel()

    def action_cancel(self) -> None:
        """Cancelled, and said so: a dialog that closes without a word leaves the operator unsure."""
        self.app.notify(f"{self.action_name} {self.capsule} cancelled: nothing sent")
        self.dismiss(None)

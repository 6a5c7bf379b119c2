"""The messages workers send the app: what came in, and what to tell the operator.

They live apart from the app so that the screens, whose workers post them, never import the app
(the app imports the screens). Both are safe to post from a worker thread.
"""

from __future__ import annotations

from textual.message import Message
from textual.notifications import SeverityLevel
from textual.worker import Worker, WorkerState

from drs_link.ops import IridiumHealthView, RecoveryView, ReleaseWindow, TelemetryRecord
from drs_link.server import HistoryView


class TelemetryArrived(Message):
    """Records from a worker (poll, command, replay); folded into the fleet state on the UI thread."""

    def __init__(self, records: list[TelemetryRecord]) -> None:
        super().__init__()
        self.records = records


class OperatorNotice(Message):
    """A one-line result or refusal for the operator (never a traceback)."""

    def __init__(self, text: str, severity: SeverityLevel = "information") -> None:
        super().__init__()
        self.text = text
        self.severity = severity


def failure_notice(event: Worker.StateChanged) -> OperatorNotice | None:
    """What a worker raised that its own handler did not expect (a bug, a malformed answer), for the
    operator: a Sync that failed so must not leave "syncing data…" as the last word.

    Textual posts a worker's state to the node that runs it and does not bubble it, so the app and
    every screen each pass theirs here; a worker with ``exit_on_error=False`` is otherwise silent."""
    error = event.worker.error
    if event.state is not WorkerState.ERROR or error is None:
        return None
    doing = event.worker.name.removeprefix("action_").replace("_", " ") or "a background task"
    return OperatorNotice(f"{doing} failed: {type(error).__name__}: {error}", "error")


View = RecoveryView | IridiumHealthView | ReleaseWindow
"""What the app's workers deliver to the screens, each of one capsule."""


class ViewWanted(Message):
    """A screen shows this view of a capsule (``"recovery"``, ``"iridium"`` or ``"window"``, the release
    window): the app reads it in a worker now and whenever the store or the capsule's telemetry changes
    (the screen never reads the store, nor starts the work itself)."""

    def __init__(self, kind: str, capsule: str) -> None:
        super().__init__()
        self.kind = kind
        self.capsule = capsule


class ViewRead(Message, bubble=False):
    """A capsule's view as the store (or the replay, or the planner) had it: to the app, which hands it on
    to the screens that show it (not bubbling, so a screen's copy never comes back to the app)."""

    def __init__(self, kind: str, capsule: str, view: View) -> None:
        super().__init__()
        self.kind = kind
        self.capsule = capsule
        self.view = view


class AuditRead(Message):
    """The audit entries after the last one shown, read when the server's audit moved on: posted, never
    waited for (a worker that waited on the app while it quit would hold the quit up)."""

    def __init__(self, after: HistoryView) -> None:
        super().__init__()
        self.after = after

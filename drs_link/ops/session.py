"""A console session that ends without quitting: the SSH link drops (SIGHUP) or the machine stops it
(SIGTERM). The quit path asks, disarms on the record and refuses while Go is being sent; a lost
session must leave the same record without anyone to ask.

So the console, on either signal, disarms every open ARM window with the reason "session lost",
lets a Go already in flight finish and be recorded by its own worker, and writes one
``session.lost`` row saying what was open. The next console to start on the store shows that row
until a session has started after it ("session lost at 01:23:45Z while ARMED DRS1: disarmed").
"""

from __future__ import annotations

import json
from collections.abc import Mapping
from dataclasses import dataclass
from datetime import datetime

from drs_link.ops.typed_text import typed_text
from drs_link.store import Store, parse_iso_utc

LOST = "session.lost"
STARTED = "session.started"


@dataclass(frozen=True)
class SessionLoss:
    time: datetime
    signal: str
    disarmed: tuple[str, ...]
    """Capsules whose ARM window was open and is now closed."""
    go_in_flight: tuple[str, ...]
    """Capsules whose Go was being sent: their own worker finishes and records it."""
    session: str | None

    def describe(self) -> str:
        parts = [f"session lost at {self.time:%H:%M:%S}Z ({self.signal})"]
        if self.disarmed:
            parts.append(f"while ARMED {', '.join(self.disarmed)}: disarmed")
        if self.go_in_flight:
            parts.append(f"with Go in flight to {', '.join(self.go_in_flight)}: see its record in History")
        if not self.disarmed and not self.go_in_flight:
            parts.append("nothing was armed or in flight")
        return "; ".join(parts)


def unprotected_ssh_warning(environ: Mapping[str, str]) -> str | None:
    """Over SSH and outside tmux or screen, a dropped link ends the console: say so at the start."""
    if environ.get("SSH_CONNECTION") and not (environ.get("TMUX") or environ.get("STY")):
        return (
            "this console runs over SSH outside tmux or screen: if the link drops, the console ends "
            "(disarmed, on the record). Run long operations inside tmux (tmux new -s drs) or screen."
        )
    return None


def record_loss(
    store: Store, operator: str, signal: str, disarmed: list[str], go_in_flight: list[str]
) -> SessionLoss:
    """Write the loss itself, after the console had its open windows (``disarmed``) closed by the
    operations server (each disarm audited there). The signal's name is refused if it holds control or
    format characters: the next console shows it to its operator."""
    record = store.append_audit(operator, None, LOST, "disarmed" if disarmed else "recorded",
                                {"signal": typed_text("the signal", signal), "disarmed": disarmed, "go_in_flight": go_in_flight})  # fmt: skip
    return SessionLoss(record.time_utc, signal, tuple(disarmed), tuple(go_in_flight), record.session)


def record_start(store: Store, operator: str) -> SessionLoss | None:
    """Note that a console started; return the loss that ended the session before, if nobody has
    started one since (that console was the last to know)."""
    last = store.query("SELECT * FROM audit WHERE action IN (?, ?) ORDER BY id DESC LIMIT 1", (LOST, STARTED))
    loss = None
    if last and last[0]["action"] == LOST:
        row = last[0]
        detail = json.loads(row["detail"] or "{}")
        loss = SessionLoss(
            parse_iso_utc(row["time_utc"]), str(detail.get("signal")), tuple(detail.get("disarmed", ())),
            tuple(detail.get("go_in_flight", ())), row["session"],
        )  # fmt: skip
    store.append_audit(operator, None, STARTED, "started")
    return loss

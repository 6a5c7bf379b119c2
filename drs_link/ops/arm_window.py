"""The ARM windows of every capsule, in the store: one open window per capsule, across processes.

Why in the store: two consoles on one store could both be ARMED on one capsule, each showing the other's
notices against its own state, and `drs capsule arm` then `drs capsule go` are two processes. Each
window is a row with its own id (an approval names the window it was given for); opening one is a
compare-and-set inside one ``BEGIN IMMEDIATE`` transaction, so of two consoles arming at once exactly
one wins and the other is told who holds it. Closing a window (expiry, disarm, FIRE done or failed)
is a compare-and-set too, so it is audited once, by whichever process saw it first.
"""

from __future__ import annotations

import os
import secrets
import sqlite3
from dataclasses import dataclass
from datetime import datetime

from drs_link.store import Store, iso_utc, parse_iso_utc, session_name

DDL = """
CREATE TABLE IF NOT EXISTS arm_window (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    capsule TEXT NOT NULL,
    holder TEXT NOT NULL,
    session TEXT NOT NULL,
    operator TEXT NOT NULL,
    armed_utc TEXT NOT NULL,
    until_utc TEXT NOT NULL,
    fingerprint TEXT NOT NULL,
    state TEXT NOT NULL,
    closed_utc TEXT,
    reason TEXT
);
CREATE INDEX IF NOT EXISTS arm_window_capsule ON arm_window (capsule, id);
"""
_LATER_COLUMNS = {"report": "TEXT"}
"""Added in place to stores made before them: the go/no-go poll ARM was granted on, with its waivers
(``drs_link.ops.brief.report_json``), which a Go approval shows its approver."""
ARMED, FIRING, FIRED, CLOSED = "armed", "firing", "fired", "closed"
_TOKENS: dict[int, str] = {}


def process_holder() -> str:
    """Who holds a window this process opens: its session (account@host pid) and a random token drawn
    once per process. Why the token: a console that crashed while ARMED leaves its window open until it
    runs out, and a new process that the kernel gives the same pid must not be able to FIRE in it."""
    token = _TOKENS.setdefault(os.getpid(), secrets.token_hex(4))
    return f"{session_name()} #{token}"


@dataclass(frozen=True)
class ArmWindow:
    """One ARM window: who opened it (``holder``: the console process, or ``account@host drs`` for the
    CLI's arm-then-go), where (``session``: account@host pid, as the audit shows it) and until when."""

    id: int
    capsule: str
    holder: str
    session: str
    operator: str
    armed_utc: datetime
    until_utc: datetime
    fingerprint: str
    state: str
    reason: str | None
    report: str | None = None
    """The poll ARM was granted on (JSON, ``drs_link.ops.brief``); None for windows from before it."""

    def open_at(self, now: datetime) -> bool:
        return self.state == ARMED and now < self.until_utc

    def who(self) -> str:
        return f"{self.operator} at {self.session}"


class ArmWindows:
    """The windows of all capsules; every change one compare-and-set."""

    def __init__(self, store: Store) -> None:
        self.store = store
        store.ensure_schema(DDL)
        have = {str(row["name"]) for row in store.query("PRAGMA table_info(arm_window)")}
        missing = [(name, kind) for name, kind in _LATER_COLUMNS.items() if name not in have]
        if missing:
            with store.transaction() as conn:
                for name, kind in missing:
                    if name not in {str(r["name"]) for r in conn.execute("PRAGMA table_info(arm_window)")}:
                        conn.execute(f"ALTER TABLE arm_window ADD COLUMN {name} {kind}")

    def latest(self, capsule: str) -> ArmWindow | None:
        rows = self.store.query(
            "SELECT * FROM arm_window WHERE capsule = ? ORDER BY id DESC LIMIT 1", (capsule,)
        )
        return _window(rows[0]) if rows else None

    def get(self, window_id: int) -> ArmWindow | None:
        rows = self.store.query("SELECT * FROM arm_window WHERE id = ?", (window_id,))
        return _window(rows[0]) if rows else None

    def open(
        self,
        capsule: str,
        holder: str,
        session: str,
        operator: str,
        now: datetime,
        until: datetime,
        fingerprint: str,
        report: str | None = None,
    ) -> tuple[ArmWindow | None, ArmWindow | None]:
        """Open a window unless another holder's is open or a FIRE is under way: (new window, None), or
        (None, the window in the way). The holder's own open window is closed ("re-armed") first."""
        with self.store.transaction() as conn:
            rows = conn.execute(
                "SELECT * FROM arm_window WHERE capsule = ? ORDER BY id DESC LIMIT 1", (capsule,)
            ).fetchall()
            current = _window(rows[0]) if rows else None
            if current is not None:
                busy = current.state in (FIRING, FIRED)
                if busy or (current.open_at(now) and current.holder != holder):
                    return None, current
                if current.state == ARMED:
                    conn.execute(
                        "UPDATE arm_window SET state = ?, closed_utc = ?, reason = ? WHERE id = ?",
                        (
                            CLOSED,
                            iso_utc(now),
                            "re-armed" if current.open_at(now) else expired_reason(current),
                            current.id,
                        ),
                    )
            row_id = conn.execute(
                "INSERT INTO arm_window (capsule, holder, session, operator, armed_utc, until_utc, fingerprint, "
                "state, report) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    capsule,
                    holder,
                    session,
                    operator,
                    iso_utc(now),
                    iso_utc(until),
                    fingerprint,
                    ARMED,
                    report,
                ),
            ).lastrowid
        return self.get(int(row_id or 0)), None

    def close(
        self, window_id: int, reason: str, now: datetime, from_states: tuple[str, ...] = (ARMED,)
    ) -> bool:
        """Close a window still in one of ``from_states``; whether this call closed it."""
        marks = ", ".join("?" for _ in from_states)
        with self.store.transaction() as conn:
            changed = conn.execute(
                f"UPDATE arm_window SET state = ?, closed_utc = ?, reason = ? WHERE id = ? AND state IN ({marks})",
                (CLOSED, iso_utc(now), reason, window_id, *from_states),
            ).rowcount
        return bool(changed)

    def start_firing(self, window_id: int, holder: str, now: datetime) -> bool:
        """ARMED → FIRING, only for the holder and only inside the window."""
        with self.store.transaction() as conn:
            return start_firing_in(conn, window_id, holder, now)

    def fired(self, window_id: int, now: datetime) -> None:
        """FIRING → FIRED: the Go this window authorised reached the Pi (or was finished later)."""
        with self.store.transaction() as conn:
            conn.execute(
                "UPDATE arm_window SET state = ?, closed_utc = ? WHERE id = ? AND state = ?",
                (FIRED, iso_utc(now), window_id, FIRING),
            )


def start_firing_in(conn: sqlite3.Connection, window_id: int, holder: str, now: datetime) -> bool:
    """``ArmWindows.start_firing`` inside a transaction the caller holds: a Go approval is marked used
    in the same one (``ApprovalBook.use``), so neither happens without the other."""
    changed = conn.execute(
        "UPDATE arm_window SET state = ? WHERE id = ? AND state = ? AND holder = ? AND until_utc > ?",
        (FIRING, window_id, ARMED, holder, iso_utc(now)),
    ).rowcount
    return bool(changed)


def expired_reason(window: ArmWindow) -> str:
    """The disarm reason of a window that ran out, as the console and the CLI both say it."""
    return f"ARM window expired at {window.until_utc:%H:%M:%S}Z"


def _window(row: sqlite3.Row) -> ArmWindow:
    return ArmWindow(
        id=int(str(row["id"])),
        capsule=str(row["capsule"]),
        holder=str(row["holder"]),
        session=str(row["session"]),
        operator=str(row["operator"]),
        armed_utc=parse_iso_utc(str(row["armed_utc"])),
        until_utc=parse_iso_utc(str(row["until_utc"])),
        fingerprint=str(row["fingerprint"]),
        state=str(row["state"]),
        reason=None if row["reason"] is None else str(row["reason"]),
        report=None if row["report"] is None else str(row["report"]),
    )

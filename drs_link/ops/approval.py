"""Second-operator approval from another session: the two-person rule as mission control keeps it.

Why: a second name typed into the same dialog lets one person at one keyboard satisfy the two-person
rule. COSMOS and Yamcs take a critical command's approval from another operator's own session. Here a
hazardous command (Go with the rule on, PARACHUTE, a take-over of release authority) can wait as
*pending approval* in the store until a different login approves or rejects it, from a second
console or with `drs approve`. The login is an OS account as the kernel names it (the operations
server reads it from each connection, ``drs_link.server.peers``), never a typed name or a variable. A
request expires (``APPROVAL_TTL_S``), an approval is used once, and both identities are
audited. The typed-name waiver
stays as the logged single-operator path.

Every change of a request is one compare-and-set in SQLite, so two approvers, or an approval racing
its expiry, can never both win.

A request is bound to one action instance: the capsule, the action, the exact command (the MT text, or
the ARM window's id) and a deadline (the window's end, the PARACHUTE's queue-before time). It is void
when its ARM window closes or the capsule's release state changes, and its requester may cancel it;
``use`` checks the binding again, so an approval can only ever send the command it was given for.
"""

from __future__ import annotations

import os
import sqlite3
import time
from collections.abc import Callable
from dataclasses import dataclass, field
from datetime import datetime, timedelta

from drs_link.errors import RefusedError
from drs_link.ops.arm_window import ARMED, DDL as ARM_WINDOW_DDL
from drs_link.ops.brief import ApprovalBrief
from drs_link.ops.typed_text import shown, typed_text
from drs_link.store import Store, account_of, iso_utc, parse_iso_utc

APPROVAL_TTL_S = 300.0
"""How long a request may wait for its approval, and an approval for its use: long enough to reach
the second operator on the radio, short enough that an old approval never sends a command today."""
ACTIONS = {"go": "Go (release)", "parachute": "PARACHUTE", "authority": "release-authority take-over"}

_DDL = """
CREATE TABLE IF NOT EXISTS approval (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    capsule TEXT NOT NULL,
    action TEXT NOT NULL,
    summary TEXT NOT NULL,
    requested_by TEXT NOT NULL,
    requester_user TEXT NOT NULL,
    requested_utc TEXT NOT NULL,
    expires_utc TEXT NOT NULL,
    state TEXT NOT NULL,
    decided_by TEXT,
    decider_user TEXT,
    decided_utc TEXT,
    reason TEXT
);
CREATE INDEX IF NOT EXISTS approval_state ON approval (state, expires_utc);
"""
_BINDING_COLUMNS = {"command": "TEXT", "window_id": "INTEGER", "capsule_state": "TEXT", "brief": "TEXT"}
"""What one request is bound to and what its approver is shown (``brief``); added in place to stores made
before them (NULL for old rows). A store from before the operations server also has ``requester_key`` and
``decider_key`` (an ssh-agent key's fingerprint): nothing reads them any more, and its rows read as before."""
USABLE = (
    f"state IN ('pending', 'approved') AND expires_utc > ? AND (window_id IS NULL OR window_id IN "
    f"(SELECT id FROM arm_window WHERE state = '{ARMED}' AND until_utc > ?))"
)
"""SQL: a request that can still be decided or spent: not expired, and its ARM window (if any) still open."""


def window_command(window_id: int) -> str:
    """The exact command a Go approval is bound to: one ARM window."""
    return f"ARM window #{window_id}"


@dataclass(frozen=True)
class Login:
    """Who is at a keyboard, as the kernel knows it: an OS account. Two accounts are two people, and one
    account is one person however many sessions it has."""

    user: str
    person: str | None = field(default=None, compare=False)
    """The operator name the server's ``[[operator]]`` list gives the account: the name it acts under."""

    def same_person(self, other: Login) -> bool:
        return self.user == other.user

    def __str__(self) -> str:
        return self.user


def current_login() -> Login:
    """This process's login: the OS account of the real uid, which only login, sshd, su or sudo set
    (``$USER`` and ``$LOGNAME`` are the shell's). It is the one account a private server serves."""
    return Login(account_of(os.getuid()))


@dataclass(frozen=True)
class Approval:
    id: int
    capsule: str
    action: str
    summary: str
    requested_by: str
    requester: Login
    requested_utc: datetime
    expires_utc: datetime
    state: str
    """pending, approved, rejected, used, void (its window closed, the capsule's state changed) or
    cancelled (an expired request keeps its state and is refused by time)."""
    decided_by: str | None
    decider: Login | None
    reason: str | None
    command: str | None = None
    """The exact command it was given for: the MT text, ``ARM window #N``, or the take-over's reason."""
    window_id: int | None = None
    capsule_state: str | None = None
    """The capsule's release state when it was asked for: any change voids it."""
    brief: ApprovalBrief | None = None
    """What the approver is shown (``drs_link.ops.brief``); None for a request from before it."""

    def expired(self, now: datetime) -> bool:
        return now >= self.expires_utc

    def reason_text(self, now: datetime) -> str:
        """Its state with why it ended, as a refusal says it."""
        if self.state in ("void", "cancelled") and self.reason:
            return f"{self.state} ({self.reason})"
        return self.status(now)

    def status(self, now: datetime) -> str:
        if self.state in ("pending", "approved") and self.expired(now):
            return f"{self.state}, expired {self.expires_utc:%H:%M:%S}Z"
        return self.state

    def describe(self, now: datetime) -> str:
        """One line; every text a person typed goes through ``shown`` (a stored row may predate the rule)."""
        left = (self.expires_utc - now).total_seconds()
        when = f"{left:.0f} s left" if left > 0 else "expired"
        who = f" by {shown(self.decided_by)} ({shown(self.decider)})" if self.decided_by else ""
        return (
            f"#{self.id} {shown(self.capsule)} {ACTIONS.get(self.action, shown(self.action))}: {shown(self.summary)} "
            f"— requested by {shown(self.requested_by)} ({shown(self.requester)}) — {shown(self.status(now))}{who}"
            f"{', ' + when if self.state in ('pending', 'approved') else ''}"
        )

    def for_approver(self, now: datetime) -> list[str]:
        """What the approver reads before deciding, the same in `drs approve` and the console: the
        request's line, then the brief (the exact command, the go/no-go verdicts, every waiver with its
        reason and author, the landed evidence or the override reason)."""
        brief = self.brief or ApprovalBrief(self.command or "(bound to no command: asked for before briefs)")
        return [self.describe(now), *brief.lines()]


class ApprovalBook:
    """The approval requests in the store."""

    def __init__(self, store: Store, clock: Callable[[], datetime] | None = None) -> None:
        self.store = store
        self.clock = clock or store.clock
        """The store's time by default: a demo's simulated time is every process's (``Store.run_clock``)."""
        store.ensure_schema(_DDL)
        store.ensure_schema(ARM_WINDOW_DDL)
        have = {str(row["name"]) for row in store.query("PRAGMA table_info(approval)")}
        missing = [(name, kind) for name, kind in _BINDING_COLUMNS.items() if name not in have]
        if missing:
            with store.transaction() as conn:
                for name, kind in missing:
                    conn.execute(f"ALTER TABLE approval ADD COLUMN {name} {kind}")

    def request(
        self,
        capsule: str,
        action: str,
        summary: str,
        operator: str,
        login: Login,
        ttl_s: float = APPROVAL_TTL_S,
        *,
        command: str | None = None,
        window_id: int | None = None,
        deadline: datetime | None = None,
        capsule_state: str | None = None,
        brief: ApprovalBrief | None = None,
    ) -> Approval:
        """A pending request another login must approve before ``expires`` (the TTL or the action's own
        deadline, whichever is first), bound to ``command``/``window_id``/``capsule_state``, with the
        ``brief`` its approver reads (default: the command alone); audited."""
        if action not in ACTIONS:
            raise ValueError(f"unknown hazardous action {action!r}")
        now, operator = self.clock(), login.person or operator
        expires = now + timedelta(seconds=ttl_s)
        if deadline is not None:
            expires = min(expires, deadline)
        brief = brief or ApprovalBrief(command or summary)
        with self.store.transaction() as conn:
            row_id = conn.execute(
                "INSERT INTO approval (capsule, action, summary, requested_by, requester_user, "
                "requested_utc, expires_utc, state, command, window_id, capsule_state, brief) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, 'pending', ?, ?, ?, ?)",
                (capsule, action, summary, operator, login.user, iso_utc(now),
                 iso_utc(expires), command, window_id, capsule_state, brief.to_json()),
            ).lastrowid  # fmt: skip
        self.store.append_audit(operator, capsule, "approval.requested", "pending",
                                {"approval": row_id, "action": action, "summary": summary, "login": str(login),
                                 "command": command, "expires_utc": iso_utc(expires)})  # fmt: skip
        return self.get(int(row_id or 0))

    def get(self, approval_id: int) -> Approval:
        rows = self.store.query("SELECT * FROM approval WHERE id = ?", (approval_id,))
        if not rows:
            raise RefusedError(f"approval #{approval_id} does not exist")
        return _approval(rows[0])

    def open_requests(self, capsule: str | None = None, requested_by: Login | None = None) -> list[Approval]:
        """Pending requests that can still be used (not expired, their ARM window still open), oldest
        first: what an approver is asked about, and what a requester still waits for."""
        now = iso_utc(self.clock())
        sql = f"SELECT * FROM approval WHERE state = 'pending' AND {USABLE}"
        params: tuple[str, ...] = (now, now)
        if capsule is not None:
            sql, params = sql + " AND capsule = ?", (*params, capsule)
        requests = [_approval(row) for row in self.store.query(sql + " ORDER BY id", params)]
        if requested_by is not None:
            requests = [r for r in requests if r.requester.same_person(requested_by)]
        return requests

    def spent_for_window(self, capsule: str, window_id: int) -> Approval | None:
        """The Go approval used to FIRE in ARM window ``window_id`` (``Release.finish_go`` asks whether it
        is still valid), else None."""
        rows = self.store.query(
            "SELECT * FROM approval WHERE capsule = ? AND action = 'go' AND window_id = ? AND state = 'used' "
            "ORDER BY id DESC LIMIT 1",
            (capsule, window_id),
        )
        return _approval(rows[0]) if rows else None

    def usable(self, request: Approval) -> bool:
        """Whether a request can still be decided or spent (see ``USABLE``)."""
        now = iso_utc(self.clock())
        rows = self.store.query(f"SELECT id FROM approval WHERE id = ? AND {USABLE}", (request.id, now, now))
        return bool(rows)

    def _end(
        self, where: str, params: tuple[object, ...], state: str, reason: str, operator: str
    ) -> list[int]:
        """Move every matching pending/approved request to ``state`` (void, cancelled); audited each."""
        with self.store.transaction() as conn:
            rows = conn.execute(
                f"SELECT id, capsule FROM approval WHERE state IN ('pending', 'approved') AND {where}", params
            ).fetchall()
            for row in rows:
                conn.execute(
                    "UPDATE approval SET state = ?, reason = ? WHERE id = ?", (state, reason, row["id"])
                )
        for row in rows:
            self.store.append_audit(operator, str(row["capsule"]), f"approval.{state}", state,
                                    {"approval": int(row["id"]), "reason": reason})  # fmt: skip
        return [int(row["id"]) for row in rows]

    def void_window(self, capsule: str, window_id: int, reason: str, operator: str) -> list[int]:
        """The ARM window closed: every request given for it is void."""
        return self._end("capsule = ? AND window_id = ?", (capsule, window_id), "void", reason, operator)

    def void_capsule(self, capsule: str, reason: str, operator: str) -> list[int]:
        """The capsule's release state changed (power-on, release, reset): every request for it is void."""
        return self._end("capsule = ?", (capsule,), "void", reason, operator)

    def cancel(self, approval_id: int, operator: str, login: Login, why: str | None = None) -> Approval:
        """The requester withdraws a request (pending or approved, not yet spent); audited. ``why``: when
        the requester did not (the server stopped, their connection dropped), the reason said instead of
        "cancelled by" them."""
        request = self.get(approval_id)
        if not request.requester.same_person(login):
            raise RefusedError(
                f"approval #{approval_id} was requested by {request.requester}; only they can cancel it"
            )
        if not self._end("id = ?", (approval_id,), "cancelled", why or f"cancelled by {operator}", operator):
            now = self.get(approval_id).status(self.clock())
            raise RefusedError(f"approval #{approval_id} is {now}: nothing to cancel")
        return self.get(approval_id)

    def decide(
        self, approval_id: int, operator: str, login: Login, approve: bool, reason: str = ""
    ) -> Approval:
        """Approve or reject a pending request from a login that is not the requester's."""
        typed_text("the approval's reason", reason)
        request = self.get(approval_id)
        now, operator = self.clock(), login.person or operator
        verdict = "approved" if approve else "rejected"

        def refuse(why: str) -> RefusedError:
            self.store.append_audit(operator, request.capsule, f"approval.{verdict}", "refused",
                                    {"approval": approval_id, "reason": why, "login": str(login)})  # fmt: skip
            return RefusedError(f"approval #{approval_id} refused: {why}")

        if request.requester.same_person(login):
            raise refuse(
                f"the same login ({login}) that requested it cannot approve it: run drs approve from another "
                "person's OS account"
            )
        if operator.casefold() == request.requested_by.casefold():
            raise refuse(
                f"{operator} requested it and cannot approve it too: "
                "the second operator approves under their own name"
            )
        with self.store.transaction() as conn:
            changed = conn.execute(
                "UPDATE approval SET state = ?, decided_by = ?, decider_user = ?, decided_utc = ?, "
                f"reason = ? WHERE id = ? AND state = 'pending' AND {USABLE}",
                (verdict, operator, login.user, iso_utc(now), reason.strip() or None,
                 approval_id, iso_utc(now), iso_utc(now)),
            ).rowcount  # fmt: skip
        if not changed:
            raise refuse(f"it is {self.why_not(self.get(approval_id), now)}, not pending")
        self.store.append_audit(operator, request.capsule, f"approval.{verdict}", verdict,
                                {"approval": approval_id, "action": request.action, "requested_by": request.requested_by,
                                 "requester_login": str(request.requester), "login": str(login),
                                 "reason": reason.strip()})  # fmt: skip
        return self.get(approval_id)

    def why_not(self, request: Approval, now: datetime, conn: sqlite3.Connection | None = None) -> str:
        """A request's state as a refusal says it, naming a closed ARM window as the reason; read through
        ``conn`` inside a transaction that holds the store."""
        if conn is not None:
            request = _approval(conn.execute("SELECT * FROM approval WHERE id = ?", (request.id,)).fetchone())
            usable = bool(conn.execute(f"SELECT id FROM approval WHERE id = ? AND {USABLE}",
                                       (request.id, iso_utc(now), iso_utc(now))).fetchall())  # fmt: skip
            if request.state in ("pending", "approved") and request.window_id is not None and not usable:
                return f"void (ARM window #{request.window_id} closed)"
            return request.reason_text(now)
        if (
            request.state in ("pending", "approved")
            and request.window_id is not None
            and not self.usable(request)
        ):
            return f"void (ARM window #{request.window_id} closed)"
        return request.reason_text(now)

    def wait(self, approval_id: int, poll_s: float = 0.25) -> Approval:
        """Block until the request is decided, expires, or can no longer be used (its window closed)."""
        while True:
            request = self.get(approval_id)
            if request.state != "pending" or not self.usable(request):
                return request
            time.sleep(poll_s)

    def use(
        self,
        approval_id: int,
        capsule: str,
        action: str,
        login: Login,
        command: str | None = None,
        capsule_state: str | None = None,
        also: Callable[[sqlite3.Connection], str | None] | None = None,
    ) -> dict[str, str]:
        """Spend an approval on the command it was given for, once; what to audit with the command.

        ``command`` and ``capsule_state`` are what is about to be sent and the capsule's state now: an
        approval bound to another command, window or state is refused. ``also`` is the state change the
        approval is spent on (an ARM window going FIRING): it runs in the same transaction as the mark
        ``used`` and returns a refusal (or None); a refusal rolls both back. So every check comes first
        and an approval is never spent on a command that was then refused (issue #29).
        """
        request = self.check(approval_id, capsule, action, login, command, capsule_state)

        def spend(conn: sqlite3.Connection) -> None:
            self.spend_in(conn, request)
            refusal = also(conn) if also is not None else None
            if refusal is not None:
                raise NotSpent(refusal)

        with self.store.transaction() as conn:
            spend(conn)
        return self.spent(request, command)

    def check(
        self,
        approval_id: int,
        capsule: str,
        action: str,
        login: Login,
        command: str | None = None,
        capsule_state: str | None = None,
    ) -> Approval:
        """Everything ``use`` checks, spending nothing: the request, approved and usable now, for exactly
        this capsule, action, requester, command and state; else RefusedError."""
        request = self.get(approval_id)
        now = self.clock()
        if request.capsule != capsule or request.action != action:
            raise RefusedError(
                f"approval #{approval_id} was given for {request.capsule} {ACTIONS.get(request.action)}, "
                f"not {capsule} {ACTIONS.get(action)}"
            )
        if not request.requester.same_person(login):
            raise RefusedError(
                f"approval #{approval_id} was requested by {request.requester}, not by {login}"
            )
        if request.command is None:  # a request from before the binding: it could fire any window
            raise RefusedError(
                f"approval #{approval_id} is bound to no command (asked for before approvals were bound to "
                "one action); ask for a new one"
            )
        if command is not None and request.command != command:
            raise RefusedError(f"approval #{approval_id} was given for {request.command}, not {command}")
        if (
            request.capsule_state is not None
            and capsule_state is not None
            and request.capsule_state != capsule_state
        ):
            self.void_capsule(
                capsule, f"capsule state changed: {request.capsule_state} → {capsule_state}", "drs"
            )
            raise RefusedError(
                f"approval #{approval_id} was given while {capsule} was {request.capsule_state}; "
                f"it is now {capsule_state}"
            )
        if request.state != "approved" or not self.usable(request):
            raise RefusedError(f"approval #{approval_id} is {self.why_not(request, now)}, not approved")
        return request

    def spend_in(self, conn: sqlite3.Connection, request: Approval) -> None:
        """Mark a checked request used inside the caller's transaction, the one that makes the state change
        it is spent on (an MT row, a window going FIRING); NotSpent (rolling both back) if it is no longer
        approved and usable."""
        now = self.clock()
        changed = conn.execute(
            f"UPDATE approval SET state = 'used' WHERE id = ? AND state = 'approved' AND {USABLE}",
            (request.id, iso_utc(now), iso_utc(now)),
        ).rowcount
        if not changed:
            raise NotSpent(f"approval #{request.id} is {self.why_not(request, now, conn)}, not approved")

    def spent(self, request: Approval, command: str | None = None) -> dict[str, str]:
        """After the transaction that spent it: audited; what to audit with the command."""
        self.store.append_audit(request.requested_by, request.capsule, "approval.used", "used",
                                {"approval": request.id, "command": command or request.command})  # fmt: skip
        return {"approved_by": f"{request.decided_by} ({request.decider})", "approval": str(request.id)}


def _approval(row: sqlite3.Row) -> Approval:
    decider = Login(str(row["decider_user"])) if row["decider_user"] else None
    return Approval(
        id=int(str(row["id"])),
        capsule=str(row["capsule"]),
        action=str(row["action"]),
        summary=str(row["summary"]),
        requested_by=str(row["requested_by"]),
        requester=Login(str(row["requester_user"])),
        requested_utc=parse_iso_utc(str(row["requested_utc"])),
        expires_utc=parse_iso_utc(str(row["expires_utc"])),
        state=str(row["state"]),
        decided_by=_text(row["decided_by"]),
        decider=decider,
        reason=_text(row["reason"]),
        command=_text(row["command"]),
        window_id=None if row["window_id"] is None else int(str(row["window_id"])),
        capsule_state=_text(row["capsule_state"]),
        brief=ApprovalBrief.from_json(str(row["brief"])) if row["brief"] else None,
    )


class NotSpent(RefusedError):
    """Raised inside the transaction that spends an approval: the mark ``used`` and the state change it
    was spent on roll back together, and the caller is refused."""


def _text(value: object) -> str | None:
    return None if value is None else str(value)


def approved(
    book: ApprovalBook,
    capsule: str,
    action: str,
    summary: str,
    operator: str,
    login: Login,
    on_pending: Callable[[Approval], None],
    *,
    command: str | None = None,
    window_id: int | None = None,
    deadline: datetime | None = None,
    capsule_state: str | None = None,
    brief: ApprovalBrief | None = None,
) -> int:
    """Ask another login to approve and wait (blocking: a worker thread or a CLI); the approval's id
    once approved, else RefusedError saying how the request ended. ``on_pending`` tells the operator
    which request to have approved; the rest is the binding (``ApprovalBook.request``)."""
    request = book.request(
        capsule, action, summary, operator, login,
        command=command, window_id=window_id, deadline=deadline, capsule_state=capsule_state, brief=brief,
    )  # fmt: skip
    on_pending(request)
    try:
        decided = book.wait(request.id)
    except KeyboardInterrupt:  # Ctrl-C at `drs … --await-approval`: nobody waits for it any more
        book.cancel(request.id, operator, login)
        raise
    if decided.state != "approved" or not book.usable(decided):
        why = f" ({decided.reason})" if decided.reason and decided.state == "rejected" else ""
        raise RefusedError(f"approval #{request.id} {book.why_not(decided, book.clock())}{why}: nothing sent")
    return request.id

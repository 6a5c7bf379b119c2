"""An MT command's life, told honestly: what is known, and what can never be known.

requested → confirmed → queued (gateway id) → probably delivered (first report after queueing)
→ effect confirmed / unconfirmable / timed out. Side exits: failed (gateway refused), not sent
(gateway unreachable), delivery unknown (the request may have been queued: never re-sent
automatically), flushed (a later ``flush=yes`` deleted it). The firmware acknowledges nothing, so
"delivered" is only ever *probable* (one MT goes down with each report, oldest first) and only an
INTERVAL or RBDESTINATION change shows in later reports; PARACHUTE and SOUNDER never do.

Only an operator can end "delivery unknown", by recording what the RockBLOCK portal shows: queued
(with the gateway's MT id; the lifecycle then continues, and later commands' attributions move
behind it) or never received (closed as not sent, so it may be requested again).

A real send needs a confirmation that names the capsule, checked here below any UI.
"""

from __future__ import annotations

import fcntl
import json
import os
import signal
import sqlite3
import threading
from collections.abc import Callable, Iterator
from contextlib import contextmanager
from dataclasses import dataclass, replace
from datetime import datetime, timedelta
from pathlib import Path
from typing import Any

from drs_link.config import CapsuleConfig
from drs_link.errors import RefusedError, StoreError
from drs_link.iridium.commands import CATALOGUE, NEVER_VISIBLE, NOT_SEEN, PENDING, SEEN, read_text
from drs_link.iridium.gateway import FLUSH_WARNING, RockblockGateway
from drs_link.iridium.mt import MtMessage
from drs_link.iridium.reports import ReportStore, StoredReport
from drs_link.store import Store, iso_utc, parse_iso_utc, utc_now

COMMANDS_DDL = """
CREATE TABLE IF NOT EXISTS mt_command (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    capsule TEXT NOT NULL,
    imei TEXT NOT NULL,
    operator TEXT NOT NULL,
    text TEXT NOT NULL,
    flush INTEGER NOT NULL,
    state TEXT NOT NULL,
    requested_utc TEXT NOT NULL,
    updated_utc TEXT NOT NULL,
    queued_utc TEXT,
    mt_id INTEGER,
    delivered_report_id INTEGER,
    effects TEXT NOT NULL,
    detail TEXT NOT NULL DEFAULT ''
);
CREATE INDEX IF NOT EXISTS mt_command_imei ON mt_command (imei, id);
"""

REQUESTED = "requested"
CONFIRMED = "confirmed"
QUEUED = "queued"
FAILED = "failed"
NOT_SENT = "not_sent"
DELIVERY_UNKNOWN = "delivery_unknown"
FLUSHED = "flushed"
PROBABLY_DELIVERED = "probably_delivered"
EFFECT_CONFIRMED = "effect_confirmed"
UNCONFIRMABLE = "unconfirmable"
TIMED_OUT = "timed_out"

UNSEEN_NAMES = " and ".join(command.name for command in CATALOGUE if command.confirm is None)
"""The commands no report can show the effect of (the catalogue's without ``confirm``)."""
INTERRUPTED_AFTER = timedelta(minutes=15)
"""A command still ``requested`` or ``confirmed`` this long after was being sent by a process that
stopped (kill -9, a crash, a lost laptop) before the gateway answered: longer than any send can take
(``rockblock.timeout_s`` is at most 600 s; a request is sent at once)."""
RECHECK_REPORTS = 10
"""A confirmed effect stays open to contradiction for this many reports after its delivery: a verdict
read from a few spacings (lost sessions can mimic an interval) is re-read as more come, and later
reports that contradict it re-open it. Bounded so that the work after each post stays small."""
RETRY_WARNING = (
    "if the gateway did queue it, this sends the same MT twice; settle it first with drs mt resolve "
    "(the RockBLOCK portal shows what is queued)"
)
QUEUE_TIMEOUT = timedelta(hours=3)
"""A command still undelivered after this long with no report at all is called timed out."""
_SEND_OUTCOME = {"queued": QUEUED, "failed": FAILED, "not_sent": NOT_SENT, "unknown": DELIVERY_UNKNOWN}


@dataclass(frozen=True)
class Command:
    id: int
    capsule: str
    imei: str
    operator: str
    text: str
    flush: bool
    state: str
    requested_utc: datetime
    updated_utc: datetime
    queued_utc: datetime | None
    """When the gateway queued it; for delivery unknown, when the request went out (the earliest moment)."""
    mt_id: int | None
    delivered_report_id: int | None
    effects: dict[str, str]
    detail: str


@dataclass(frozen=True)
class _Change:
    """One state change to write; ``action`` names it in the audit log (default ``mt.<state>``)."""

    command: Command
    state: str
    detail: str
    columns: dict[str, Any]
    action: str | None = None
    expected: str | None = None
    """The state the command must still be in, or nothing is written (a compare-and-set)."""


def _row_to_command(row: Any) -> Command:
    return Command(
        id=row["id"],
        capsule=row["capsule"],
        imei=row["imei"],
        operator=row["operator"],
        text=row["text"],
        flush=bool(row["flush"]),
        state=row["state"],
        requested_utc=parse_iso_utc(row["requested_utc"]),
        updated_utc=parse_iso_utc(row["updated_utc"]),
        queued_utc=parse_iso_utc(row["queued_utc"]) if row["queued_utc"] else None,
        mt_id=row["mt_id"],
        delivered_report_id=row["delivered_report_id"],
        effects=json.loads(row["effects"]),
        detail=row["detail"],
    )


def _initial_effects(commands: tuple[str, ...] | list[str]) -> dict[str, str]:
    """Pending for a command whose effect the reports can show (the catalogue's ``confirm``), else never visible."""
    effects = {}
    for text in commands:
        found = read_text(text)
        effects[text] = PENDING if found is not None and found[0].confirm is not None else NEVER_VISIBLE
    return effects


def _queue_order(command: Command) -> tuple[datetime, int]:
    return (command.queued_utc or command.requested_utc, command.id)


def _assign(commands: list[Command], reports: list[StoredReport]) -> dict[int, StoredReport]:
    """The report each queued command went down with: one MT per session, oldest queued first.

    Reports already taken by a command stay taken, so an attribution once made holds unless a
    resolution explicitly reopens it.
    """
    used = {c.delivered_report_id for c in commands if c.delivered_report_id is not None}
    assignment: dict[int, StoredReport] = {}
    for command in sorted(commands, key=_queue_order):
        if command.state != QUEUED or command.queued_utc is None:
            continue
        queued_utc = command.queued_utc
        delivering = next((r for r in reports if r.id not in used and r.session_time > queued_utc), None)
        if delivering is not None:
            used.add(delivering.id)
            assignment[command.id] = delivering
    return assignment


def _effect_reports(
    command: Command, reports: list[StoredReport], commands: list[Command]
) -> list[StoredReport] | None:
    """The accepted reports after the one that delivered ``command``, up to where a later delivered command
    of the same kind takes over (its delivering report and the next still run on this one's value, by the
    switch-over rule); None while its delivering report is not among ``reports``."""
    position = {r.id: i for i, r in enumerate(reports)}
    index = position.get(command.delivered_report_id) if command.delivered_report_id is not None else None
    if index is None:
        return None
    kinds = {found[0].name for text in command.effects if (found := read_text(text)) is not None}
    end = len(reports)
    for other in commands:
        at = position.get(other.delivered_report_id) if other.delivered_report_id is not None else None
        if other.id == command.id or at is None or at <= index:
            continue
        if any((found := read_text(text)) is not None and found[0].name in kinds for text in other.effects):
            end = min(end, at + 2)
    return [r for r in reports[index + 1 : end] if r.report is not None]


_HELD: dict[Path, int] = {}
"""The sender locks this process holds, by path: one per command it requested and has not finished."""
_HELD_LOCK = threading.Lock()


def _sender_lock(store: Store, command_id: int) -> Path:
    return store.path.parent / "mt-senders" / f"{store.path.name}.{command_id}.lock"


def _hold(path: Path) -> bool:
    """Take the sender lock (or find it already held by this process); False if another process has it.

    Why a lock and not a PID: the kernel drops an flock when its holder dies however it dies (kill -9
    too), so "no live sender" is a fact read at once, not a guess after INTERRUPTED_AFTER, and a
    recycled PID can not fake a live one.
    """
    with _HELD_LOCK:
        if path in _HELD:
            return True
        try:
            if not path.parent.is_dir():
                path.parent.mkdir(exist_ok=True)
                path.parent.chmod(0o700)
            fd = os.open(path, os.O_RDWR | os.O_CREAT, 0o600)
        except OSError as exc:
            raise StoreError(f"cannot write the MT sender lock {path}: {exc.strerror or exc}") from None
        try:
            fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
        except BlockingIOError:
            os.close(fd)
            return False
        _HELD[path] = fd
        return True


def _release(path: Path) -> None:
    with _HELD_LOCK:
        fd = _HELD.pop(path, None)
        if fd is not None:
            path.unlink(missing_ok=True)
            os.close(fd)


def _sender_alive(path: Path) -> bool:
    """Whether a process (this one included) still holds the sender lock of a command."""
    with _HELD_LOCK:
        if path in _HELD:
            return True
    try:
        fd = os.open(path, os.O_RDONLY)
    except FileNotFoundError:
        return False
    except OSError:
        return True  # cannot tell: the INTERRUPTED_AFTER rule settles it
    try:
        fcntl.flock(fd, fcntl.LOCK_EX | fcntl.LOCK_NB)
    except BlockingIOError:
        return True
    finally:
        os.close(fd)  # closing drops a lock taken just now
    return False


class Terminated(SystemExit):
    """SIGTERM during a send: raised in the main thread so the send is recorded before the process ends."""

    def __init__(self) -> None:
        super().__init__(128 + signal.SIGTERM)

    def __repr__(self) -> str:
        return "SIGTERM"


@contextmanager
def _terminate_as_exit() -> Iterator[None]:
    """SIGTERM raises ``Terminated`` while the gateway call runs (main thread only: a worker thread can not
    set handlers, and the console stops its workers itself). Python's default ends the process at once,
    and the command stayed ``confirmed`` with nobody to say it may be queued."""
    if threading.current_thread() is not threading.main_thread():
        yield
        return

    def terminate(signum: int, frame: object) -> None:
        raise Terminated

    previous = signal.signal(signal.SIGTERM, terminate)
    try:
        yield
    finally:
        signal.signal(signal.SIGTERM, previous)


def _caveat(command: Command, unresolved: list[Command]) -> str:
    """Why an attribution may be one report early: an older command may be queued without our knowing."""
    older = [c for c in unresolved if _queue_order(c) < _queue_order(command)]
    if not older:
        return ""
    ids = ", ".join(str(c.id) for c in older)
    return (
        f"; uncertain until MT {ids} (delivery unknown, queued before it) is resolved: "
        "if the gateway did queue it, it went down first and this one later"
    )


class CommandLifecycle:
    """Commands of every capsule in the durable store; each state change is audited."""

    def __init__(self, store: Store, operator: str, clock: Callable[[], datetime] = utc_now) -> None:
        self.store = store
        self.operator = operator or "unknown"
        self.clock = clock
        store.ensure_schema(COMMANDS_DDL)
        self._recover_interrupted()

    def _recover_interrupted(self) -> None:
        """Settle what a stopped process left half done. A send cut off after ``confirmed`` may or may not
        have reached the gateway: say so, so that ``drs mt resolve`` can settle it and attribution never
        guesses across it. One cut off while still ``requested`` never left this machine (``confirmed``
        is written before the gateway is called): close it as not sent, so it shows as what it is.

        A command is settled at once when no process holds its sender lock (``_hold``), and in any case
        after ``INTERRUPTED_AFTER`` (a sender hung past any send's timeout)."""
        cutoff = iso_utc(self.clock() - INTERRUPTED_AFTER)
        rows = self.store.query(
            "SELECT * FROM mt_command WHERE state IN (?, ?) ORDER BY id", (REQUESTED, CONFIRMED)
        )
        for command in map(_row_to_command, rows):
            if iso_utc(command.updated_utc) >= cutoff and _sender_alive(_sender_lock(self.store, command.id)):
                continue
            try:
                if command.state == REQUESTED:
                    self._set(
                        command, NOT_SENT, "the process that requested it stopped before sending it: it never "
                        "reached the gateway; request it again if still wanted", expected=REQUESTED,
                    )  # fmt: skip
                    continue
                self._set(
                    command, DELIVERY_UNKNOWN,
                    "the process sending it stopped before the gateway answered: it may or may not be "
                    "queued; settle it with drs mt resolve", expected=CONFIRMED,
                    queued_utc=iso_utc(command.updated_utc),
                )  # fmt: skip
            except RefusedError:
                pass  # another process settled it meanwhile

    def get(self, command_id: int) -> Command:
        rows = self.store.query("SELECT * FROM mt_command WHERE id = ?", (command_id,))
        if not rows:
            raise RefusedError(f"no MT command with id {command_id}")
        return _row_to_command(rows[0])

    def for_imei(self, imei: str) -> list[Command]:
        return [
            _row_to_command(r)
            for r in self.store.query("SELECT * FROM mt_command WHERE imei = ? ORDER BY id", (imei,))
        ]

    def _set(
        self, command: Command, state: str, detail: str, expected: str | None = None, **columns: Any
    ) -> Command:
        self._apply([_Change(command, state, detail, columns, expected=expected)])
        return self.get(command.id)

    def _apply(self, changes: list[_Change]) -> None:
        """Several state changes in one transaction (a resolution and the re-attributions it forces)."""
        now = self.clock()
        with self.store.transaction() as conn:
            for change in changes:
                assignments = {
                    "state": change.state,
                    "detail": change.detail,
                    "updated_utc": iso_utc(now),
                    **change.columns,
                }
                sql = ", ".join(f"{name} = ?" for name in assignments)
                if change.expected is None:
                    conn.execute(
                        f"UPDATE mt_command SET {sql} WHERE id = ?",
                        (*assignments.values(), change.command.id),
                    )
                    continue
                updated = conn.execute(
                    f"UPDATE mt_command SET {sql} WHERE id = ? AND state = ?",
                    (*assignments.values(), change.command.id, change.expected),
                ).rowcount
                if updated != 1:
                    raise RefusedError(
                        f"MT {change.command.id} is no longer {change.expected}: another console or process "
                        "acted on it first, and it is never sent twice"
                    )
        for change in changes:
            command = change.command
            detail: dict[str, Any] = {"command_id": command.id, "text": command.text, "detail": change.detail}
            if change.columns.get("mt_id") is not None:
                detail["mt_id"] = change.columns["mt_id"]
            self.store.append_audit(
                self.operator,
                command.capsule,
                change.action or f"mt.{change.state}",
                change.state,
                detail,
                when=now,
            )

    def request(
        self,
        capsule: CapsuleConfig,
        message: MtMessage,
        flush: bool = False,
        also: Callable[[sqlite3.Connection], None] | None = None,
    ) -> Command:
        """Record what the operator asked for; nothing leaves the machine yet. ``also`` runs in the same
        transaction as the new row (a PARACHUTE's approval is marked used there) and may raise to refuse
        both."""
        if not capsule.imei:
            raise RefusedError(
                f"capsule {capsule.name} has no imei configured: the gateway needs the modem's IMEI"
            )
        moment = self.clock()
        now = iso_utc(moment)
        effects = json.dumps(_initial_effects(message.commands))
        with self.store.transaction() as conn:
            command_id = conn.execute(
                "INSERT INTO mt_command (capsule, imei, operator, text, flush, state, requested_utc, "
                "updated_utc, effects) VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    capsule.name,
                    capsule.imei,
                    self.operator,
                    message.text,
                    int(flush),
                    REQUESTED,
                    now,
                    now,
                    effects,
                ),
            ).lastrowid
            if also is not None:
                also(conn)
            # Held before the row is committed, so no other process ever sees it without its sender.
            _hold(_sender_lock(self.store, int(command_id or 0)))
        detail: dict[str, Any] = {"command_id": command_id, "text": message.text, "flush": flush}
        unresolved = [c.id for c in self.unresolved_like(capsule.imei, message.text)]
        if unresolved:
            detail["retry_over_unresolved"] = unresolved
            detail["warning"] = RETRY_WARNING
        self.store.append_audit(self.operator, capsule.name, "mt.requested", REQUESTED, detail, when=moment)
        return self.get(int(command_id or 0))

    def unresolved_like(self, imei: str, text: str) -> list[Command]:
        """Commands of this modem with the same text whose delivery is still unknown: a retry may queue
        the same MT twice (the gateway may hold the first), which the operator must be told before."""
        return [c for c in self.for_imei(imei) if c.text == text and c.state == DELIVERY_UNKNOWN]

    def send(self, command_id: int, confirmation: str, gateway: RockblockGateway) -> Command:
        """Queue a requested command at the gateway once; refused unless ``confirmation`` names it."""
        lock = _sender_lock(self.store, command_id)
        try:
            return self._send(command_id, confirmation, gateway, lock)
        finally:
            _release(lock)

    def _send(self, command_id: int, confirmation: str, gateway: RockblockGateway, lock: Path) -> Command:
        command = self.get(command_id)
        if command.state != REQUESTED:
            raise RefusedError(f"MT {command_id} is {command.state}, not requested: it is never sent twice")
        if not _hold(lock):
            raise RefusedError(f"MT {command_id} is being sent by another process: it is never sent twice")
        if confirmation != command.capsule:
            self.store.append_audit(
                self.operator,
                command.capsule,
                "mt.send",
                "refused",
                {"command_id": command_id, "reason": "confirmation does not name the capsule"},
                when=self.clock(),
            )
            self._set(
                command,
                NOT_SENT,
                f"refused: the confirmation {confirmation!r} does not name {command.capsule!r}",
            )
            raise RefusedError(
                f"refused: to send {command.text} the confirmation must name the capsule {command.capsule!r}"
            )
        detail = f"operator {self.operator} confirmed sending to {command.capsule}"
        if command.flush:
            detail += f"; WARNING: {FLUSH_WARNING}"
        command = self._set(command, CONFIRMED, detail, expected=REQUESTED)
        request_written_by = self.clock()
        try:
            with _terminate_as_exit():
                result = gateway.send(command.imei, command.text.encode("ascii"), flush=command.flush)
        except BaseException as exc:
            self._set(
                command, DELIVERY_UNKNOWN, f"the send stopped before the gateway answered ({exc!r}): it may "
                "or may not be queued; settle it with drs mt resolve", expected=CONFIRMED,
                queued_utc=iso_utc(request_written_by),
            )  # fmt: skip
            raise
        state = _SEND_OUTCOME[result.status]
        columns: dict[str, Any] = {}
        try:
            if state == QUEUED:
                columns = {"queued_utc": iso_utc(self.clock()), "mt_id": result.mt_id}
                if command.flush:
                    self._flush_older(command)
            elif state == DELIVERY_UNKNOWN:
                columns = {"queued_utc": iso_utc(request_written_by)}
            return self._set(command, state, result.detail, expected=CONFIRMED, **columns)
        except StoreError as exc:
            # The gateway has acted; the store only failed to say so. Without this the operator read a
            # store error and nothing about the MT already queued (and might send it again).
            acted = f"queued it as MT {result.mt_id}" if state == QUEUED else f"answered: {result.detail}"
            raise StoreError(
                f"the gateway {acted} (command {command.id}, {command.text}), but the store could not record "
                f"it ({exc}); do not send it again: it stays 'confirmed' until the store is writable, then "
                "becomes delivery_unknown for drs mt resolve"
            ) from None

    def _unknown(self, command_id: int, capsule: str) -> Command:
        """The command an operator may resolve: this capsule's, and still of unknown delivery."""
        command = self.get(command_id)
        if command.capsule != capsule:
            raise RefusedError(f"MT {command_id} was sent to {command.capsule}, not {capsule}")
        if command.state != DELIVERY_UNKNOWN:
            raise RefusedError(
                f"MT {command_id} is {command.state}: only a command in delivery_unknown can be resolved, "
                "and only once"
            )
        return command

    @staticmethod
    def _note(note: str) -> str:
        if not note.isprintable():
            raise RefusedError("the note must be one line of printable text")
        return f" (note: {note})" if note else ""

    def resolve_not_sent(self, command_id: int, capsule: str, note: str = "") -> Command:
        """The portal shows the request never reached the gateway: close it so it may be requested again."""
        command = self._unknown(command_id, capsule)
        detail = (
            f"resolved by {self.operator}: the RockBLOCK portal shows it never reached the gateway; closed "
            f"as not sent, request it again if still wanted{self._note(note)}"
        )
        self._apply([_Change(command, NOT_SENT, detail, {"queued_utc": None}, "mt.resolved")])
        return self.get(command_id)

    def resolve_queued(
        self, command_id: int, capsule: str, mt_id: int, reports: list[StoredReport], note: str = ""
    ) -> Command:
        """The portal shows it queued as ``mt_id``: it rejoins the queue at the time its request went out.

        One MT goes down per session, oldest first, so a later command that was attributed to a
        report while this one was unknown may really have gone down a report later: every such
        attribution that changes is undone here (back to queued, effects pending) and ``observe``
        re-attributes them in queue order.
        """
        command = self._unknown(command_id, capsule)
        suffix = self._note(note)
        if mt_id < 1:
            raise RefusedError(f"the gateway's MT id must be a positive number, not {mt_id}")
        commands = self.for_imei(command.imei)
        owner = next((c for c in commands if c.mt_id == mt_id), None)
        if owner is not None:
            raise RefusedError(f"gateway MT id {mt_id} already belongs to MT {owner.id} ({owner.text})")
        queued_at = command.queued_utc or command.requested_utc
        resolved = replace(command, state=QUEUED, queued_utc=queued_at, mt_id=mt_id)
        later = [
            c
            for c in commands
            if c.delivered_report_id is not None and _queue_order(c) > _queue_order(resolved)
        ]
        reopened = [replace(c, state=QUEUED, delivered_report_id=None) for c in later]
        reconsidered = {command.id} | {c.id for c in later}
        others = [c for c in commands if c.id not in reconsidered]
        assignment = _assign([resolved, *reopened, *others], reports)
        detail = (
            f"resolved by {self.operator}: the RockBLOCK portal shows it queued at the gateway as MT "
            f"{mt_id}{suffix}"
        )
        changes = [
            _Change(
                command, QUEUED, detail, {"queued_utc": iso_utc(queued_at), "mt_id": mt_id}, "mt.resolved"
            )
        ]
        for shifted in later:
            new_report = assignment.get(shifted.id)
            if new_report is not None and new_report.id == shifted.delivered_report_id:
                continue
            changes.append(
                _Change(
                    shifted,
                    QUEUED,
                    f"re-attributed: MT {command.id}, queued before it, was resolved as queued, so the report "
                    f"once taken for this one carried MT {command.id} or an older one",
                    {
                        "delivered_report_id": None,
                        "effects": json.dumps(_initial_effects(list(shifted.effects))),
                    },
                    "mt.reattributed",
                )
            )
        self._apply(changes)
        return self.get(command_id)

    def _flush_older(self, flushing: Command) -> None:
        for older in self.for_imei(flushing.imei):
            if older.id != flushing.id and older.state in (QUEUED, DELIVERY_UNKNOWN):
                self._set(older, FLUSHED, f"deleted from the gateway queue by the flush of MT {flushing.id}")

    def observe(self, reports: list[StoredReport], imei: str) -> list[Command]:
        """Advance this modem's commands from its reports (time order); returns the commands that changed."""
        changed: list[Command] = []
        commands = self.for_imei(imei)
        assignment = _assign(commands, reports)
        unresolved = [c for c in commands if c.state == DELIVERY_UNKNOWN]
        for command in sorted(commands, key=_queue_order):
            if command.state == QUEUED and command.queued_utc is not None:
                delivering = assignment.get(command.id)
                if delivering is None:
                    if self.clock() - command.queued_utc > QUEUE_TIMEOUT:
                        changed.append(
                            self._set(
                                command,
                                TIMED_OUT,
                                f"no report in {QUEUE_TIMEOUT} since queueing: the capsule may be silent; "
                                "the MT is probably still queued at the gateway (flush to cancel)",
                            )
                        )
                    continue
                command = self._deliver(command, delivering, _caveat(command, unresolved))
                changed.append(command)
            if command.state == PROBABLY_DELIVERED:
                updated = self._check_effects(command, reports, commands, _caveat(command, unresolved))
                if updated is not None:
                    changed.append(updated)
            elif command.state == EFFECT_CONFIRMED:
                updated = self._recheck_effects(command, reports, commands)
                if updated is not None:
                    changed.append(updated)
        return changed

    def observe_store(self, reports: ReportStore, imei: str) -> list[Command]:
        """``observe`` given only the reports it can still use: what ``drs mo serve`` runs after each post.

        Why not every report: re-reading and re-parsing the whole flight after each post made the work
        per post grow with the flight. A queued command can only take a report from a session after it
        was queued, and a probably delivered one reads only its own report and the ones after; no other
        report changes anything, so the outcome is ``observe(reports.for_imei(imei), imei)``'s.
        """
        commands = self.for_imei(imei)
        queued = [c.queued_utc for c in commands if c.state == QUEUED and c.queued_utc is not None]
        delivered = [
            c.delivered_report_id
            for c in commands
            if c.state == PROBABLY_DELIVERED and c.delivered_report_id is not None
        ]
        delivered += [
            c.delivered_report_id
            for c in commands
            if c.state == EFFECT_CONFIRMED and c.delivered_report_id is not None
            and self._reports_after(c.delivered_report_id) <= RECHECK_REPORTS
        ]  # fmt: skip
        if not queued and not delivered:
            return []
        return self.observe(reports.tail(imei, min(queued, default=None), delivered), imei)

    def _deliver(self, command: Command, report: StoredReport, caveat: str) -> Command:
        visible = [c for c, e in command.effects.items() if e == PENDING]
        note = (
            f"probably downloaded in the session of report MOMSN {report.delivery.momsn} "
            f"at {iso_utc(report.session_time)} (one MT per session, oldest first; nothing is acknowledged)"
            f"{caveat}"
        )
        if not visible:
            return self._set(
                command,
                UNCONFIRMABLE,
                f"{note}; {UNSEEN_NAMES} leave no trace in the reports: their effect can not be confirmed",
                delivered_report_id=report.id,
            )
        return self._set(command, PROBABLY_DELIVERED, note, delivered_report_id=report.id)

    def _reports_after(self, report_id: int) -> int:
        """How many reports of the same modem sort after this one."""
        rows = self.store.query(
            "SELECT COUNT(*) AS n FROM mo_report AS r JOIN mo_report AS d ON d.id = ? "
            "WHERE r.imei = d.imei AND (r.sort_utc, r.id) > (d.sort_utc, d.id)",
            (report_id,),
        )
        return int(rows[0]["n"]) if rows else 0

    def _recheck_effects(
        self, command: Command, reports: list[StoredReport], commands: list[Command]
    ) -> Command | None:
        """Re-open a confirmed effect that later reports contradict (``RECHECK_REPORTS``)."""
        after = _effect_reports(command, reports, commands)
        if after is None:
            return None
        after = after[:RECHECK_REPORTS]
        effects = dict(command.effects)
        for text, state in command.effects.items():
            found = read_text(text)
            if state == SEEN and found is not None and found[0].confirm is not None:
                effects[text] = found[0].confirm(found[1], after)
        if NOT_SEEN not in effects.values():
            return None
        summary = "; ".join(f"{text}: {state}" for text, state in effects.items())
        return self._set(
            command,
            TIMED_OUT,
            f"effect once confirmed, now contradicted by later reports (re-opened): {summary}",
            effects=json.dumps(effects),
        )

    def _check_effects(
        self, command: Command, reports: list[StoredReport], commands: list[Command], caveat: str
    ) -> Command | None:
        after = _effect_reports(command, reports, commands)
        if after is None:
            return None
        effects = dict(command.effects)
        for text in effects:
            if effects[text] != PENDING:
                continue
            found = read_text(text)
            if found is None:
                continue
            command_kind, value = found
            if command_kind.confirm is None:
                continue
            effects[text] = command_kind.confirm(value, after)
        if effects == command.effects:
            return None
        if PENDING in effects.values():
            return self._set(command, PROBABLY_DELIVERED, command.detail, effects=json.dumps(effects))
        summary = "; ".join(f"{text}: {state}" for text, state in effects.items()) + caveat
        if NOT_SEEN in effects.values():
            return self._set(
                command, TIMED_OUT, f"effect not seen in the reports: {summary}", effects=json.dumps(effects)
            )
        if SEEN in effects.values():
            return self._set(
                command,
                EFFECT_CONFIRMED,
                f"effect confirmed by later reports: {summary}",
                effects=json.dumps(effects),
            )
        return self._set(
            command, UNCONFIRMABLE, f"no effect can be confirmed: {summary}", effects=json.dumps(effects)
        )

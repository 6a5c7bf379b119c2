"""The durable store: one SQLite file holding the audit log and every service's state.

Nothing shown to an operator as done may be lost by a crash, so the database runs in WAL
mode with ``synchronous=FULL`` and every write commits before it returns. Each thread gets
its own connection (console workers, the webhook server and the CLI share one file). Services
own their tables: they call ``ensure_schema`` with their DDL instead of editing this module.
"""

from __future__ import annotations

import json
import logging
import os
import pwd
import socket
import sqlite3
import threading
import time
from collections.abc import Callable, Iterator, Mapping
from contextlib import contextmanager
from dataclasses import dataclass
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

from drs_link.errors import StoreError
from drs_link.skip_clock import skipped_seconds

log = logging.getLogger(__name__)

_AUDIT_DDL = """
CREATE TABLE IF NOT EXISTS audit (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    time_utc TEXT NOT NULL,
    operator TEXT NOT NULL,
    capsule TEXT,
    action TEXT NOT NULL,
    result TEXT NOT NULL,
    detail TEXT,
    session TEXT
);
CREATE INDEX IF NOT EXISTS audit_capsule_time ON audit (capsule, time_utc);
CREATE INDEX IF NOT EXISTS audit_capsule_action ON audit (capsule, action);
"""
_AUDIT_SESSION_COLUMN = "ALTER TABLE audit ADD COLUMN session TEXT"
"""Stores made before the session column get it on first open (SQLite adds it in place, NULL for old rows)."""
_CLOCK_DDL = """
CREATE TABLE IF NOT EXISTS store_clock (
    id INTEGER PRIMARY KEY CHECK (id = 1),
    wall_utc TEXT NOT NULL,
    store_utc TEXT NOT NULL,
    scale REAL NOT NULL
);
"""


def session_name() -> str:
    """Which process wrote a row: the OS account, the host and the process id. Several consoles share
    one store (two operators, each in their own SSH session); each must see what the other did, and
    who did it."""
    return f"{pwd.getpwuid(os.geteuid()).pw_name}@{socket.gethostname()} pid {os.getpid()}"


WAIT_NOTICE_S = 1.0
"""A write that has waited this long for another process's lock says so (``Store.transaction``)."""


def _on_read_only_filesystem(path: Path) -> bool:
    """The store exists on a filesystem mounted read-only (statvfs's ST_RDONLY)."""
    try:
        return path.is_file() and bool(os.statvfs(path.parent).f_flag & os.ST_RDONLY)
    except OSError:
        return False


def utc_now() -> datetime:
    """The wall clock in UTC, which a test may have skipped forward (``drs_link.skip_clock``)."""
    skipped = skipped_seconds()
    now = datetime.now(UTC)
    return now + timedelta(seconds=skipped) if skipped else now


def iso_utc(moment: datetime) -> str:
    """ISO 8601 UTC with a ``Z``, the one time format of the store and every output."""
    if moment.tzinfo is None:
        raise ValueError("naive datetime: every time in the store is UTC and must say so")
    return moment.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def parse_iso_utc(text: str) -> datetime:
    return datetime.fromisoformat(text.replace("Z", "+00:00")).astimezone(UTC)


@dataclass(frozen=True)
class AuditRecord:
    id: int
    time_utc: datetime
    operator: str
    capsule: str | None
    action: str
    result: str
    detail: dict[str, Any] | None
    session: str | None = None
    """The process that wrote it (``session_name``); None for rows older than the column."""


PRIVATE_FILE_MODE = 0o600
"""The store is one account's: a team shares it through the operations server, which alone opens it."""


def _scaled_clock(wall: datetime, start: datetime, scale: float) -> Callable[[], datetime]:
    """``start`` at the wall time ``wall``, running ``scale`` times faster: from the wall clock, which every
    process reads alike (a monotonic clock is per machine boot, not per store)."""

    def now() -> datetime:
        return start + timedelta(seconds=(utc_now() - wall).total_seconds() * scale)

    return now


def _protect(path: Path) -> None:
    """Create the store file with its mode before SQLite does (its -wal and -shm take the main file's
    mode). The audit log names operators and holds the gateway's echoes: owner only. Another account's
    file is left as it is: only its owner may change its mode, and says so if it cannot be used."""
    try:
        path.touch(mode=PRIVATE_FILE_MODE, exist_ok=True)
        info = path.stat()
        if info.st_uid == os.geteuid() and info.st_mode & 0o777 != PRIVATE_FILE_MODE:
            path.chmod(PRIVATE_FILE_MODE)
    except OSError as exc:
        raise StoreError(f"cannot create the store {path}: {exc}{_owner_hint(path)}") from None
    if not os.access(path, os.R_OK | os.W_OK):
        raise StoreError(f"cannot use the store {path}: permission denied{_owner_hint(path)}")


def _owner_hint(path: Path) -> str:
    """Whose store it is, when it (or its directory) belongs to another account, and the way for two
    accounts to work on one: the team's operations server, not a store both can write."""
    owner = None
    for place in (path, path.parent):  # the file, else (not there, or not even visible) its directory
        try:
            owner = place.stat().st_uid
            break
        except OSError:
            continue
    if owner is None or owner == os.geteuid():
        return ""
    return (
        f" (it belongs to {account_of(owner)}; accounts share one store through the team's operations "
        "server, `drs setup server --group GROUP`: docs/console.md)"
    )


def account_of(uid: int) -> str:
    """The account of a uid, or ``uid N`` when it has none (a deleted account still owns its files)."""
    try:
        return pwd.getpwuid(uid).pw_name
    except KeyError:
        return f"uid {uid}"


class Store:
    """A SQLite database file shared by threads and processes."""

    read_only: bool = False
    """Opened read-only because its filesystem is (``open``): what it holds can be read, nothing recorded."""
    WRITE_WAIT_S = 30.0
    """How long a write waits for another process's lock before it is refused (``transaction``)."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._local = threading.local()
        self._schemas: list[str] = []
        self._schema_lock = threading.Lock()
        self.session = session_name()
        self.clock: Callable[[], datetime] = utc_now
        """The store's time: the wall clock, or a simulated one all processes on it share (``run_clock``)."""
        self.scale = 1.0
        """Simulated seconds per wall second of ``clock`` (the demo's speed): what a process that polls on
        a timer scales its periods by (the operations server's telemetry)."""
        self._writer = threading.RLock()
        """Writers of this process take turns here before SQLite's lock. Left to SQLite, a thread that
        finds the database locked sleeps in its busy handler (1, 2, 5 … 100 ms a try), and with 20
        receiver threads at once the unlucky ones waited 0.4–1 s; this lock hands over at once."""

    @classmethod
    def open(cls, path: str | Path) -> Store:
        path = Path(path).expanduser()
        if _on_read_only_filesystem(path):
            return cls._open_read_only(path)
        try:
            path.parent.mkdir(mode=0o700, parents=True, exist_ok=True)
        except OSError as exc:
            raise StoreError(f"cannot create the data directory {path.parent}: {exc}") from None
        _protect(path)
        store = cls(path)
        store.ensure_schema(_AUDIT_DDL)
        store._add_session_column()
        store._adopt_clock()
        return store

    def run_clock(self, start: datetime, scale: float) -> None:
        """Make this store's time simulated (the demo): ``start`` now, running ``scale`` times faster.

        Written into the store, so every process that opens it reads the same time: the demo once wrote
        its audit with two clocks (wall and ×4), History came out of order, and the demo console and
        `drs approve` disagreed about when an approval expires."""
        self.ensure_schema(_CLOCK_DDL)
        wall = utc_now()
        self.write("INSERT OR REPLACE INTO store_clock (id, wall_utc, store_utc, scale) VALUES (1, ?, ?, ?)",
                   (iso_utc(wall), iso_utc(start), scale))  # fmt: skip
        self.clock = _scaled_clock(wall, start, scale)
        self.scale = scale

    def _adopt_clock(self) -> None:
        if not self.query("SELECT name FROM sqlite_master WHERE type = 'table' AND name = 'store_clock'"):
            return
        rows = self.query("SELECT wall_utc, store_utc, scale FROM store_clock WHERE id = 1")
        if rows:
            row = rows[0]
            wall, start = parse_iso_utc(row["wall_utc"]), parse_iso_utc(row["store_utc"])
            self.clock = _scaled_clock(wall, start, row["scale"])
            self.scale = float(row["scale"])

    @classmethod
    def _open_read_only(cls, path: Path) -> Store:
        """A store on a read-only filesystem (a disk remounted read-only after errors, a copy on a DVD):
        recovery, health, status and export read it; ``open`` once failed on touching the file. SQLite's
        ``immutable`` mode is right here: nobody can write a file on a read-only filesystem, and a WAL
        store closed cleanly has no -shm that ``mode=ro`` could use."""
        store = cls(path)
        store.read_only = True
        store.query("SELECT COUNT(*) FROM sqlite_master")  # unreadable: say so now, naming the file
        store._adopt_clock()
        return store

    def _add_session_column(self) -> None:
        columns = {row["name"] for row in self.query("PRAGMA table_info(audit)")}
        if "session" in columns:
            return
        try:
            self.conn.execute(_AUDIT_SESSION_COLUMN)
        except sqlite3.OperationalError as exc:
            if "duplicate column" not in str(exc):  # another process added it first
                raise StoreError(f"cannot update the store {self.path}: {exc}") from None

    def data_version(self) -> int:
        """SQLite's count of commits by OTHER connections, as this thread's connection sees it: one
        cheap PRAGMA, no table read, so a console can ask it every half second."""
        return int(self.query("PRAGMA data_version")[0][0])

    def _connect(self) -> sqlite3.Connection:
        if self.read_only:
            uri = f"{self.path.resolve().as_uri()}?immutable=1"
            try:
                conn = sqlite3.connect(uri, uri=True, isolation_level=None, check_same_thread=True)
                conn.row_factory = sqlite3.Row
                conn.execute("PRAGMA query_only=1")
            except sqlite3.Error as exc:
                raise StoreError(f"cannot open the store {self.path} read-only: {exc}") from None
            return conn
        try:
            conn = sqlite3.connect(self.path, timeout=30.0, isolation_level=None, check_same_thread=True)
            conn.row_factory = sqlite3.Row
            conn.execute("PRAGMA journal_mode=WAL")
            conn.execute("PRAGMA synchronous=FULL")
            conn.execute("PRAGMA foreign_keys=ON")
        except sqlite3.Error as exc:
            raise StoreError(f"cannot open the store {self.path}: {exc}") from None
        for ddl in self._schemas:
            conn.executescript(ddl)
        return conn

    @property
    def conn(self) -> sqlite3.Connection:
        conn = getattr(self._local, "conn", None)
        if conn is None:
            conn = self._connect()
            self._local.conn = conn
        return conn

    def ensure_schema(self, ddl: str) -> None:
        """Create a service's tables (idempotent ``CREATE ... IF NOT EXISTS`` statements)."""
        with self._schema_lock:
            if ddl in self._schemas:
                return
            self._schemas.append(ddl)
        if self.read_only:
            return  # tables missing from an old store are reported by the query that needs them
        try:
            self.conn.executescript(ddl)
        except sqlite3.Error as exc:
            raise StoreError(f"cannot create tables in {self.path}: {exc}") from None

    @contextmanager
    def transaction(self, wait_s: float | None = None) -> Iterator[sqlite3.Connection]:
        """One atomic, durable write: committed (and fsynced) when the block ends without error.

        ``wait_s`` bounds the wait for the store's write lock, in this process and from others together
        (default ``WRITE_WAIT_S``): the receiver must answer the gateway inside its 3 s, and once waited
        19-30 s behind another process's lock. A wait past ``WAIT_NOTICE_S`` is logged as it happens, so a
        command line does not sit silent.
        """
        if self.read_only:
            raise StoreError(f"the store {self.path} is on a read-only filesystem: nothing can be recorded")
        wait = self.WRITE_WAIT_S if wait_s is None else wait_s
        deadline = time.monotonic() + wait
        if not self._writer.acquire(timeout=wait):
            raise StoreError(f"the store {self.path} is busy: no write lock within {wait:g} s")
        try:
            yield from self._transaction(deadline)
        finally:
            self._writer.release()

    def _begin(self, conn: sqlite3.Connection, deadline: float) -> None:
        """BEGIN IMMEDIATE within the deadline; says once that it is waiting for another process's lock."""
        told = False
        while True:
            left = deadline - time.monotonic()
            step = min(max(left, 0.0), WAIT_NOTICE_S) if not told else max(left, 0.0)
            conn.execute(f"PRAGMA busy_timeout = {int(step * 1000)}")
            try:
                conn.execute("BEGIN IMMEDIATE")
                return
            except sqlite3.OperationalError as exc:
                if "locked" not in str(exc) or time.monotonic() >= deadline or told:
                    raise
                log.warning("the store %s is locked by another process: waiting up to %.0f s more",
                            self.path, deadline - time.monotonic())  # fmt: skip
                told = True
            finally:
                conn.execute(f"PRAGMA busy_timeout = {int(self.WRITE_WAIT_S * 1000)}")

    def _transaction(self, deadline: float) -> Iterator[sqlite3.Connection]:
        conn = self.conn
        try:
            self._begin(conn, deadline)
        except sqlite3.Error as exc:
            raise StoreError(f"the store {self.path} cannot be written: {exc}") from None
        try:
            yield conn
        except sqlite3.Error as exc:
            self._rollback(conn)
            raise StoreError(f"the store {self.path} cannot be written: {exc}") from None
        except BaseException:
            self._rollback(conn)
            raise
        try:
            conn.execute("COMMIT")
        except sqlite3.Error as exc:
            self._rollback(conn)
            raise StoreError(f"the store {self.path} cannot be written: {exc}") from None

    @staticmethod
    def _rollback(conn: sqlite3.Connection) -> None:
        """Roll back what is still open. On a full disk or an I/O error SQLite has already rolled the
        transaction back itself, and a second ROLLBACK would replace the real error ("database or disk
        is full") with "cannot rollback - no transaction is active"."""
        if conn.in_transaction:
            try:
                conn.execute("ROLLBACK")
            except sqlite3.Error:
                pass  # the original error is the one the operator needs

    def write(self, sql: str, params: tuple[Any, ...] | dict[str, Any] = ()) -> int:
        """Run one statement in its own durable transaction; returns the row id it wrote."""
        try:
            with self.transaction() as conn:
                return int(conn.execute(sql, params).lastrowid or 0)
        except sqlite3.Error as exc:
            raise StoreError(f"the store {self.path} cannot be written: {exc}") from None

    def query(self, sql: str, params: tuple[Any, ...] | dict[str, Any] = ()) -> list[sqlite3.Row]:
        try:
            return self.conn.execute(sql, params).fetchall()
        except sqlite3.Error as exc:
            raise StoreError(f"cannot read the store {self.path}: {exc}") from None

    def append_audit(
        self,
        operator: str,
        capsule: str | None,
        action: str,
        result: str,
        detail: Mapping[str, object] | None = None,
        when: datetime | None = None,
    ) -> AuditRecord:
        """Record one step durably; only after this returns may anyone be told it happened."""
        moment = when or self.clock()
        record_detail = dict(detail) if detail is not None else None  # json writes a dict, not any Mapping
        detail_json = json.dumps(record_detail, sort_keys=True, default=str) if detail is not None else None
        row_id = self.write(
            "INSERT INTO audit (time_utc, operator, capsule, action, result, detail, session) "
            "VALUES (?, ?, ?, ?, ?, ?, ?)",
            (iso_utc(moment), operator, capsule, action, result, detail_json, self.session),
        )
        return AuditRecord(row_id, moment, operator, capsule, action, result, record_detail, self.session)

    def audit(
        self,
        capsule: str | None = None,
        text: str | None = None,
        limit: int | None = None,
        after_id: int = 0,
        action: str | None = None,
    ) -> list[AuditRecord]:
        """Audit records oldest first, optionally for one capsule, containing ``text`` (in the capsule's
        name, the action, the result, the detail or the operator: History's search box), newer than
        ``after_id``, or of one ``action`` (an exact match: what a screen asks every second must not scan
        every detail)."""
        clauses: list[str] = ["id > ?"]
        params: list[object] = [after_id]
        if capsule is not None:
            clauses.append("capsule = ?")
            params.append(capsule)
        if action is not None:
            clauses.append("action = ?")
            params.append(action)
        if text:
            clauses.append(
                "(COALESCE(capsule, '') || ' ' || action || ' ' || result || ' ' || COALESCE(detail, '') || ' ' "
                "|| operator) LIKE ?"
            )
            params.append(f"%{text}%")
        sql = f"SELECT * FROM audit WHERE {' AND '.join(clauses)} ORDER BY id"
        if limit is not None:
            sql = f"SELECT * FROM ({sql.replace('ORDER BY id', 'ORDER BY id DESC')} LIMIT {int(limit)}) ORDER BY id"
        return [
            AuditRecord(
                row["id"],
                parse_iso_utc(row["time_utc"]),
                row["operator"],
                row["capsule"],
                row["action"],
                row["result"],
                json.loads(row["detail"]) if row["detail"] else None,
                row["session"],
            )
            for row in self.query(sql, tuple(params))
        ]

    def close(self) -> None:
        conn = getattr(self._local, "conn", None)
        if conn is not None:
            conn.close()
            self._local.conn = None

"""The two-step release of one capsule as a durable state machine that never skips a step.

Go is the one irreversible command, so its preconditions live here, below any UI: power-on must
have succeeded in the current session, NMEA must have been seen since (the microcontroller is
only listening for Go while it echoes NMEA), and the caller must present a fresh confirmation
token minted by an explicit confirmation that names this capsule. State lives in the store, so a
CLI ``go`` after a CLI ``power-on`` works and a restarted console resumes; every step is audited
before it is reported as done.
"""

from __future__ import annotations

import re
import secrets
import socket
import sqlite3
import time
from collections.abc import Callable, Mapping
from dataclasses import dataclass, replace
from datetime import datetime
from enum import StrEnum

from drs_link.config import CapsuleConfig
from drs_link.errors import LinkError, RefusedError, StoreError
from drs_link.link import GnssStatus, summarise
from drs_link.link.backends import AuthorityStatus, CapsuleBackend, GoResult
from drs_link.ops.typed_text import typed_text
from drs_link.store import Store, iso_utc, parse_iso_utc, utc_now

TOKEN_TTL_S = 60.0
SEEN_NMEA_POLL_S = 1.0

_DDL = """
CREATE TABLE IF NOT EXISTS release_state (
    capsule TEXT PRIMARY KEY,
    state TEXT NOT NULL,
    session TEXT,
    holder TEXT,
    log_offset INTEGER NOT NULL DEFAULT 0,
    powered_at TEXT,
    nmea_seen_at TEXT,
    go_at TEXT,
    released_at TEXT,
    note TEXT,
    updated_at TEXT NOT NULL
);
CREATE TABLE IF NOT EXISTS release_tokens (
    token TEXT PRIMARY KEY,
    capsule TEXT NOT NULL,
    session TEXT NOT NULL,
    minted_at TEXT NOT NULL,
    used_at TEXT
);
"""
_LATER_COLUMNS = {"failed_go_at": "TEXT"}
"""Added in place to stores made before them: the time of a Go that was never verified, kept beside the
verified Go that finished it (``ReleaseRecord.failed_go_at``)."""

SILENT_MICROCONTROLLER_CHECKS = (
    "no NMEA from the microcontroller since power-on; check: "
    "(1) the two 9 V batteries are fitted and fresh; "
    "(2) the relay latched (press ON with the Pi powered, or run power-on again); "
    "(3) it may still be booting (10 s wait plus ~13 s GNSS set-up); "
    "(4) the unit may be in Gone mode after an earlier drop, where it never talks to the Pi: "
    "clear it with the four-button reset (hold OPEN_A+CLOSE_A+OPEN_B+CLOSE_B, press RESET, "
    "hold until the LED is green)"
)


POWER_ON_UNKNOWN_NOTE = (
    "power-on outcome unknown: check the relay; then run power-on again (a second SET pulse leaves a "
    "latched relay latched) or, if it is off and should stay off, reset"
)


class ReleaseState(StrEnum):
    IDLE = "idle"
    POWER_ON_UNKNOWN = "power-on-unknown"
    """Power-on was started and its outcome never recorded: the Pi may have latched the relay."""
    POWERED = "powered"
    GO_SENT = "go-sent-unverified"
    RELEASED = "released"


@dataclass(frozen=True)
class ReleaseRecord:
    capsule: str
    state: ReleaseState
    session: str | None
    holder: str | None
    log_offset: int
    powered_at: datetime | None
    nmea_seen_at: datetime | None
    go_at: datetime | None
    released_at: datetime | None
    note: str | None
    failed_go_at: datetime | None = None
    """When a Go was sent and never verified, if a later Go finished it: ``go_at`` is then the verified
    Go's time, the release time, and this the failed attempt's, kept beside it (issue #29)."""


@dataclass(frozen=True)
class ConfirmationToken:
    """Proof that an operator named this capsule just now; only the store can vouch for it."""

    value: str
    capsule: str
    minted_at: datetime


@dataclass(frozen=True)
class MicrocontrollerReport:
    """Whether the microcontroller is waiting for Go, and if not, what to check."""

    waiting_for_go: bool
    seconds_since_power_on: float | None
    gnss: GnssStatus
    diagnosis: str
    still_booting: bool = False


def default_holder(operator: str) -> str:
    """Who holds release authority on the Pi: operator and machine, in the lock file's alphabet."""
    raw = f"{operator or 'operator'}@{socket.gethostname()}"
    return re.sub(r"[^A-Za-z0-9@._:+-]", "_", raw)[:96]


def take_over_outcome(seen: AuthorityStatus, holder: str) -> str:
    """What taking over from ``seen`` amounts to for ``holder``: from itself it is only a renewal."""
    if seen.holder == holder:
        return "renewed"
    return "claimed" if seen.holder is None else f"taken over from {seen.holder}"


class _TokenUsed(Exception):
    """Another Go used this confirmation between the check and the send."""


class _StateChanged(Exception):
    """The stored record moved on between reading it and writing a step (``_swap``)."""

    def __init__(self, current: ReleaseRecord) -> None:
        super().__init__(current.state.value)
        self.current = current


def _identity(record: ReleaseRecord) -> tuple[str, str | None, str | None]:
    """What a compare-and-set compares, as stored (times to the store's precision, not the clock's)."""
    return record.state.value, record.session, iso_utc(record.go_at) if record.go_at else None


def _time(text: str | None) -> datetime | None:
    return parse_iso_utc(text) if text else None


class ReleaseStateMachine:
    def __init__(
        self,
        store: Store,
        capsule: CapsuleConfig,
        backend: CapsuleBackend,
        operator: str,
        clock: Callable[[], datetime] = utc_now,
        sleep: Callable[[float], None] | None = None,
        token_ttl_s: float = TOKEN_TTL_S,
        holder: str | None = None,
    ) -> None:
        self.store = store
        self.capsule = capsule
        self.backend = backend
        self.operator = operator or "unknown"
        self.clock = clock
        self.sleep = sleep or time.sleep
        self.token_ttl_s = token_ttl_s
        self.holder = holder or default_holder(self.operator)
        store.ensure_schema(_DDL)
        have = {str(row["name"]) for row in store.query("PRAGMA table_info(release_state)")}
        if any(name not in have for name in _LATER_COLUMNS):
            with store.transaction() as conn:
                have = {str(row["name"]) for row in conn.execute("PRAGMA table_info(release_state)")}
                for name, kind in _LATER_COLUMNS.items():
                    if name not in have:
                        conn.execute(f"ALTER TABLE release_state ADD COLUMN {name} {kind}")

    @property
    def name(self) -> str:
        return self.capsule.name

    def record(self) -> ReleaseRecord:
        return self._read(self.store.query("SELECT * FROM release_state WHERE capsule = ?", (self.name,)))

    def _read(self, rows: list[sqlite3.Row]) -> ReleaseRecord:
        if not rows:
            return ReleaseRecord(self.name, ReleaseState.IDLE, None, None, 0, None, None, None, None, None)
        row = rows[0]
        return ReleaseRecord(
            capsule=self.name,
            state=ReleaseState(row["state"]),
            session=row["session"],
            holder=row["holder"],
            log_offset=row["log_offset"],
            powered_at=_time(row["powered_at"]),
            nmea_seen_at=_time(row["nmea_seen_at"]),
            go_at=_time(row["go_at"]),
            released_at=_time(row["released_at"]),
            note=row["note"],
            failed_go_at=_time(row["failed_go_at"]),
        )

    def _save(self, conn: sqlite3.Connection, record: ReleaseRecord) -> None:
        def iso(moment: datetime | None) -> str | None:
            return iso_utc(moment) if moment else None

        conn.execute(
            "INSERT OR REPLACE INTO release_state (capsule, state, session, holder, log_offset, powered_at,"
            " nmea_seen_at, go_at, released_at, note, updated_at, failed_go_at) VALUES (?,?,?,?,?,?,?,?,?,?,?,?)",
            (
                record.capsule,
                record.state.value,
                record.session,
                record.holder,
                record.log_offset,
                iso(record.powered_at),
                iso(record.nmea_seen_at),
                iso(record.go_at),
                iso(record.released_at),
                record.note,
                iso_utc(self.clock()),
                iso(record.failed_go_at),
            ),
        )

    def _swap(self, seen: ReleaseRecord, new: ReleaseRecord) -> ReleaseRecord:
        """Write ``new`` only if the store still holds ``seen``: a compare-and-set under SQLite's write lock.

        Two consoles, or two threads of one, acting on the same capsule each read the record and then
        act on the Pi; without this, the slower one wrote its stale copy back over the other's step
        (a refused Go once turned ``released`` into ``powered``).
        """
        with self.store.transaction() as conn:
            self._swap_in(conn, seen, new)
        return new

    def _swap_in(self, conn: sqlite3.Connection, seen: ReleaseRecord, new: ReleaseRecord) -> None:
        """``_swap`` inside a transaction the caller holds (Go also marks its token used in it)."""
        current = self._read(
            conn.execute("SELECT * FROM release_state WHERE capsule = ?", (self.name,)).fetchall()
        )
        if _identity(current) != _identity(seen):
            raise _StateChanged(current)
        self._save(conn, new)

    def _audit(self, action: str, result: str, detail: Mapping[str, object] | None = None) -> None:
        self.store.append_audit(self.operator, self.name, action, result, detail, when=self.clock())

    def _refuse(self, action: str, reason: str) -> RefusedError:
        self._audit(action, "refused", {"reason": reason})
        return RefusedError(f"{self.name}: {action} refused: {reason}")

    def _refuse_changed(self, action: str, changed: _StateChanged, hint: str = "") -> RefusedError:
        """A compare-and-set lost to another step: say what the capsule became."""
        return self._refuse(action, f"the capsule became {changed.current.state.value} meanwhile{hint}")

    # Power-on ---------------------------------------------------------------------------------

    def power_on(self, confirmed: bool) -> ReleaseRecord:
        """Pulse the latching relay; software cannot switch it off again, hence the confirmation.

        The attempt is recorded (compare-and-set) before the Pi is asked, as ``power-on-unknown``: a
        console killed while the Pi runs the script, or before it records the answer, once left ``idle``
        over a latched relay. Only the Pi's own refusal (its release-authority lock, checked before the
        relay is touched) puts the previous state back; a link that fails meanwhile leaves the outcome
        unknown, which power-on again or reset settles.
        """
        current = self.record()
        if not confirmed:
            raise self._refuse("power-on", "not confirmed (the relay cannot be switched off by software)")
        if current.state in (ReleaseState.RELEASED, ReleaseState.GO_SENT):
            raise self._refuse(
                "power-on", f"capsule is {current.state.value}; reset it after recovery before a new release"
            )
        attempt = ReleaseRecord(
            self.name, ReleaseState.POWER_ON_UNKNOWN, secrets.token_hex(8), self.holder, current.log_offset,
            None, None, None, None, POWER_ON_UNKNOWN_NOTE,
        )  # fmt: skip
        try:
            self._swap(current, attempt)
        except _StateChanged as changed:
            raise self._refuse_changed("power-on", changed, " (another console?)") from None
        self._audit("power-on", "started", {"holder": self.holder, "session": attempt.session})
        try:
            result = self.backend.power_on(self.holder, self.capsule.authority_lease_s)
        except RefusedError as exc:
            try:
                self._swap(attempt, current)
            except _StateChanged:
                pass  # another step moved the capsule on meanwhile: its state stands
            self._audit("power-on", "refused", {"reason": str(exc)})
            raise
        except LinkError as exc:
            self._audit("power-on", "outcome unknown", {"error": str(exc)})
            raise LinkError(f"{exc}; {POWER_ON_UNKNOWN_NOTE}") from None
        record = replace(
            attempt,
            state=ReleaseState.POWERED,
            log_offset=result.log_offset,
            powered_at=self.clock(),
            note=None,
        )
        try:
            self._swap(attempt, record)
        except _StateChanged as changed:
            raise self._refuse(
                "power-on",
                f"the relay is latched, but the capsule became {changed.current.state.value} "
                "meanwhile (another console?); that state is kept",
            ) from None
        except StoreError as exc:
            raise StoreError(
                f"{self.name}: power-on ran on the Pi (the relay is latched) but was not recorded: {exc}; "
                "the store says power-on-unknown"
            ) from None
        self._audit("power-on", "ok", {"session": record.session, "log_offset": result.log_offset})
        return record

    # Microcontroller and GNSS -------------------------------------------------------------------

    def check_microcontroller(self) -> MicrocontrollerReport:
        """Read the serial log once and say whether the microcontroller is waiting for Go."""
        record = self.record()
        if record.state is not ReleaseState.POWERED:
            return MicrocontrollerReport(
                False,
                None,
                summarise([], self.clock()),
                f"capsule is {record.state.value}: no power-on session",
            )
        lines = self.backend.read_serial(record.log_offset)
        now = self.clock()
        gnss = summarise(lines, now)
        elapsed = (now - record.powered_at).total_seconds() if record.powered_at else None
        if gnss.nmea_seen:
            if record.nmea_seen_at is None:
                try:
                    self._swap(record, replace(record, nmea_seen_at=now))
                    self._audit("microcontroller", "waiting for Go", {"gnss": gnss.as_dict()})
                except _StateChanged:
                    pass  # another step moved the capsule on; the NMEA seen is reported all the same
            return MicrocontrollerReport(
                True, elapsed, gnss, "NMEA arriving: the microcontroller is waiting for Go"
            )
        if elapsed is not None and elapsed < self.capsule.microcontroller_wait_s:
            return MicrocontrollerReport(
                False,
                elapsed,
                gnss,
                f"no NMEA yet, {elapsed:.0f} s after power-on: still booting (allow ~25 s)",
                still_booting=True,
            )
        return MicrocontrollerReport(False, elapsed, gnss, SILENT_MICROCONTROLLER_CHECKS)

    def wait_for_microcontroller(self) -> MicrocontrollerReport:
        """Poll the log until NMEA arrives or ``microcontroller_wait_s`` after power-on has passed."""
        while True:
            report = self.check_microcontroller()
            if report.waiting_for_go:
                return report
            if not report.still_booting:
                if report.seconds_since_power_on is not None:
                    self._audit("microcontroller", "silent", {"diagnosis": report.diagnosis})
                return report
            self.sleep(SEEN_NMEA_POLL_S)

    # Confirmation and Go ----------------------------------------------------------------------

    def confirm(self, typed_name: str) -> ConfirmationToken:
        """Mint a Go token; the operator must type this capsule's name, not click through."""
        record = self.record()
        typed_text("the typed capsule name", typed_name)
        if typed_name != self.name:
            raise self._refuse(
                "go-confirmation", f"the confirmation {typed_name!r} does not name {self.name!r}"
            )
        if record.state is ReleaseState.RELEASED:
            raise self._refuse("go-confirmation", "the capsule is already released")
        if record.state not in (ReleaseState.POWERED, ReleaseState.GO_SENT) or record.session is None:
            raise self._refuse("go-confirmation", "power-on has not succeeded in this session")
        now = self.clock()
        token = ConfirmationToken(secrets.token_urlsafe(16), self.name, now)
        self.store.write(
            "INSERT INTO release_tokens (token, capsule, session, minted_at) VALUES (?, ?, ?, ?)",
            (token.value, self.name, record.session, iso_utc(now)),
        )
        self._audit("go-confirmation", "minted", {"session": record.session})
        return token

    def _check_go(self, token: ConfirmationToken) -> ReleaseRecord:
        record = self.record()
        if record.state is ReleaseState.RELEASED:
            raise self._refuse("go", "the capsule is already released")
        if record.state not in (ReleaseState.POWERED, ReleaseState.GO_SENT) or record.session is None:
            raise self._refuse("go", "power-on has not succeeded in this session")
        rows = self.store.query(
            "SELECT * FROM release_tokens WHERE token = ? AND capsule = ?", (token.value, self.name)
        )
        if not rows:
            raise self._refuse("go", "the confirmation token was not minted for this capsule")
        row = rows[0]
        if row["session"] != record.session:
            raise self._refuse("go", "the confirmation token belongs to an earlier power-on session")
        if row["used_at"] is not None:
            raise self._refuse("go", "the confirmation token was already used")
        age = (self.clock() - parse_iso_utc(row["minted_at"])).total_seconds()
        if not 0 <= age <= self.token_ttl_s:
            raise self._refuse("go", f"the confirmation is {age:.0f} s old (limit {self.token_ttl_s:.0f} s)")
        if record.nmea_seen_at is None:
            raise self._refuse(
                "go", "no NMEA seen since power-on, so the microcontroller is not known to be waiting for Go"
            )
        return record

    def go(self, token: ConfirmationToken) -> ReleaseRecord:
        """Send Go once; the link dropping right after ``Shutting down...`` is the expected success.

        While a Go is unverified the record keeps the first Go's time: that is when the capsule may have
        left. A retry that the Pi confirms (GoGoGo written) shows the Pi was still up to take it, so the
        release time becomes the verified Go's and the failed attempt's is kept beside it
        (``failed_go_at``, and in the audit).
        """
        record = self._check_go(token)
        now = self.clock()
        sending = replace(
            record, state=ReleaseState.GO_SENT, go_at=record.go_at or now, note="Go sent, not yet confirmed"
        )
        try:
            with self.store.transaction() as conn:
                used = conn.execute(
                    "UPDATE release_tokens SET used_at = ? WHERE token = ? AND used_at IS NULL",
                    (iso_utc(now), token.value),
                ).rowcount
                if used != 1:
                    raise _TokenUsed()
                self._swap_in(conn, record, sending)
        except _TokenUsed:
            raise self._refuse("go", "the confirmation token was already used") from None
        except _StateChanged as changed:
            raise self._refuse_changed("go", changed, " (another console?)") from None
        retry = {"retry_of_go_at": iso_utc(record.go_at)} if record.go_at else {}
        self._audit("go", "sending", {"session": record.session, **retry})
        try:
            result = self.backend.go(self.holder)
        except RefusedError as exc:
            try:
                self._swap(sending, record)
            except _StateChanged:
                pass  # another step moved the capsule on meanwhile: its state stands, not our stale copy
            self._audit("go", "refused", {"reason": str(exc)})
            raise
        except LinkError as exc:
            self._audit("go", "unverified", {"error": str(exc)})
            raise LinkError(
                f"{self.name}: Go may or may not have reached the Pi ({exc}); check the capsule, "
                "a repeated Go is harmless to the firmware"
            ) from None
        return self._conclude(sending, result, now if record.go_at else None)

    def _conclude(
        self, sending: ReleaseRecord, result: GoResult, retry_at: datetime | None = None
    ) -> ReleaseRecord:
        """``retry_at``: this Go finishes an unverified one (sent at ``sending.go_at``) and was sent then."""
        detail: dict[str, object] = {
            "exit_status": result.exit_status,
            "link_dropped": result.link_dropped,
            "firmware_acknowledged": result.acknowledged,
        }
        if retry_at is not None and sending.go_at is not None:
            detail |= {"go_at": iso_utc(retry_at), "failed_go_at": iso_utc(sending.go_at)}
        if result.go_written and result.shutting_down:
            note = "released, Pi shut down" if result.link_dropped else "released, Pi shutting down"
        elif result.go_written:
            note = "released, Pi shutdown not seen"
        else:
            self._audit("go", "unverified", {**detail, "output_tail": result.output[-400:]})
            how = "the link dropped" if result.link_dropped else "the Go script ended"
            raise LinkError(
                f"{self.name}: {how} before confirming that GoGoGo was written; Go may or may not have "
                "reached the capsule (check it; a repeated Go is harmless to the firmware)"
            )
        released = replace(sending, state=ReleaseState.RELEASED, released_at=self.clock(), note=note)
        if retry_at is not None:
            released = replace(released, go_at=retry_at, failed_go_at=sending.go_at)
        try:
            self._swap(sending, released)
        except _StateChanged as changed:
            if changed.current.state is not ReleaseState.RELEASED:
                raise
            self._audit("go", f"{note} (already recorded released)", detail)
            return changed.current
        except StoreError as exc:
            # The Pi has acted: an operator told only "cannot update the store" might Go again (#24).
            raise StoreError(
                f"{self.name}: Go reached the Pi ({note}) but was not recorded: {exc}; the capsule IS "
                "released, do not Go again; the store says go-sent-unverified: once it can be written, "
                f"settle it with `drs capsule released {self.name} --confirm {self.name} --evidence …`"
            ) from None
        self._audit("go", note, detail)
        return released

    def recheck_unverified_go(self, after_s: float) -> ReleaseRecord:
        """End an unverified Go that the Pi never took, so that a fresh ARM and FIRE under every rule can
        release the capsule; nothing is sent to the Pi but the serial logger's read.

        Why a Pi that answers proves it: the Go script shuts the Pi down within 6 s of writing GoGoGo,
        and a capsule that drops pulls its power connector apart (drs_protocol.md §1 and §2.6). A Pi that
        still runs its logger ``after_s`` after the attempt was neither shut down nor dropped, so the
        capsule is still on the balloon: back to powered, the failed attempt's time kept beside it. A Pi
        that does not answer leaves the Go unverified: the capsule may be falling (``record_released``).
        """
        record = self.record()
        if record.state is not ReleaseState.GO_SENT or record.go_at is None:
            return record
        waited = (self.clock() - record.go_at).total_seconds()
        if waited < after_s:
            return record
        try:
            lines = self.backend.read_serial(record.log_offset)
        except LinkError:
            return record
        now = self.clock()
        gnss = summarise(lines, now)
        note = f"Go of {record.go_at:%H:%M:%S}Z never taken: the Pi still answered {waited:.0f} s later"
        back = replace(
            record, state=ReleaseState.POWERED, go_at=None, failed_go_at=record.go_at,
            nmea_seen_at=now if gnss.nmea_seen else None, note=note,
        )  # fmt: skip
        try:
            self._swap(record, back)
        except _StateChanged:
            return self.record()
        self._audit("go", "not taken", {"failed_go_at": iso_utc(record.go_at), "waited_s": round(waited),
                                        "nmea_seen": gnss.nmea_seen})  # fmt: skip
        return back

    def record_released(self, typed_name: str, evidence: str) -> ReleaseRecord:
        """Settle an unverified Go as released, on the operator's evidence.

        A console killed after the Pi wrote GoGoGo, and before it recorded the answer, leaves
        ``go-sent-unverified``; the Pi then halts, so no Go retry can confirm it, and reset is refused
        there (the capsule may be falling). Only an operator who knows (the Iridium reports show the
        fall, the balloon team saw it go) can end it: named, with the evidence in the audit log.
        The release time is the first Go's, when the capsule may have left.
        """
        typed_text("the typed capsule name", typed_name)
        if typed_name != self.name:
            raise self._refuse("released", f"the confirmation {typed_name!r} does not name {self.name!r}")
        if self.operator == "unknown":
            raise self._refuse(
                "released", "no operator name: set [operator] name; this ends a release on the record"
            )
        typed_text("the release evidence", evidence)
        if not evidence.strip() or not evidence.isprintable():
            raise self._refuse(
                "released", "give the evidence as one line of text (what shows it was released)"
            )
        seen = self.record()
        if seen.state is not ReleaseState.GO_SENT:
            raise self._refuse(
                "released",
                f"the capsule is {seen.state.value}: only an unverified Go can be settled as released",
            )
        released = replace(
            seen, state=ReleaseState.RELEASED, released_at=seen.go_at,
            note=f"released (recorded by {self.operator}: {evidence.strip()})",
        )  # fmt: skip
        try:
            self._swap(seen, released)
        except _StateChanged as changed:
            raise self._refuse_changed("released", changed) from None
        self._audit("go", "released (recorded by the operator)", {"evidence": evidence.strip()})
        return released

    # Release authority ------------------------------------------------------------------------

    def authority(self) -> AuthorityStatus:
        """Who holds the release authority on the Pi now; reading it changes nothing, so it is not audited."""
        return self.backend.authority()

    def check_take_over(
        self, reason: str, seen: AuthorityStatus | None = None, typed_name: str | None = None
    ) -> None:
        """Refuse (audited) a take-over that can never be right, before the Pi is asked, an approval is
        spent, or (``typed_name`` None) the name typed."""
        if reason.strip():
            typed_text("the take-over reason", reason)
        if typed_name is not None:
            typed_text("the typed capsule name", typed_name)
            if typed_name != self.name:
                raise self._refuse_take_over(
                    f"the confirmation {typed_name!r} does not name {self.name!r}", reason, seen
                )
        if self.record().state is ReleaseState.RELEASED:
            raise self._refuse_take_over("the capsule is already released", reason, seen)
        if not reason.strip():
            raise self._refuse_take_over(
                "a reason is required (it is written to the audit log)", reason, seen
            )

    def _take_over_detail(self, reason: str, seen: AuthorityStatus | None) -> dict[str, object]:
        return {
            "holder": self.holder,
            "from": seen.holder if seen else None,
            "from_state": seen.state.value if seen else None,
            "from_lease_end": iso_utc(seen.lease_end) if seen and seen.lease_end else None,
            "reason": reason.strip(),
        }

    def _refuse_take_over(self, refusal: str, reason: str, seen: AuthorityStatus | None) -> RefusedError:
        self._audit(
            "authority-take-over", "refused", {**self._take_over_detail(reason, seen), "refusal": refusal}
        )
        return RefusedError(f"{self.name}: take-over refused: {refusal}")

    def take_over(self, seen: AuthorityStatus, typed_name: str, reason: str) -> AuthorityStatus:
        """Become the release-authority holder deliberately: named, with a reason, audited before and after.

        ``seen`` is what the operator was shown; the Pi hands the authority over only if its owner
        file still says exactly that, so a console that renewed or took over meanwhile is never
        silently overridden. Taking over from this console's own holder is a plain renewal.
        """
        self.check_take_over(reason, seen)
        typed_text("the typed capsule name", typed_name)
        if typed_name != self.name:
            raise self._refuse_take_over(
                f"the confirmation {typed_name!r} does not name {self.name!r}", reason, seen
            )
        detail = self._take_over_detail(reason, seen)
        self._audit("authority-take-over", "started", detail)
        try:
            now = self.backend.take_over_authority(self.holder, seen, self.capsule.authority_lease_s)
        except RefusedError as exc:
            self._audit("authority-take-over", "refused", {**detail, "refusal": str(exc)})
            raise
        except LinkError as exc:
            self._audit("authority-take-over", "failed", {**detail, "error": str(exc)})
            raise
        result = take_over_outcome(seen, self.holder)
        lease_end = iso_utc(now.lease_end) if now.lease_end else None
        self._audit("authority-take-over", result, {**detail, "lease_end": lease_end})
        return now

    def release_authority(self, reason: str = "") -> AuthorityStatus:
        """Give up this console's release authority (end of a shift); refused if another console holds it.

        Returns what was given up: this console's lease, or a free authority when it held none.
        """
        typed_text("the reason for giving up release authority", reason)
        detail: dict[str, object] = {"holder": self.holder, "reason": reason.strip()}
        self._audit("authority-release", "started", detail)
        try:
            before = self.backend.release_authority(self.holder)
        except RefusedError as exc:
            self._audit("authority-release", "refused", {**detail, "refusal": str(exc)})
            raise
        except LinkError as exc:
            self._audit("authority-release", "failed", {**detail, "error": str(exc)})
            raise
        if before.lease_end is None:
            self._audit("authority-release", "was free", detail)
        else:
            self._audit("authority-release", "released", {**detail, "lease_end": iso_utc(before.lease_end)})
        return before

    def reset(self, typed_name: str) -> ReleaseRecord:
        """After recovery (Gone flag cleared on the unit), allow a new release of this capsule.

        Not while a Go is unverified: the capsule may be falling, and a reset would let the next
        power-on and Go be treated as the first. Not without a named operator: it ends a release.
        """
        typed_text("the typed capsule name", typed_name)
        if typed_name != self.name:
            raise self._refuse("reset", f"the confirmation {typed_name!r} does not name {self.name!r}")
        if self.operator == "unknown":
            raise self._refuse(
                "reset", "no operator name: set [operator] name; a reset ends a release on the record"
            )
        seen = self.record()
        if seen.state is ReleaseState.GO_SENT:
            raise self._refuse(
                "reset",
                "Go was sent and not verified: the capsule may have been released; find out first "
                "(drs capsule status, its Iridium reports): send Go again if it is still on the balloon, "
                "or record it released with the evidence (drs capsule released)",
            )
        record = ReleaseRecord(self.name, ReleaseState.IDLE, None, None, 0, None, None, None, None, "reset")
        try:
            self._swap(seen, record)
        except _StateChanged as changed:
            raise self._refuse_changed("reset", changed) from None
        self._audit("reset", "ok", {"from": seen.state.value})
        return record


def record_as_dict(record: ReleaseRecord) -> dict[str, object]:
    def iso(moment: datetime | None) -> str | None:
        return iso_utc(moment) if moment else None

    return {
        "capsule": record.capsule,
        "state": record.state.value,
        "powered_at": iso(record.powered_at),
        "nmea_seen_at": iso(record.nmea_seen_at),
        "go_at": iso(record.go_at),
        "released_at": iso(record.released_at),
        "failed_go_at": iso(record.failed_go_at),
        "note": record.note,
    }

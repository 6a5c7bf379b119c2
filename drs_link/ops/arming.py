"""ARM then FIRE: the release of one capsule as two deliberate acts, enforced below any screen.

ARM is granted only on a GO poll and opens a short window. FIRE is accepted only inside that
window, only with the capsule's name typed (and, when the flight rules ask for it, a second,
different operator or a logged single-operator waiver), and only if the poll still says GO with
the same values ARM saw: any change, a lost link or a stale critical input disarms. FIRE then
goes through the release state machine's own confirmation token (``ReleaseStateMachine.confirm``
and ``go``), so the Pi-side preconditions are checked a second time by the layer that owns them.
Every transition is audited before it is reported.

The window lives in the store (``drs_link.ops.arm_window``): one per capsule across every console
and ``drs`` process, held by the process that opened it. An approval is bound to one window
(``drs_link.ops.approval``): when the window closes, for whatever reason, its approvals are void, so a
late approval can never fire the capsule in a later window.
"""

from __future__ import annotations

import sqlite3
import threading
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime, timedelta
from enum import StrEnum
from typing import Protocol

from drs_link.errors import RefusedError
from drs_link.ops.approval import ApprovalBook, Login, current_login, window_command
from drs_link.ops.arm_window import (
    ARMED,
    CLOSED,
    FIRED,
    FIRING,
    ArmWindow,
    ArmWindows,
    expired_reason,
    process_holder,
    start_firing_in,
)
from drs_link.ops.brief import report_json
from drs_link.ops.capsule import ConfirmationToken, ReleaseRecord, ReleaseState
from drs_link.ops.gonogo import WAIVER_REASON_MAX, GoNoGoReport, Waiver
from drs_link.ops.typed_text import typed_optional, typed_text
from drs_link.store import Store, session_name, utc_now

DEFAULT_ARM_WINDOW_S = 60.0
FINISH_GO_S = 60.0
"""How long after a Go that was never verified its ARM window's holder may still finish it without a
fresh ARM: long enough to see the link drop and send it again, short enough that the go/no-go it was
judged on still stands (issue #29)."""
FIRING_STALE_S = 30.0
"""How long after its window's end a FIRING window whose Go never left is taken for a FIRE that died.
Between FIRING and the state machine's write-ahead ``go-sent-unverified`` there is no network, only
SQLite: milliseconds. Without this, a console killed there would block the capsule's ARM for ever."""


class ReleaseMachine(Protocol):
    """The part of ``drs_link.ops.capsule.ReleaseStateMachine`` that FIRE drives."""

    @property
    def name(self) -> str: ...

    def confirm(self, typed_name: str) -> ConfirmationToken: ...

    def go(self, token: ConfirmationToken) -> ReleaseRecord: ...

    def record(self) -> ReleaseRecord: ...


class ArmState(StrEnum):
    DISARMED = "disarmed"
    ARMED = "armed"
    FIRING = "firing"
    FIRED = "fired"


_STATES = {ARMED: ArmState.ARMED, FIRING: ArmState.FIRING, FIRED: ArmState.FIRED, CLOSED: ArmState.DISARMED}


@dataclass(frozen=True)
class ArmStatus:
    state: ArmState
    armed_until: datetime | None
    remaining_s: float
    last_disarm_reason: str | None
    window: ArmWindow | None = None
    """The capsule's latest ARM window, whoever holds it."""
    mine: bool = True
    """Whether this process holds the window (only the holder can FIRE in it)."""

    @property
    def armed(self) -> bool:
        return self.state is ArmState.ARMED

    def holder_text(self) -> str:
        """Who holds another console's window, for the screen and the refusal: account@host pid."""
        return "" if self.window is None or self.mine else f"held by {self.window.who()}"


SECOND_LOGIN_HOWTO = (
    "ask another login to approve it (the console's 'Ask another login', or --await-approval here), "
    "then the second operator runs `drs approve ID` from their own login"
)


def check_second_operator(
    first: str,
    second: str | None,
    single_operator_waiver: str | None,
    required: bool,
    crew: tuple[str, ...] = (),
) -> dict[str, str]:
    """The two-person rule for hazardous commands (FIRE, PARACHUTE, a take-over); returns what to audit.

    With the rule required (``[console] require_second_operator``) only another login's approval
    satisfies it: a typed name or a waiver can be written by one person alone, so both are refused and
    the refusal says how to get an approval. Without it, a typed second operator must be a different
    person named in the configured crew list, and a team of one may waive the rule, saying why (audited).
    """
    first_name = first.strip()
    second_name = (typed_optional("the second operator's name", second) or "").strip()
    waiver = (typed_optional("the single-operator waiver", single_operator_waiver) or "").strip()
    if len(waiver) > WAIVER_REASON_MAX:
        raise RefusedError(
            f"a single-operator waiver is at most {WAIVER_REASON_MAX} characters (this one has {len(waiver)}): "
            "it is read on the screen and in History, so say why in a sentence"
        )
    if required:
        typed = "a typed second operator" if second_name else "a single-operator waiver" if waiver else ""
        if typed:
            raise RefusedError(
                f"require_second_operator is on: {typed} is not accepted; {SECOND_LOGIN_HOWTO}"
            )
        raise RefusedError(
            f"require_second_operator is on: a second login's approval is needed; {SECOND_LOGIN_HOWTO}"
        )
    if second_name:
        if second_name.casefold() == first_name.casefold():
            raise RefusedError(f"the second operator must be a different person than {first_name!r}")
        if second_name.casefold() not in {name.casefold() for name in crew}:
            listed = ", ".join(crew) if crew else "none configured"
            raise RefusedError(
                f"the second operator {second_name!r} is not in the crew list ([console] crew: {listed})"
            )
        return {"second_operator": second_name}
    if waiver:
        return {"single_operator_waiver": waiver}
    return {}


class ArmingController:
    """The ARM window of one capsule as this process sees it; thread-safe because FIRE runs in a worker."""

    def __init__(
        self,
        store: Store,
        machine: ReleaseMachine,
        operator: str,
        clock: Callable[[], datetime] = utc_now,
        arm_window_s: float = DEFAULT_ARM_WINDOW_S,
        require_second_operator: bool = False,
        holder: str | None = None,
        crew: tuple[str, ...] = (),
    ) -> None:
        if arm_window_s <= 0:
            raise ValueError("the ARM window must be positive")
        self.store = store
        self.machine = machine
        self.operator = operator or "unknown"
        self.clock = clock
        self.arm_window_s = arm_window_s
        self.require_second_operator = require_second_operator
        self.crew = crew
        self.session = session_name()
        self.holder = holder or process_holder()
        """Who may FIRE in a window this controller opens: this process (its session and a random token,
        so a later process given the same pid is not it), or (the CLI) account@host."""
        self.windows = ArmWindows(store)
        self._lock = threading.RLock()

    @property
    def capsule(self) -> str:
        return self.machine.name

    def _audit(self, action: str, result: str, detail: dict[str, object] | None = None) -> None:
        self.store.append_audit(self.operator, self.capsule, action, result, detail, when=self.clock())

    def status(self) -> ArmStatus:
        """The current state; an ARM window that has run out is closed (and audited, once) here."""
        with self._lock:
            now = self.clock()
            window = self.windows.latest(self.capsule)
            if window is not None and window.state == ARMED and now >= window.until_utc:
                self._close(window, expired_reason(window))
                window = self.windows.latest(self.capsule)
            if window is not None and window.state == FIRING and self._fire_died(window, now):
                self._close(window, "FIRE stopped before Go left (the firing process ended)", (FIRING,))
                window = self.windows.latest(self.capsule)
            if window is None:
                return ArmStatus(ArmState.DISARMED, None, 0.0, None)
            state = _STATES[window.state]
            armed = state is ArmState.ARMED
            remaining = max(0.0, (window.until_utc - now).total_seconds()) if armed else 0.0
            return ArmStatus(
                state, window.until_utc if armed else None, remaining,
                window.reason if state is ArmState.DISARMED else None, window, window.holder == self.holder,
            )  # fmt: skip

    def seen(self) -> ArmStatus:
        """The state as a view shows it, without waiting for a FIRE that holds the lock while Go is sent
        (the server's push to every console must not stall for 10 s): ``status`` when the lock is free,
        else the window as the store has it (FIRING, while that FIRE runs), closing nothing."""
        if self._lock.acquire(blocking=False):
            try:
                return self.status()
            finally:
                self._lock.release()
        window = self.windows.latest(self.capsule)
        if window is None:
            return ArmStatus(ArmState.DISARMED, None, 0.0, None)
        state = _STATES[window.state]
        armed = state is ArmState.ARMED
        remaining = max(0.0, (window.until_utc - self.clock()).total_seconds()) if armed else 0.0
        return ArmStatus(
            state, window.until_utc if armed else None, remaining,
            window.reason if state is ArmState.DISARMED else None, window, window.holder == self.holder,
        )  # fmt: skip

    def _fire_died(self, window: ArmWindow, now: datetime) -> bool:
        """A FIRING window long past its end whose Go never left: the state machine is still before Go."""
        if (now - window.until_utc).total_seconds() < FIRING_STALE_S:
            return False
        return self.machine.record().state not in (ReleaseState.GO_SENT, ReleaseState.RELEASED)

    def finished(self) -> None:
        """An unverified Go was finished (``Release.finish_go``): the window that authorised it fired."""
        with self._lock:
            window = self.windows.latest(self.capsule)
            if window is not None and window.state == FIRING:
                self.windows.fired(window.id, self.clock())

    def go_not_taken(self, reason: str) -> None:
        """The unverified Go of the FIRING window never left (``ReleaseStateMachine.recheck_unverified_go``):
        the window closes, with its approvals, so that only a fresh ARM and FIRE may send Go."""
        with self._lock:
            window = self.windows.latest(self.capsule)
            if window is not None and window.state == FIRING:
                self._close(window, reason, (FIRING,))

    def _close(self, window: ArmWindow, reason: str, states: tuple[str, ...] = (ARMED,)) -> None:
        """Close a window and void every approval given for it; audited by whichever process won."""
        if self.windows.close(window.id, reason, self.clock(), states):
            self._audit("disarm", reason, {"window": window.id, "held_by": window.session})
            ApprovalBook(self.store, self.clock).void_window(
                self.capsule, window.id, f"ARM window #{window.id} closed: {reason}", self.operator
            )

    def arm(self, report: GoNoGoReport, waivers: Sequence[Waiver] = ()) -> ArmStatus:
        """Open the window on a GO poll; the poll and the ``waivers`` of its WAIVED items are kept with
        the window, for a Go approval to show its approver (``drs_link.ops.brief``)."""
        with self._lock:
            if report.capsule != self.capsule:
                raise RefusedError(f"{self.capsule}: ARM refused: the poll is for {report.capsule!r}")
            state = self.status().state
            if state in (ArmState.FIRING, ArmState.FIRED):
                raise RefusedError(f"{self.capsule}: ARM refused: the capsule is {state.value}")
            if not report.go:
                self._audit("arm", "refused", {"reason": report.summary()})
                raise RefusedError(f"{self.capsule}: ARM refused: {report.summary()}")
            now = self.clock()
            before = self.windows.latest(self.capsule)
            window, in_way = self.windows.open(
                self.capsule, self.holder, self.session, self.operator, now,
                now + timedelta(seconds=self.arm_window_s), report.fingerprint, report_json(report, waivers),
            )  # fmt: skip
            if window is None:
                assert in_way is not None
                why = (
                    f"ARM window #{in_way.id} is held by {in_way.who()} until {in_way.until_utc:%H:%M:%S}Z; "
                    "one ARM per capsule"
                    if in_way.state == ARMED else f"the capsule is {in_way.state}"
                )  # fmt: skip
                self._audit("arm", "refused", {"reason": why})
                raise RefusedError(f"{self.capsule}: ARM refused: {why}")
            if before is not None and before.state == ARMED:
                self._audit("disarm", "re-armed", {"window": before.id})
                ApprovalBook(self.store, self.clock).void_window(
                    self.capsule, before.id, f"ARM window #{before.id} closed: re-armed", self.operator
                )
            self._audit("arm", "armed", {"window": window.id, "window_s": self.arm_window_s,
                                         "inputs": report.fingerprint})  # fmt: skip
            return self.status()

    def disarm(self, reason: str, any_holder: bool = False) -> ArmStatus:
        """Close this process's window; ``any_holder``: an operator's explicit disarm closes anyone's
        (disarming is always the safe direction)."""
        with self._lock:
            status = self.status()
            if status.window is not None and status.armed and (status.mine or any_holder):
                self._close(status.window, reason)
            return self.status()

    def observe(self, report: GoNoGoReport) -> ArmStatus:
        """Feed each new poll: a NO-GO or any changed value disarms this process's window at once."""
        with self._lock:
            status = self.status()
            if not status.armed or not status.mine or status.window is None:
                return status
            if not report.go:
                self._close(status.window, f"no longer GO: {report.summary()}")
            elif report.fingerprint != status.window.fingerprint:
                self._close(status.window, "inputs changed since ARM")
            return self.status()

    def after_reset(self) -> ArmStatus:
        """The capsule was recovered and reset (``ReleaseStateMachine.reset``): a new release may start."""
        with self._lock:
            window = self.windows.latest(self.capsule)
            if window is not None and window.state in (FIRING, FIRED):
                self._close(window, "capsule reset after recovery", (FIRING, FIRED))
            return self.status()

    def link_lost(self) -> ArmStatus:
        return self.disarm("link lost")

    def window_for_approval(self, typed_name: str) -> ArmWindow:
        """The window a Go approval is asked for: this process's open one (else the refusal FIRE gives)."""
        with self._lock:
            status = self._fireable(typed_name)
            assert status.window is not None
            return status.window

    def _fireable(self, typed_name: str) -> ArmStatus:
        status = self.status()
        if status.state in (ArmState.FIRING, ArmState.FIRED):
            why = f"the capsule is {status.state.value}"
            self._audit("fire", "refused", {"reason": why})
            raise RefusedError(f"{self.capsule}: FIRE refused: {why}")
        if status.state is not ArmState.ARMED:
            why = f"not armed: {status.last_disarm_reason}" if status.last_disarm_reason else "not armed"
            self._audit("fire", "refused", {"reason": why})
            raise RefusedError(f"{self.capsule}: FIRE refused: {why}")
        if not status.mine:
            why = f"the ARM window is {status.holder_text()}, not this console"
            self._audit("fire", "refused", {"reason": why})
            raise RefusedError(f"{self.capsule}: FIRE refused: {why}")
        typed_text("the typed capsule name", typed_name)
        if typed_name != self.capsule:
            self._audit("fire", "refused", {"reason": "wrong capsule name typed", "typed": typed_name})
            raise RefusedError(
                f"{self.capsule}: FIRE refused: the typed name {typed_name!r} does not name {self.capsule!r}"
            )
        return status

    def fire(
        self,
        typed_name: str,
        report: GoNoGoReport,
        second_operator: str | None = None,
        single_operator_waiver: str | None = None,
        approval: int | None = None,
        login: Login | None = None,
        on_sending: Callable[[], None] | None = None,
    ) -> ReleaseRecord:
        """Release; blocking (SSH), so call it from a worker thread. Refused unless every rule holds.

        ``approval``: a Go request another login approved for this very window
        (``drs_link.ops.approval``), spent here once in place of a typed second operator: marked used in
        the same transaction that moves the window to FIRING, after every other check, so an approval is
        never spent on a FIRE that was then refused.

        A Go that may have left (the state machine says ``go-sent-unverified``) keeps its window FIRING and
        its approval as it is: only its holder may finish it, briefly (``Release.finish_go``).
        ``on_sending``: told once every rule here held, just before the Go goes to the state machine (a
        "sending Go…" line printed earlier stood above each refusal).
        """
        with self._lock:
            status = self._fireable(typed_name)
            assert status.window is not None
            window = status.window
            if not self.observe(report).armed:
                why = self.status().last_disarm_reason
                raise RefusedError(f"{self.capsule}: FIRE refused and disarmed: {why}")
            now = self.clock()
            closed = f"ARM window #{window.id} closed meanwhile (expired, disarmed or taken)"

            def firing(conn: sqlite3.Connection) -> str | None:
                return None if start_firing_in(conn, window.id, self.holder, self.clock()) else closed

            try:
                if approval is not None:
                    people = ApprovalBook(self.store, self.clock).use(
                        approval, self.capsule, "go", login or current_login(), window_command(window.id),
                        also=firing,
                    )  # fmt: skip
                else:
                    people = check_second_operator(
                        self.operator, second_operator, single_operator_waiver, self.require_second_operator,
                        self.crew,
                    )  # fmt: skip
                    if not self.windows.start_firing(window.id, self.holder, now):
                        raise RefusedError(closed)
            except RefusedError as exc:
                self._audit("fire", "refused", {"reason": str(exc)})
                raise RefusedError(f"{self.capsule}: FIRE refused: {exc}") from None
            self._audit("fire", "authorised", {"window": window.id, "inputs": report.fingerprint, **people})
        try:
            token = self.machine.confirm(typed_name)
            if on_sending is not None:
                on_sending()
            record = self.machine.go(token)
        except Exception:
            with self._lock:
                if self.machine.record().state is ReleaseState.GO_SENT:
                    self._audit("fire", "unverified", {"window": window.id})
                else:
                    self._close(window, "FIRE failed", (FIRING,))
            raise
        self.windows.fired(window.id, self.clock())
        return record

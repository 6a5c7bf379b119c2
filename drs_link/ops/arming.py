"""ARM then FIRE: the release of one capsule as two deliberate acts, enforced below any screen.

ARM is granted only on a GO poll and opens a short window. FIRE is accepted only inside that
window, only with the capsule's name typed (and, when the flight rules ask for it, a second,
different operator or a logged single-operator waiver), and only if the poll still says GO with
the same values ARM saw: any change, a lost link or a stale critical input disarms. FIRE then
goes through the release state machine's own confirmation token (``ReleaseStateMachine.confirm``
and ``go``), so the Pi-side preconditions are checked a second time by the layer that owns them.
Every transition is audited before it is reported.
"""

from __future__ import annotations

import threading
from collections.abc import Callable
from dataclasses import dataclass
from datetime import datetime, timedelta
from enum import StrEnum
from typing import Protocol

from drs_link.errors import RefusedError
from drs_link.ops.approval import ApprovalBook, Login, current_login
from drs_link.ops.capsule import ConfirmationToken, ReleaseRecord
from drs_link.ops.gonogo import GoNoGoReport
from drs_link.store import Store, utc_now

DEFAULT_ARM_WINDOW_S = 60.0


class ReleaseMachine(Protocol):
    """The part of ``drs_link.ops.capsule.ReleaseStateMachine`` that FIRE drives."""

    @property
    def name(self) -> str: ...

    def confirm(self, typed_name: str) -> ConfirmationToken: ...

    def go(self, token: ConfirmationToken) -> ReleaseRecord: ...


class ArmState(StrEnum):
    DISARMED = "disarmed"
    ARMED = "armed"
    FIRING = "firing"
    FIRED = "fired"


@dataclass(frozen=True)
class ArmStatus:
    state: ArmState
    armed_until: datetime | None
    remaining_s: float
    last_disarm_reason: str | None

    @property
    def armed(self) -> bool:
        return self.state is ArmState.ARMED


def check_second_operator(
    first: str, second: str | None, single_operator_waiver: str | None, required: bool
) -> dict[str, str]:
    """The two-person rule for hazardous commands (FIRE, PARACHUTE); returns what to audit.

    The second operator must be a different person; a team of one may waive the rule, but only
    by saying why, and the waiver is audited with the command.
    """
    first_name = first.strip()
    second_name = (second or "").strip()
    if second_name:
        if second_name.casefold() == first_name.casefold():
            raise RefusedError(f"the second operator must be a different person than {first_name!r}")
        return {"second_operator": second_name}
    if single_operator_waiver and single_operator_waiver.strip():
        return {"single_operator_waiver": single_operator_waiver.strip()}
    if not required:
        return {}
    raise RefusedError("a second operator (a different name) is required, or a logged single-operator waiver")


class ArmingController:
    """The ARM window of one capsule; thread-safe because FIRE runs in a worker thread."""

    def __init__(
        self,
        store: Store,
        machine: ReleaseMachine,
        operator: str,
        clock: Callable[[], datetime] = utc_now,
        arm_window_s: float = DEFAULT_ARM_WINDOW_S,
        require_second_operator: bool = False,
    ) -> None:
        if arm_window_s <= 0:
            raise ValueError("the ARM window must be positive")
        self.store = store
        self.machine = machine
        self.operator = operator or "unknown"
        self.clock = clock
        self.arm_window_s = arm_window_s
        self.require_second_operator = require_second_operator
        self._lock = threading.RLock()
        self._state = ArmState.DISARMED
        self._armed_until: datetime | None = None
        self._fingerprint: str | None = None
        self._last_reason: str | None = None

    @property
    def capsule(self) -> str:
        return self.machine.name

    def _audit(self, action: str, result: str, detail: dict[str, object] | None = None) -> None:
        self.store.append_audit(self.operator, self.capsule, action, result, detail, when=self.clock())

    def status(self) -> ArmStatus:
        """The current state; an ARM window that has run out is closed (and audited) here."""
        with self._lock:
            now = self.clock()
            if self._state is ArmState.ARMED and self._armed_until is not None and now >= self._armed_until:
                self._disarm(f"ARM window expired at {self._armed_until:%H:%M:%S}Z")
            remaining = 0.0
            if self._state is ArmState.ARMED and self._armed_until is not None:
                remaining = max(0.0, (self._armed_until - now).total_seconds())
            return ArmStatus(self._state, self._armed_until, remaining, self._last_reason)

    def _disarm(self, reason: str) -> None:
        self._state = ArmState.DISARMED
        self._armed_until = None
        self._fingerprint = None
        self._last_reason = reason
        self._audit("disarm", reason)

    def arm(self, report: GoNoGoReport) -> ArmStatus:
        with self._lock:
            if report.capsule != self.capsule:
                raise RefusedError(f"{self.capsule}: ARM refused: the poll is for {report.capsule!r}")
            state = self.status().state
            if state in (ArmState.FIRING, ArmState.FIRED):
                raise RefusedError(f"{self.capsule}: ARM refused: the capsule is {state.value}")
            if not report.go:
                self._audit("arm", "refused", {"reason": report.summary()})
                raise RefusedError(f"{self.capsule}: ARM refused: {report.summary()}")
            self._state = ArmState.ARMED
            self._armed_until = self.clock() + timedelta(seconds=self.arm_window_s)
            self._fingerprint = report.fingerprint
            self._last_reason = None
            self._audit("arm", "armed", {"window_s": self.arm_window_s, "inputs": report.fingerprint})
            return self.status()

    def disarm(self, reason: str) -> ArmStatus:
        with self._lock:
            if self._state is ArmState.ARMED:
                self._disarm(reason)
            return self.status()

    def observe(self, report: GoNoGoReport) -> ArmStatus:
        """Feed each new poll: a NO-GO or any changed value disarms at once."""
        with self._lock:
            if self.status().state is not ArmState.ARMED:
                return self.status()
            if not report.go:
                self._disarm(f"no longer GO: {report.summary()}")
            elif report.fingerprint != self._fingerprint:
                self._disarm("inputs changed since ARM")
            return self.status()

    def after_reset(self) -> ArmStatus:
        """The capsule was recovered and reset (``ReleaseStateMachine.reset``): a new release may start."""
        with self._lock:
            if self._state is ArmState.FIRED:
                self._disarm("capsule reset after recovery")
            return self.status()

    def link_lost(self) -> ArmStatus:
        return self.disarm("link lost")

    def fire(
        self,
        typed_name: str,
        report: GoNoGoReport,
        second_operator: str | None = None,
        single_operator_waiver: str | None = None,
        approval: int | None = None,
        login: Login | None = None,
    ) -> ReleaseRecord:
        """Release; blocking (SSH), so call it from a worker thread. Refused unless every rule holds.

        ``approval``: a Go request another login approved (``drs_link.ops.approval``), spent here once in
        place of a typed second operator.
        """
        with self._lock:
            status = self.status()
            if status.state is not ArmState.ARMED:
                why = f"not armed: {status.last_disarm_reason}" if status.last_disarm_reason else "not armed"
                self._audit("fire", "refused", {"reason": why})
                raise RefusedError(f"{self.capsule}: FIRE refused: {why}")
            if typed_name != self.capsule:
                self._audit("fire", "refused", {"reason": "wrong capsule name typed", "typed": typed_name})
                raise RefusedError(
                    f"{self.capsule}: FIRE refused: the typed name {typed_name!r} does not name {self.capsule!r}"
                )
            self.observe(report)
            if self._state is not ArmState.ARMED:
                raise RefusedError(f"{self.capsule}: FIRE refused and disarmed: {self._last_reason}")
            try:
                if approval is not None:
                    people = ApprovalBook(self.store, self.clock).use(
                        approval, self.capsule, "go", login or current_login()
                    )
                else:
                    people = check_second_operator(
                        self.operator, second_operator, single_operator_waiver, self.require_second_operator
                    )
            except RefusedError as exc:
                self._audit("fire", "refused", {"reason": str(exc)})
                raise RefusedError(f"{self.capsule}: FIRE refused: {exc}") from None
            self._state = ArmState.FIRING
            self._audit("fire", "authorised", {"inputs": report.fingerprint, **people})
        try:
            token = self.machine.confirm(typed_name)
            record = self.machine.go(token)
        except Exception:
            with self._lock:
                self._state = ArmState.DISARMED
                self._armed_until = None
                self._last_reason = "FIRE failed"
            raise
        with self._lock:
            self._state = ArmState.FIRED
            self._armed_until = None
        return record

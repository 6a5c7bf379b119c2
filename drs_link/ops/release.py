"""One operator's release: go/no-go, ARM, FIRE, finishing an unverified Go and the release authority.

The rules themselves live in ``arming``/``gonogo``/``capsule``/``approval``; this wires them for one
operator (``OpsState``), for the CLI, the server and the console alike.
"""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

from drs_link.errors import RefusedError
from drs_link.link.backends import AuthorityStatus
from drs_link.ops.approval import approved, window_command
from drs_link.ops.arm_window import FIRING
from drs_link.ops.arming import FINISH_GO_S, ArmStatus, check_second_operator
from drs_link.ops.brief import ApprovalBrief, go_brief
from drs_link.ops.capsule import ReleaseRecord, ReleaseState
from drs_link.ops.fleet import CapsuleTelemetry, FleetState
from drs_link.ops.gonogo import GoNoGoReport, Waiver, evaluate
from drs_link.ops.iridium_ops import IridiumOps
from drs_link.ops.links import CapsuleLinks
from drs_link.ops.ops_state import CapsuleOps, OpsState, SecondOperator, load_exclusion_zones
from drs_link.ops.origin import ReleaseOrigin, release_origin
from drs_link.ops.telemetry import LinkSample, TelemetryRecord
from drs_link.ops.typed_text import typed_text
from drs_link.store import iso_utc

Predict = Callable[[str, ReleaseOrigin], list[TelemetryRecord]]
"""A landing prediction "release now" from an origin, as telemetry (the console's ``PredictionService``)."""


class Release:
    """The release of each capsule: go/no-go, waivers, ARM, FIRE, finishing an unverified Go, the release
    authority and its take-over, and the approvals they wait on."""

    def __init__(self, state: OpsState, links: CapsuleLinks, iridium: IridiumOps) -> None:
        """``links`` and ``iridium`` are the same operator's: ``poll_gonogo`` polls the capsule and the gateway."""
        self.state = state
        self.links = links
        self.iridium = iridium
        self.zones = load_exclusion_zones(state.config.console.exclusion_zones_file)

    def gonogo(self, name: str, telemetry: CapsuleTelemetry) -> GoNoGoReport:
        """The go/no-go poll of one capsule on what ``telemetry`` holds, with this process's waivers."""
        now = self.state.clock()
        return evaluate(
            name, telemetry.gonogo_inputs(now, self.zones), now, self.state.ops(name).waivers.waivers
        )

    def poll_gonogo(self, name: str, predict: Predict | None = None) -> GoNoGoReport:
        """The go/no-go poll for a process without a console's fleet (``drs capsule arm/go``): poll the
        capsule and the gateway now, predict "release now" from the fresh fix (when weather is given),
        and judge them by the same ``evaluate`` and the same items the console's release screen shows."""
        fleet = FleetState.for_capsules([name])
        for record in [*self.links.poll(name), *self.iridium.gateway_check()]:
            fleet.apply(record)
        origin = release_origin(fleet, name, self.state.clock())
        if predict is not None and origin is not None:
            for record in predict(name, origin):
                fleet.apply(record)
            # The capsule again, as it is now: a prediction can outlast a polled reading's freshness (a
            # first one compiling its kernels took 17 s on a loaded machine, and ARM was refused on link,
            # microcontroller and GNSS readings 20 s old). The prediction stays fresh for minutes.
            for record in self.links.poll(name):
                fleet.apply(record)
        return self.gonogo(name, fleet.capsules[name])

    def waive(self, name: str, item: str, reason: str) -> Waiver:
        """Waive one go/no-go item (GNSS fix or sync only), with this operator's name; audited."""
        return self.state.ops(name).waivers.grant(item, self.state.operator, reason)

    def arm(self, name: str, report: GoNoGoReport) -> ArmStatus:
        """Open the capsule's ARM window on a GO poll (one per capsule across consoles); audited. The poll
        and this process's waivers are kept with the window: a Go approval shows them to its approver."""
        ops = self.state.ops(name)
        return ops.arming.arm(report, ops.waivers.waivers)

    def fire(
        self,
        name: str,
        typed_name: str,
        poll: Callable[[], GoNoGoReport],
        second: SecondOperator = SecondOperator(),
        on_sending: Callable[[], None] | None = None,
    ) -> list[TelemetryRecord]:
        """FIRE (Go) in this process's open ARM window: every rule of ``ArmingController.fire``.

        With ``second.await_approval`` another login's approval is asked for, bound to this ARM window
        and ending with it, and waited on (without holding the capsule's lock) before FIRE is tried.
        ``poll`` is the go/no-go poll, taken once the approval is in: FIRE judges the inputs of the moment.
        """
        ops = self.state.ops(name)
        approval = None
        if second.await_approval:
            window = ops.arming.window_for_approval(typed_name)
            summary = f"Go: release {name} in ARM window #{window.id}"
            approval = approved(
                self.state.approvals, name, "go", summary, self.state.operator,
                self.state.login, second.on_pending or (lambda request: None), command=window_command(window.id),
                window_id=window.id, deadline=window.until_utc, brief=go_brief(summary, window.report),
            )  # fmt: skip
        report = poll()  # before the lock: a poll of the capsule (drs capsule go) takes it itself
        with ops.lock:
            login = self.state.login if approval is not None else None
            record = ops.arming.fire(
                typed_name, report, second.name, second.waiver, approval, login, on_sending
            )
            ops.link.close()
            self.state.command_done(name, "fire", record.note or "Go sent")
        self.state.approvals.void_capsule(name, "capsule state changed: released", self.state.operator)
        return self.state.emit([
            self.state.release_record(name, record),
            TelemetryRecord(self.state.clock(), name, LinkSample(False, "released: the Pi shut down")),
        ])  # fmt: skip

    def finish_go(self, name: str, typed_name: str) -> list[TelemetryRecord]:
        """Finish a Go that left and was never verified (its link dropped before GoGoGo was confirmed):
        the state machine retries it. Not a new release decision, so no new ARM, and therefore narrow
        (issue #29): only the holder of the ARM window that authorised it, within ``FINISH_GO_S`` of the
        failed attempt, and (with ``require_second_operator``) while the approval it was fired with is still
        valid; otherwise refused, and only a fresh ARM and FIRE under every rule may send Go. The release
        time recorded is the verified Go's, the failed attempt's kept beside it (``failed_go_at``)."""
        ops = self.state.ops(name)
        typed_text("the typed capsule name", typed_name)
        with ops.lock:
            record, now = ops.machine.record(), self.state.clock()
            why, detail = self._finish_refusal(name, ops, record, now)
            if why:
                self.state.store.append_audit(
                    self.state.operator, name, "go", "refused", {"reason": why, **detail}, when=now
                )
                raise RefusedError(f"{name}: finish refused: {why}")
            self.state.store.append_audit(self.state.operator, name, "go", "finishing", detail, when=now)
            record = ops.machine.go(ops.machine.confirm(typed_name))
            ops.arming.finished()
            ops.link.close()
            self.state.command_done(name, "fire", record.note or "Go sent")
        return self.state.emit([self.state.release_record(name, record)])

    def _finish_refusal(
        self, name: str, ops: CapsuleOps, record: ReleaseRecord, now: datetime
    ) -> tuple[str | None, dict[str, object]]:
        """Why ``finish_go`` is refused now (None: it may go ahead), and what to audit either way."""
        if record.state is not ReleaseState.GO_SENT:
            return (
                f"only an unverified Go (go-sent-unverified) is finished; {name} is {record.state.value}",
                {},
            )
        window = ops.arming.windows.latest(name)
        failed = record.go_at
        detail: dict[str, object] = {"state": record.state.value, "failed_go_at": iso_utc(failed) if failed else None,
                                     "window": window.id if window else None}  # fmt: skip
        fresh = (
            "a fresh ARM and FIRE under every rule is needed, once a poll finds the Pi still up "
            f"{FINISH_GO_S:.0f} s after the attempt (the console's, or drs capsule arm {name})"
        )
        if window is None or window.state != FIRING:
            return f"no ARM window is firing for this Go; {fresh}", detail
        if window.holder != ops.arming.holder:
            return (
                f"only the holder of ARM window #{window.id} ({window.who()}) may finish its Go; {fresh}",
                detail,
            )
        age = (now - failed).total_seconds() if failed else FINISH_GO_S + 1
        if age > FINISH_GO_S:
            return (
                f"the failed attempt was {age:.0f} s ago (limit {FINISH_GO_S:.0f} s); {fresh}, or, if the "
                f"capsule fell, record it: drs capsule released {name} --evidence …"
            ), detail
        if self.state.config.console.require_second_operator:
            spent = self.state.approvals.spent_for_window(name, window.id)
            if spent is None:
                return f"no approval was spent on ARM window #{window.id}; {fresh}", detail
            detail["approval"] = spent.id
            if spent.expired(now):
                return f"its approval #{spent.id} expired at {spent.expires_utc:%H:%M:%S}Z; {fresh}", detail
        return None, detail

    def take_over(
        self,
        name: str,
        seen: AuthorityStatus,
        typed_name: str,
        reason: str,
        second: SecondOperator = SecondOperator(),
    ) -> AuthorityStatus:
        """Take over the capsule's release authority from what the operator was shown (``seen``).

        Hazardous like FIRE: with ``require_second_operator`` only another login's approval, bound to
        this take-over and the capsule's state, lets it go ahead (a typed name or a waiver is refused);
        without the rule an approval, a crew member's name or a waiver may still be given and is audited.
        """
        ops = self.state.ops(name)
        ops.machine.check_take_over(reason, seen, typed_name)
        command, state = f"release-authority take-over: {reason.strip()}", self.release_state(name).value
        people: dict[str, str] = {}
        try:
            if second.await_approval:
                approval = approved(
                    self.state.approvals, name, "authority", command, self.state.operator, self.state.login,
                    second.on_pending or (lambda request: None), command=command, capsule_state=state,
                    brief=ApprovalBrief(command, notes=(f"from {seen.holder or 'nobody'} ({seen.state.value})",)),
                )  # fmt: skip
                people = self.state.approvals.use(
                    approval, name, "authority", self.state.login, command, self.release_state(name).value
                )
            else:
                people = check_second_operator(
                    self.state.operator, second.name, second.waiver, self.state.config.console.require_second_operator,
                    self.state.config.console.crew,
                )  # fmt: skip
        except RefusedError as exc:
            detail = {"reason": reason.strip(), "refusal": str(exc)}
            self.state.store.append_audit(
                self.state.operator, name, "authority-take-over", "refused", detail, when=self.state.clock()
            )
            raise RefusedError(f"{name}: take-over refused: {exc}") from None
        if people:
            self.state.store.append_audit(
                self.state.operator, name, "authority-take-over", "approved", people, when=self.state.clock()
            )
        with ops.lock:
            try:
                return ops.machine.take_over(seen, typed_name, reason)
            finally:
                ops.link.close()

    def release_authority(self, name: str, reason: str) -> AuthorityStatus:
        """Give up this console's release authority on the Pi (end of a shift); what was given up."""
        ops = self.state.ops(name)
        with ops.lock:
            try:
                return ops.machine.release_authority(reason)
            finally:
                ops.link.close()

    def record_released(self, name: str, typed_name: str, evidence: str) -> ReleaseRecord:
        """Settle an unverified Go as released on the operator's evidence; the checklist's Go step too."""
        ops = self.state.ops(name)
        with ops.lock:
            record = ops.machine.record_released(typed_name, evidence)
            self.state.command_done(name, "fire", record.note or "released")
        self.state.approvals.void_capsule(name, "capsule state changed: released", self.state.operator)
        return record

    def release_state(self, name: str) -> ReleaseState:
        return self.state.ops(name).machine.record().state

    def authority(self, name: str) -> AuthorityStatus:
        """Who holds the capsule's release authority on its Pi (read-only), for the release screen to show."""
        ops = self.state.ops(name)
        with ops.lock:
            return ops.machine.authority()

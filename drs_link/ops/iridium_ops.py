"""One operator's Iridium: the gateway check, the capsules' reports as telemetry, and the MTs (plan, send,
resolve) through the landed gate and the two-person rule (``authorize``).
"""

from __future__ import annotations

import threading
from dataclasses import dataclass, field
from datetime import datetime

from drs_link.errors import ConfigError, RefusedError
from drs_link.iridium import (
    Command,
    CommandLifecycle,
    LandedEvidence,
    LandedVerdicts,
    MtMessage,
    ParachutePlan,
    ReportStore,
    RockblockGateway,
    StoredReport,
    interval_track,
    landed_evidence,
    plan_parachute,
)
from drs_link.ops.approval import approved
from drs_link.ops.authorize import approval_command, authorize_mt, hazard_of
from drs_link.ops.brief import ApprovalBrief
from drs_link.ops.checklist import Step
from drs_link.ops.ops_state import OpsState, SecondOperator
from drs_link.ops.procedure import complete_mt_steps
from drs_link.ops.telemetry import GatewaySample, ReportSample, TelemetryRecord
from drs_link.ops.typed_text import typed_text
from drs_link.store import iso_utc

GNSS_UERE_M = 5.0
"""Metres of position error per unit of HDOP (a typical user range error), for the fix's uncertainty."""


@dataclass(frozen=True)
class SentMt:
    """What one send did: the command as queued (or failed), the checklist steps it completed, and what
    the gate authorised it with (the evidence, the second operator or approval; empty for a routine one)."""

    command: Command
    steps: list[Step]
    authorised: dict[str, object]


def report_position(stored: StoredReport) -> tuple[float, float, float, str] | None:
    """(lat, lon, uncertainty m, source): the GNSS fix, else the Iridium network's estimate and CEP."""
    report = stored.report
    if report is not None and report.fix is not None:
        return report.fix.lat, report.fix.lon, report.fix.hdop * GNSS_UERE_M, "gnss"
    coarse = stored.iridium_position()
    return (*coarse, "iridium") if coarse is not None else None


def report_record(capsule: str, stored: StoredReport, interval_min: int, landed: bool) -> TelemetryRecord:
    """One Iridium report as telemetry (position from the fix, else the Iridium estimate).

    ``interval_min`` is the longest time the next report may take (``IntervalTrack.overdue_after``):
    the report's staleness period, so a report is not called stale before the next one is due.
    ``landed`` is ``drs_link.iridium.landed``'s verdict on the reports up to this one: the rule the
    PARACHUTE gate and the checklist's steps use, so the fleet never says landed when they do not.
    """
    report = stored.report
    fix = report.fix if report else None
    position = report_position(stored)
    sample = ReportSample(
        momsn=stored.delivery.momsn,
        has_fix=fix is not None,
        lat=position[0] if position else None,
        lon=position[1] if position else None,
        uncertainty_m=position[2] if position else None,
        position_source=position[3] if position else None,
        alt_m=fix.alt_m if fix else None,
        speed_ms=fix.speed_ms if fix else None,
        sats=fix.sats if fix else None,
        vbat=report.vbat if report else None,
        iteration=report.iteration if report else None,
        interval_min=interval_min,
        landed=landed,
    )
    return TelemetryRecord(stored.time, capsule, sample)


@dataclass
class _ReportsRead:
    """One capsule's reports as the console has read them (time order), each with its landed verdict.

    Why kept: a report poll re-read and re-parsed the whole flight whenever one report was new; now it
    parses the new ones and feeds them to the landing rule, unless one sorts before a report already
    read (an old attachment imported late), when it reads the history again.
    """

    stored: list[StoredReport] = field(default_factory=list)
    landed: list[bool] = field(default_factory=list)
    verdicts: LandedVerdicts = field(default_factory=LandedVerdicts)
    newest_id: int = 0

    def add(self, report: StoredReport) -> None:
        self.stored.append(report)
        self.landed.append(self.verdicts.add(report))
        self.newest_id = max(self.newest_id, report.id)

    def follows(self, report: StoredReport) -> bool:
        """Whether ``report`` sorts after every report read so far, in the store's order (time, then id)."""
        last = self.stored[-1]
        return (iso_utc(last.time), last.id) < (iso_utc(report.time), report.id)


class IridiumOps:
    """Iridium for one operator: the gateway's check, the capsules' reports and the MTs (plan, send, resolve)."""

    def __init__(self, state: OpsState) -> None:
        self.state = state
        self.reports = ReportStore(state.store)
        self.lifecycle = CommandLifecycle(state.store, state.operator, state.clock)
        self._reports_read: dict[str, _ReportsRead] = {}
        self._reports_lock = threading.Lock()
        """Report polls may overlap on worker threads; each must see what the one before it read."""

    def gateway_check(self) -> list[TelemetryRecord]:
        """Whether commands could be sent: the gateway's address and credentials are configured."""
        try:
            RockblockGateway.from_config(self.state.config.rockblock, self.state.environ)
            sample = GatewaySample(True, f"user {self.state.config.rockblock.username}")
        except ConfigError as exc:
            sample = GatewaySample(False, str(exc))
        return self.state.emit([TelemetryRecord(self.state.clock(), None, sample)])

    def new_reports(self, name: str) -> list[TelemetryRecord]:
        """Iridium reports of one capsule stored since the last call (webhook or importer wrote them)."""
        imei = self.state.ops(name).config.imei
        if not imei:
            return []
        with self._reports_lock:
            read = self._reports_read.get(name)
            seen = read.newest_id if read is not None else 0
            fresh = self.reports.for_imei(imei, after_id=seen)
            if not fresh:
                return []
            if read is None or not read.follows(fresh[0]):
                history = fresh if read is None else self.reports.for_imei(imei)
                read = self._reports_read[name] = _ReportsRead()
                fresh = history
            for report in fresh:
                read.add(report)
            self.lifecycle.observe_store(self.reports, imei)
            track = interval_track(read.stored, self.lifecycle.for_imei(imei))
            records = [
                report_record(name, r, track.overdue_after(r), landed)
                for r, landed in zip(read.stored, read.landed, strict=True) if r.id > seen
            ]  # fmt: skip
        return self.state.emit(records)

    def stored_reports(self, name: str) -> list[StoredReport]:
        imei = self.state.ops(name).config.imei
        return self.reports.for_imei(imei) if imei else []

    def reports_of(self, name: str) -> list[StoredReport]:
        """The capsule's Iridium reports in time order; refused when it has no IMEI to key them by."""
        imei = self.state.ops(name).config.imei
        if not imei:
            raise ConfigError(
                f"capsule {name}: imei is not configured; reports and commands are keyed by IMEI"
            )
        return self.reports.for_imei(imei)

    def mt_status(self, name: str) -> list[Command]:
        """The capsule's MTs after the reports moved them on (delivered, applied), oldest first."""
        reports = self.reports_of(name)
        imei = self.state.ops(name).config.imei or ""
        self.lifecycle.observe(reports, imei)
        return self.lifecycle.for_imei(imei)

    def plan_parachute(
        self, name: str, requested: tuple[int, int] | None, accept_midnight: bool = False
    ) -> ParachutePlan:
        """When a PARACHUTE can fire (``requested`` HH:MM, or the next cycle): the reports, the MTs known
        (read-only: ``mt_status`` moves them on first) and the queue-before deadline ``send_mt`` re-checks."""
        return plan_parachute(
            self.reports_of(name), self.state.clock(), self.commands(name), requested, accept_midnight
        )

    def landed(self, name: str) -> LandedEvidence:
        """The landed evidence the PARACHUTE gate will judge, for the operator to read before sending."""
        return landed_evidence(self.reports_of(name))

    def commands(self, name: str) -> list[Command]:
        imei = self.state.ops(name).config.imei
        return self.lifecycle.for_imei(imei) if imei else []

    def unresolved_like(self, name: str, message: MtMessage) -> list[Command]:
        """This capsule's commands with the same text whose delivery is still unknown: a retry may queue
        the MT twice (the gateway may hold the first), which the operator is told before sending."""
        return self.lifecycle.unresolved_like(self.state.ops(name).config.imei or "", message.text)

    def send_mt(
        self,
        name: str,
        message: MtMessage,
        confirmation: str,
        second: SecondOperator = SecondOperator(),
        *,
        override_landed: str | None = None,
        queue_by: datetime | None = None,
        flush: bool = False,
    ) -> SentMt:
        """Gate, request and queue one MT, the one path of ``drs mt send`` and the console.

        A hazardous command (``MtCommand.hazard``: PARACHUTE) passes ``authorize_mt`` first, the landed
        gate and the two-person rule, whoever calls; with ``second.await_approval`` another login's
        approval is asked for, bound to this exact text and the queue-before deadline. ``confirmation``
        must be the capsule's name (checked by the lifecycle). A queued MT completes its checklist steps
        here.
        """
        capsule = self.state.ops(name).config
        reports = self.stored_reports(name)
        typed_text("the override reason", override_landed or "")
        approval = None
        if second.await_approval:
            if hazard_of(message) is None:
                raise RefusedError(f"{name}: {message.text} needs no second operator: nothing to approve")
            bound = approval_command(message, override_landed)
            evidence = landed_evidence(reports)
            override = (override_landed or "").strip() if not evidence.on_ground else None
            approval = approved(
                self.state.approvals, name, "parachute", bound, self.state.operator, self.state.login,
                second.on_pending or (lambda request: None), command=bound, deadline=queue_by,
                brief=ApprovalBrief(message.text, landed=evidence.summary, override=override or None),
            )  # fmt: skip
        authorised = authorize_mt(
            self.state.store, name, self.state.operator, message, reports, second_operator=second.name,
            single_operator_waiver=second.waiver,
            require_second_operator=self.state.config.console.require_second_operator,
            crew=self.state.config.console.crew,
            override_landed=override_landed, queue_by=queue_by, now=self.state.clock(), approval=approval,
            login=self.state.login if approval is not None else None, spend=False,
        )  # fmt: skip
        gateway = RockblockGateway.from_config(
            self.state.config.rockblock, self.state.environ
        )  # before it is spent
        if approval is None:
            command = self.lifecycle.request(capsule, message, flush=flush)
        else:
            request = self.state.approvals.get(approval)
            try:
                command = self.lifecycle.request(
                    capsule,
                    message,
                    flush=flush,
                    also=lambda conn: self.state.approvals.spend_in(conn, request),
                )
            except RefusedError as exc:
                detail = {"text": message.text, "reason": str(exc)}
                self.state.store.append_audit(
                    self.state.operator, name, "mt.parachute", "refused", detail, when=self.state.clock()
                )
                raise RefusedError(f"{name}: PARACHUTE refused: {exc}") from None
            self.state.approvals.spent(request)
        command = self.lifecycle.send(command.id, confirmation, gateway)
        steps = complete_mt_steps(
            self.state.store,
            self.state.checklists,
            self.state.operator,
            command,
            self.stored_reports(name),
            self.state.clock,
        )
        return SentMt(command, steps, authorised)

    def resolve_mt(self, name: str, command_id: int, gateway_id: int | None, note: str = "") -> list[Command]:
        """Record what the RockBLOCK portal shows for an MT whose delivery is unknown: queued as
        ``gateway_id``, or (None) never sent; then the reports move it on. The resolved command first,
        then every other that changed; audited by the lifecycle."""
        typed_text("the note", note)
        reports = self.stored_reports(name)
        if gateway_id is None:
            command = self.lifecycle.resolve_not_sent(command_id, name, note)
        else:
            command = self.lifecycle.resolve_queued(command_id, name, gateway_id, reports, note)
        return [command, *self.lifecycle.observe(reports, self.state.ops(name).config.imei or "")]

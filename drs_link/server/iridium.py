"""The Iridium service: ``drs mt send`` composed, gated and queued by the server, which alone holds the
RockBLOCK credentials. A thin service over each desk's ``IridiumOps.plan_parachute``/``send_mt``: the landed gate
and the two-person rule stay in ``drs_link.ops.authorize``."""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime

from drs_link.errors import ConfigError, RefusedError
from drs_link.iridium import track_csv
from drs_link.ops import (
    CATALOGUE,
    FLUSH_WARNING,
    LISTED,
    PARACHUTE,
    QUEUED,
    RETRY_WARNING,
    Approval,
    Command,
    IridiumOps,
    LandedEvidence,
    MtComposer,
    MtMessage,
    SecondOperator,
    assess,
    hazard_of,
    iso_utc,
    parse_hhmm,
)
from drs_link.server.desk_views import ParachuteView
from drs_link.server.desks import Desks
from drs_link.server.peers import Mode, Peer
from drs_link.server.protocol import (
    Done,
    FindingView,
    HealthView,
    MtSendRequest,
    MtStatus,
    MtView,
    ResolveMtRequest,
    TrackCsv,
    TrackRequest,
)
from drs_link.server.release import two_person_refusal
from predictor.errors import UsageError

Say = Callable[[str], None]
IMEI_DIGITS = 15


def compose(
    iridium: IridiumOps, name: str, request: MtSendRequest, say: Say
) -> tuple[MtMessage, datetime | None]:
    """The message from the options as typed, and the PARACHUTE plan's queue-before deadline."""
    known = {command.dest: command for command in LISTED}
    unknown = sorted(set(request.options) - set(known))
    if unknown:
        raise UsageError(f"mt send: no command option {unknown[0]!r} (known: {', '.join(sorted(known))})")
    composer = MtComposer(CATALOGUE)
    queue_by = None
    for command in sorted(LISTED, key=lambda c: c is PARACHUTE):  # plan only once the rest is accepted
        given = request.options.get(command.dest)
        if given is None:
            continue
        if command is not PARACHUTE:
            composer.add(command.name, command.from_option(given))
            continue
        requested = None if given == "next" else parse_hhmm(str(given))
        iridium.mt_status(name)  # the reports move the MTs on first, as the console's report poll does
        plan = iridium.plan_parachute(name, requested, request.accept_midnight)
        say(f"window: {plan.window_text()}")
        for warning in plan.warnings:
            say(f"warning: {warning}")
        composer.add(command.name, (plan.hour, plan.minute))
        queue_by = plan.queue_by
    return composer.build(), queue_by


def mt_view(command: Command) -> MtView:
    def iso(moment: datetime | None) -> str | None:
        return iso_utc(moment) if moment else None

    return MtView(
        command.id, command.text, command.state, command.detail, command.operator, command.flush,
        iso_utc(command.requested_utc), iso_utc(command.updated_utc), iso(command.queued_utc), command.mt_id,
        command.delivered_report_id, dict(command.effects),
    )  # fmt: skip


class IridiumService:
    def __init__(self, desks: Desks, mode: Mode) -> None:
        self.desks = desks
        self.mode = mode

    def send_mt(
        self, peer: Peer, name: str, request: MtSendRequest, say: Say, on_pending: Callable[[Approval], None]
    ) -> Done:
        iridium = self.desks.desk(peer).iridium
        capsule = iridium.state.config.capsule(name)
        message, queue_by = compose(iridium, name, request, say)
        say(f"text: {message.text}")
        say(f"hex:  {message.hex} ({len(message.payload)} bytes)")
        if request.flush:
            say(f"warning: {FLUSH_WARNING}")
        hazardous = hazard_of(message) is not None
        if hazardous:
            say(f"landed: {iridium.landed(name).summary}")
        if request.dry_run:
            return Done(("dry run: nothing sent",))
        if request.confirm is None:
            raise RefusedError(f"a real send needs --confirm {capsule.name} (or --dry-run to only look)")
        if not peer.operator:
            raise ConfigError("operator.name: set [operator] name; every command is audited with it")
        second = request.second
        if second.await_approval and not hazardous:
            raise UsageError("--await-approval is for PARACHUTE, the command the two-person rule covers")
        two_person_refusal(self.mode, peer, second.await_approval)
        for older in iridium.unresolved_like(capsule.name, message):
            say(f"warning: MT {older.id} {older.text} is delivery_unknown: {RETRY_WARNING}")
        sent = iridium.send_mt(
            capsule.name, message, request.confirm,
            SecondOperator(second.name, second.waiver, second.await_approval, on_pending),
            override_landed=request.override_landed, queue_by=queue_by, flush=request.flush,
        )  # fmt: skip
        lines = []
        if "approval" in sent.authorised:
            lines.append(
                f"approval #{sent.authorised['approval']}: approved by {sent.authorised['approved_by']}"
            )
        lines.append(f"MT {sent.command.id}: {sent.command.state}: {sent.command.detail}")
        lines.extend(f"checklist: done: {step.text}" for step in sent.steps)
        return Done(tuple(lines), sent.command.state == QUEUED)

    def mt_status(self, peer: Peer, name: str) -> MtStatus:
        """The capsule's MTs after the reports moved them on (delivered, applied), oldest first."""
        iridium = self.desks.desk(peer).iridium
        capsule = iridium.state.config.capsule(name)
        return MtStatus(capsule.name, capsule.imei, tuple(mt_view(c) for c in iridium.mt_status(name)))

    def resolve_mt(self, peer: Peer, name: str, request: ResolveMtRequest) -> tuple[MtView, ...]:
        """``IridiumOps.resolve_mt``: the resolved MT first, then every other the reports moved on."""
        iridium = self.desks.desk(peer).iridium
        if not peer.operator:
            raise ConfigError("operator.name: set [operator] name; every resolution is audited with it")
        iridium.reports_of(name)  # an unknown capsule or one without an IMEI is refused first
        resolved = iridium.resolve_mt(name, request.command_id, request.gateway_id, request.note)
        return tuple(mt_view(c) for c in resolved)

    def health(self, peer: Peer, name: str) -> HealthView:
        """``assess`` of the capsule's stored reports and MTs: battery, resets, gaps and spacing."""
        iridium = self.desks.desk(peer).iridium
        capsule = iridium.state.config.capsule(name)
        health = assess(iridium.reports_of(name), iridium.mt_status(name))
        findings = tuple(FindingView(f.kind, f.report_id, f.message) for f in health.findings)
        return HealthView(
            capsule.name, capsule.imei, health.reports, health.last_report, health.last_vbat, findings
        )

    def track(self, peer: Peer, request: TrackRequest) -> TrackCsv:
        """The stored fixes of a capsule, or of a modem by IMEI, as the canonical track CSV's text: the
        client writes it where its operator chose, so the file is the operator's (issue #29 item 6)."""
        if (request.capsule is None) == (request.imei is None):
            raise UsageError("give either a capsule NAME or --imei IMEI, not both or neither")
        iridium = self.desks.desk(peer).iridium
        if request.capsule is not None:
            reports, who = iridium.reports_of(request.capsule), request.capsule
        else:
            imei = request.imei or ""
            if not (imei.isascii() and imei.isdigit() and len(imei) == IMEI_DIGITS):
                raise UsageError(f"--imei {imei!r}: an IMEI is 15 digits")
            reports, who = iridium.reports.for_imei(imei), f"IMEI {imei}"
        text, fixes, without_fix, rejected = track_csv(reports, who)
        return TrackCsv(who, text, fixes, without_fix, rejected)

    def plan_parachute(self, peer: Peer, name: str, requested: tuple[int, int] | None) -> ParachuteView:
        """``IridiumOps.plan_parachute`` and the landed evidence the gate will judge, for the operator to
        read before typing the name; the send plans and judges again (``send_mt``)."""
        iridium = self.desks.desk(peer).iridium
        return ParachuteView(iridium.plan_parachute(name, requested), iridium.landed(name))

    def landed(self, peer: Peer, name: str) -> LandedEvidence:
        """The landed evidence as it is now (a dialog shows it again when a report changed it)."""
        return self.desks.desk(peer).iridium.landed(name)

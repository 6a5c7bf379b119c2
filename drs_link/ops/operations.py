"""The console's engine without a screen: polls capsules, runs release steps, reads Iridium reports.

Every method blocks (SSH, SQLite, HTTP) and is meant to be called from a worker thread; results
come back as telemetry records that the screen folds into its fleet state on its own thread. The
release rules themselves live in ``arming``/``gonogo``/``capsule``; this module only wires one
set of them per configured capsule, so the CLI, tests and the Textual app share one path.
"""

from __future__ import annotations

import os
import pwd
import socket
import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

from shapely import Polygon

from drs_link.config import CapsuleConfig, Config
from drs_link.errors import ConfigError, LinkError, RefusedError
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
from drs_link.link import (
    CapsuleLink,
    HostKeyError,
    Syncer,
    SyncReport,
    SyncStatus,
    enrol_host_key,
    fingerprint,
    known_hosts_name,
    read_storage,
    scan_host_key,
)
from drs_link.link.backends import AuthorityStatus, build_backend
from drs_link.ops.approval import Approval, ApprovalBook, Login, approved, current_login, window_command
from drs_link.ops.arm_window import FIRING
from drs_link.ops.arming import ArmingController, ArmStatus, check_second_operator
from drs_link.ops.authorize import approval_command, authorize_mt, hazard_of
from drs_link.ops.brief import ApprovalBrief, go_brief
from drs_link.ops.capsule import ReleaseRecord, ReleaseState, ReleaseStateMachine, record_as_dict
from drs_link.ops.checklist import PROCEDURE_DIR, Step, complete_command, load_checklists, start_new_flight
from drs_link.ops.fleet import CapsuleTelemetry, FleetState
from drs_link.ops.gonogo import ExclusionZone, GoNoGoReport, Waiver, WaiverBook, evaluate
from drs_link.ops.origin import ReleaseOrigin, release_origin
from drs_link.ops.procedure import complete_mt_steps
from drs_link.ops.telemetry import (
    GatewaySample,
    GnssSample,
    LinkSample,
    ReleaseSample,
    ReportSample,
    StorageSample,
    SyncSample,
    TelemetryRecord,
    TelemetryRecorder,
)
from drs_link.ops.typed_text import shown, typed_text
from drs_link.store import Store, iso_utc, utc_now
from predictor.prediction import ZoneFileError, load_zones

if TYPE_CHECKING:
    import paramiko

Predict = Callable[[str, ReleaseOrigin], list[TelemetryRecord]]
"""A landing prediction "release now" from an origin, as telemetry (the console's ``PredictionService``)."""
SyncProgress = Callable[[str, int, int], None]
"""Told (file, bytes done, bytes in it) while a sync uploads, for a progress bar."""
OnPending = Callable[[Approval], None]
"""Told which approval request waits, so the operator can have it approved."""


@dataclass(frozen=True)
class SecondOperator:
    """How the two-person rule is met for one hazardous action, as the operator gave it: a typed name,
    a logged waiver, or (``await_approval``) another login's approval, asked for and waited on here."""

    name: str | None = None
    waiver: str | None = None
    await_approval: bool = False
    on_pending: OnPending | None = None


def cli_holder() -> str:
    """Who holds an ARM window opened by ``drs capsule arm``: the OS account on this host, so that the
    ``drs capsule go`` that follows (another process) may FIRE in it, and no console or other account may."""
    return f"{pwd.getpwuid(os.geteuid()).pw_name}@{socket.gethostname()} drs"


@dataclass(frozen=True)
class HostKeyOffer:
    """The host key a capsule's Pi offers, for the operator to compare with the one read on the Pi."""

    address: str
    """As known_hosts names it (``[host]:port``)."""
    key_type: str
    fingerprint: str
    key: paramiko.PKey
    """The key itself (paramiko's), saved as it was offered once the operator confirms it."""


@dataclass(frozen=True)
class SentMt:
    """What one send did: the command as queued (or failed), the checklist steps it completed, and what
    the gate authorised it with (the evidence, the second operator or approval; empty for a routine one)."""

    command: Command
    steps: list[Step]
    authorised: dict[str, object]


FINISH_GO_S = 60.0
"""How long after a Go that was never verified its ARM window's holder may still finish it without a
fresh ARM: long enough to see the link drop and send it again, short enough that the go/no-go it was
judged on still stands (issue #29)."""

NO_SYNC_SOURCE = (
    "sync_source is not configured (set it in the capsule's [[capsule]] table: the payload data to upload)"
)
"""What go/no-go's sync item and ``drs sync`` say when the capsule has no directory to upload."""
GNSS_UERE_M = 5.0
"""Metres of position error per unit of HDOP (a typical user range error), for the fix's uncertainty."""


def load_exclusion_zones(path: Path | None) -> tuple[ExclusionZone, ...]:
    """The zones go/no-go checks, read by the planner's own loader (``predictor.prediction.zones.load_zones``).

    One reader, so go/no-go and the release-window sweep accept and refuse the same files and see the
    same polygons (MultiPolygon parts, holes, rings across the antimeridian); each part keeps its
    feature's name.
    """
    if path is None:
        return ()
    try:
        features = load_zones(path)
    except ZoneFileError as exc:
        raise ConfigError(f"console.exclusion_zones_file: {exc}") from None
    zones = []
    for feature in features:
        for part in getattr(feature.geometry, "geoms", (feature.geometry,)):
            if isinstance(part, Polygon):
                holes = tuple(_lon_lat(ring.coords) for ring in part.interiors)
                zones.append(ExclusionZone(feature.name, _lon_lat(part.exterior.coords), holes))
    return tuple(zones)


def _lon_lat(coords: Iterable[tuple[float, ...]]) -> tuple[tuple[float, float], ...]:
    """A ring's (lon, lat) points: go/no-go tests where a landing falls on the map, not its height."""
    return tuple((c[0], c[1]) for c in coords)


@dataclass
class CapsuleOps:
    config: CapsuleConfig
    link: CapsuleLink
    machine: ReleaseStateMachine
    arming: ArmingController
    waivers: WaiverBook
    syncer: Syncer
    lock: threading.Lock


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


class Operations:
    """One console's live connection to its capsules and gateway."""

    def __init__(
        self,
        config: Config,
        store: Store,
        clock: Callable[[], datetime] = utc_now,
        recorder: TelemetryRecorder | None = None,
        environ: dict[str, str] | None = None,
        sleep: Callable[[float], None] | None = None,
        holder: str | None = None,
        login: Login | None = None,
    ) -> None:
        """``holder``: who may FIRE in an ARM window this process opens (default: this process;
        ``drs`` uses account@host so that ``drs capsule arm`` and ``drs capsule go`` are one holder)."""
        self.config = config
        self.store = store
        self.clock = clock
        self.recorder = recorder
        self.environ = environ
        self.operator = config.operator.name or "unknown"
        self._login = login
        self.zones = load_exclusion_zones(config.console.exclusion_zones_file)
        self.checklists = load_checklists(PROCEDURE_DIR)
        self.reports = ReportStore(store)
        self.lifecycle = CommandLifecycle(store, self.operator, clock)
        self.approvals = ApprovalBook(store, clock)
        self._reports_read: dict[str, _ReportsRead] = {}
        self._reports_lock = threading.Lock()
        """Report polls may overlap on worker threads; each must see what the one before it read."""
        self.capsules: dict[str, CapsuleOps] = {}
        for capsule in config.capsules:
            link = CapsuleLink(capsule)
            backend = build_backend(capsule, link)
            machine = ReleaseStateMachine(store, capsule, backend, self.operator, clock=clock, sleep=sleep)
            arming = ArmingController(
                store, machine, self.operator, clock, config.console.arm_window_s,
                config.console.require_second_operator, holder, config.console.crew,
            )  # fmt: skip
            self.capsules[capsule.name] = CapsuleOps(
                capsule, link, machine, arming, WaiverBook(store, capsule.name, clock),
                Syncer(store, link, capsule.name, capsule.storage_mount, capsule.raid_device), threading.Lock(),
            )  # fmt: skip

    @classmethod
    def open(cls, config: Config, holder: str | None = None) -> Operations:
        """The engine of one ``drs`` command: the configured store, nothing polled yet."""
        return cls(config, Store.open(config.store_path), holder=holder)

    @property
    def login(self) -> Login:
        """Who is at this keyboard (``approval.current_login``), asked for only when an approval needs it."""
        if self._login is None:
            self._login = current_login()
        return self._login

    def _emit(self, records: list[TelemetryRecord]) -> list[TelemetryRecord]:
        if self.recorder is not None:
            for record in records:
                self.recorder.append(record)
        return records

    def ops(self, name: str) -> CapsuleOps:
        if name not in self.capsules:
            raise ConfigError(f"no capsule named {name!r} in the configuration")
        return self.capsules[name]

    def _release_record(self, name: str, record: ReleaseRecord) -> TelemetryRecord:
        sample = ReleaseSample(
            record.state.value,
            record.nmea_seen_at is not None,
            None if record.note is None else shown(record.note),
            record.released_at,
        )
        return TelemetryRecord(self.clock(), name, sample)

    def poll(self, name: str) -> list[TelemetryRecord]:
        """Link, release state, microcontroller/GNSS, storage and sync of one capsule, as records."""
        ops = self.ops(name)
        with ops.lock:
            record = ops.machine.record()
            if record.state is ReleaseState.GO_SENT:
                record = ops.machine.recheck_unverified_go(FINISH_GO_S)
                if record.state is ReleaseState.POWERED:
                    ops.arming.go_not_taken(record.note or "Go never taken")
            out = [self._release_record(name, record)]
            if record.state in (ReleaseState.RELEASED, ReleaseState.GO_SENT):
                out.append(TelemetryRecord(self.clock(), name, LinkSample(False, "released")))
                return self._emit(out)
            try:
                ops.link.ensure_connected()
                up = ops.link.heartbeat()
            except HostKeyError as exc:
                out.append(TelemetryRecord(self.clock(), name, LinkSample(False, str(exc))))
                return self._emit(out)
            except LinkError as exc:
                up = False
                note = str(exc)
            else:
                note = "heartbeat answered" if up else "heartbeat failed"
            out.append(TelemetryRecord(self.clock(), name, LinkSample(up, note)))
            if not up:
                ops.link.close()
                return self._emit(out)
            try:
                if record.state is ReleaseState.POWERED:
                    mcu = ops.machine.check_microcontroller()
                    gnss = mcu.gnss
                    out.append(self._release_record(name, ops.machine.record()))
                    out.append(TelemetryRecord(self.clock(), name, GnssSample(
                        has_fix=gnss.has_fix, quality=gnss.fix_quality_name, sats=gnss.satellites,
                        hdop=gnss.hdop, lat=gnss.latitude, lon=gnss.longitude, alt_m=gnss.altitude_m,
                        fix_age_s=gnss.age_s, diagnosis=mcu.diagnosis, date_problem=gnss.date_problem,
                    )))  # fmt: skip
                storage = read_storage(ops.link, ops.config.storage_mount, ops.config.raid_device)
                usage = storage.usage
                out.append(TelemetryRecord(self.clock(), name, StorageSample(
                    used_bytes=usage.used_bytes if usage else None,
                    total_bytes=usage.total_bytes if usage else None,
                    raid=storage.raid.state if storage.raid else "missing",
                )))  # fmt: skip
                if ops.config.sync_source is not None:
                    status = ops.syncer.status(ops.config.sync_source)
                    total = status.bytes_pending + sum(
                        p.stat().st_size for p in ops.config.sync_source.rglob("*")
                        if p.is_file() and p.relative_to(ops.config.sync_source).as_posix() in status.up_to_date
                    )  # fmt: skip
                    fraction = 1.0 if total == 0 else 1.0 - status.bytes_pending / total
                    out.append(TelemetryRecord(self.clock(), name, SyncSample(
                        fraction=fraction, bytes_pending=status.bytes_pending,
                        files_pending=len(status.missing) + len(status.changed),
                    )))  # fmt: skip
                else:
                    out.append(TelemetryRecord(self.clock(), name, SyncSample(unknown=NO_SYNC_SOURCE)))
            except LinkError as exc:
                out.append(TelemetryRecord(self.clock(), name, LinkSample(False, str(exc))))
            return self._emit(out)

    def _sync_source(self, name: str, source: Path | None) -> Path:
        chosen = source if source is not None else self.ops(name).config.sync_source
        if chosen is None:
            raise ConfigError(f"capsule {name}: {NO_SYNC_SOURCE}, and no directory was given")
        return chosen

    def sync(
        self, name: str, source: Path | None = None, on_progress: SyncProgress | None = None
    ) -> SyncReport:
        """Upload ``source`` (default: the capsule's ``sync_source``) to its storage, each file verified by
        sha256 on the Pi; every verified file, the outcome and a failure are audited, whichever face asked."""
        ops = self.ops(name)
        chosen = self._sync_source(name, source)

        def verified(relative: str) -> None:
            self.store.append_audit(
                self.operator, name, "sync-file", "verified", {"path": relative}, when=self.clock()
            )

        with ops.lock:
            try:
                report = ops.syncer.sync(chosen, on_progress=on_progress, on_verified=verified)
            except LinkError as exc:
                self.store.append_audit(
                    self.operator, name, "sync", "failed", {"error": str(exc)}, when=self.clock()
                )
                raise
        detail = {"uploaded": len(report.uploaded), "bytes": report.bytes_sent}
        self.store.append_audit(self.operator, name, "sync", "ok", detail, when=self.clock())
        return report

    def sync_status(self, name: str, source: Path | None = None, with_hash: bool = False) -> SyncStatus:
        """What a sync of ``source`` would upload (missing or changed files), read-only."""
        ops = self.ops(name)
        chosen = self._sync_source(name, source)
        with ops.lock:
            return ops.syncer.status(chosen, with_hash=with_hash)

    def power_on(self, name: str, confirmed: bool = True) -> list[TelemetryRecord]:
        """Confirmed by the operator before this is called (the relay cannot be switched off by software);
        ``confirmed`` False is refused (and audited) by the state machine. Voids the capsule's approvals."""
        ops = self.ops(name)
        with ops.lock:
            record = ops.machine.power_on(confirmed=confirmed)
            ops.arming.disarm("power-on")
            self.approvals.void_capsule(name, "capsule state changed: powered on", self.operator)
            self._command_done(name, "power-on", "relay latched")
        return self._emit([self._release_record(name, record)])

    def _command_done(self, name: str, command: str, result: str) -> None:
        """The checklist step a release command completes, by the rule ``drs capsule`` uses too."""
        complete_command(self.store, self.checklists, name, command, self.operator, result, {}, self.clock)

    def gonogo(self, name: str, telemetry: CapsuleTelemetry) -> GoNoGoReport:
        """The go/no-go poll of one capsule on what ``telemetry`` holds, with this process's waivers."""
        now = self.clock()
        return evaluate(name, telemetry.gonogo_inputs(now, self.zones), now, self.ops(name).waivers.waivers)

    def poll_gonogo(self, name: str, predict: Predict | None = None) -> GoNoGoReport:
        """The go/no-go poll for a process without a console's fleet (``drs capsule arm/go``): poll the
        capsule and the gateway now, predict "release now" from the fresh fix (when weather is given),
        and judge them by the same ``evaluate`` and the same items the console's release screen shows."""
        fleet = FleetState.for_capsules([name])
        for record in [*self.poll(name), *self.gateway_check()]:
            fleet.apply(record)
        origin = release_origin(fleet, name, self.clock())
        if predict is not None and origin is not None:
            for record in predict(name, origin):
                fleet.apply(record)
            # The capsule again, as it is now: a prediction can outlast a polled reading's freshness (a
            # first one compiling its kernels took 17 s on a loaded machine, and ARM was refused on link,
            # microcontroller and GNSS readings 20 s old). The prediction stays fresh for minutes.
            for record in self.poll(name):
                fleet.apply(record)
        return self.gonogo(name, fleet.capsules[name])

    def waive(self, name: str, item: str, reason: str) -> Waiver:
        """Waive one go/no-go item (GNSS fix or sync only), with this operator's name; audited."""
        return self.ops(name).waivers.grant(item, self.operator, reason)

    def arm(self, name: str, report: GoNoGoReport) -> ArmStatus:
        """Open the capsule's ARM window on a GO poll (one per capsule across consoles); audited. The poll
        and this process's waivers are kept with the window: a Go approval shows them to its approver."""
        ops = self.ops(name)
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
        ops = self.ops(name)
        approval = None
        if second.await_approval:
            window = ops.arming.window_for_approval(typed_name)
            summary = f"Go: release {name} in ARM window #{window.id}"
            approval = approved(
                self.approvals, name, "go", summary, self.operator,
                self.login, second.on_pending or (lambda request: None), command=window_command(window.id),
                window_id=window.id, deadline=window.until_utc, brief=go_brief(summary, window.report),
            )  # fmt: skip
        report = poll()  # before the lock: a poll of the capsule (drs capsule go) takes it itself
        with ops.lock:
            login = self.login if approval is not None else None
            record = ops.arming.fire(
                typed_name, report, second.name, second.waiver, approval, login, on_sending
            )
            ops.link.close()
            self._command_done(name, "fire", record.note or "Go sent")
        self.approvals.void_capsule(name, "capsule state changed: released", self.operator)
        return self._emit([
            self._release_record(name, record),
            TelemetryRecord(self.clock(), name, LinkSample(False, "released: the Pi shut down")),
        ])  # fmt: skip

    def waiting_approvals(self, name: str) -> list[Approval]:
        """This login's requests for ``name`` that still wait for another login (and can still be used)."""
        return self.approvals.open_requests(name, requested_by=self.login)

    def cancel_approvals(self, name: str) -> list[Approval]:
        """Withdraw this login's waiting requests for ``name``: the action waiting on them is refused."""
        return [self.approvals.cancel(r.id, self.operator, self.login) for r in self.waiting_approvals(name)]

    def finish_go(self, name: str, typed_name: str) -> list[TelemetryRecord]:
        """Finish a Go that left and was never verified (its link dropped before GoGoGo was confirmed):
        the state machine retries it. Not a new release decision, so no new ARM, and therefore narrow
        (issue #29): only the holder of the ARM window that authorised it, within ``FINISH_GO_S`` of the
        failed attempt, and (with ``require_second_operator``) while the approval it was fired with is still
        valid; otherwise refused, and only a fresh ARM and FIRE under every rule may send Go. The release
        time recorded is the verified Go's, the failed attempt's kept beside it (``failed_go_at``)."""
        ops = self.ops(name)
        typed_text("the typed capsule name", typed_name)
        with ops.lock:
            record, now = ops.machine.record(), self.clock()
            why, detail = self._finish_refusal(name, ops, record, now)
            if why:
                self.store.append_audit(
                    self.operator, name, "go", "refused", {"reason": why, **detail}, when=now
                )
                raise RefusedError(f"{name}: finish refused: {why}")
            self.store.append_audit(self.operator, name, "go", "finishing", detail, when=now)
            record = ops.machine.go(ops.machine.confirm(typed_name))
            ops.arming.finished()
            ops.link.close()
            self._command_done(name, "fire", record.note or "Go sent")
        return self._emit([self._release_record(name, record)])

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
        if self.config.console.require_second_operator:
            spent = self.approvals.spent_for_window(name, window.id)
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
        ops = self.ops(name)
        ops.machine.check_take_over(reason, seen, typed_name)
        command, state = f"release-authority take-over: {reason.strip()}", self.release_state(name).value
        people: dict[str, str] = {}
        try:
            if second.await_approval:
                approval = approved(
                    self.approvals, name, "authority", command, self.operator, self.login,
                    second.on_pending or (lambda request: None), command=command, capsule_state=state,
                    brief=ApprovalBrief(command, notes=(f"from {seen.holder or 'nobody'} ({seen.state.value})",)),
                )  # fmt: skip
                people = self.approvals.use(
                    approval, name, "authority", self.login, command, self.release_state(name).value
                )
            else:
                people = check_second_operator(
                    self.operator, second.name, second.waiver, self.config.console.require_second_operator,
                    self.config.console.crew,
                )  # fmt: skip
        except RefusedError as exc:
            detail = {"reason": reason.strip(), "refusal": str(exc)}
            self.store.append_audit(
                self.operator, name, "authority-take-over", "refused", detail, when=self.clock()
            )
            raise RefusedError(f"{name}: take-over refused: {exc}") from None
        if people:
            self.store.append_audit(
                self.operator, name, "authority-take-over", "approved", people, when=self.clock()
            )
        with ops.lock:
            try:
                return ops.machine.take_over(seen, typed_name, reason)
            finally:
                ops.link.close()

    def capsule_status(self, name: str) -> tuple[dict[str, object], bool]:
        """``drs capsule status``: the release record, storage, microcontroller and GNSS as one report
        (read-only), and whether the link was up. A refused host key is raised, never reported as down."""
        ops = self.ops(name)
        with ops.lock:
            record = ops.machine.record()
            report: dict[str, object] = {"release": record_as_dict(record)}
            if record.state is ReleaseState.RELEASED:
                report["link"] = {"up": False, "note": "released: the Pi shut itself down"}
                return report, False
            try:
                ops.link.connect()
                report["link"] = {"up": True}
                report["storage"] = read_storage(
                    ops.link, ops.config.storage_mount, ops.config.raid_device
                ).as_dict()
                if record.state is ReleaseState.POWERED:
                    mcu = ops.machine.check_microcontroller()
                    report["microcontroller"] = {
                        "waiting_for_go": mcu.waiting_for_go,
                        "diagnosis": mcu.diagnosis,
                    }
                    report["gnss"] = mcu.gnss.as_dict()
            except HostKeyError:
                raise
            except LinkError as exc:
                report["link"] = {"up": False, "error": str(exc)}
                return report, False
            finally:
                ops.link.close()
        return report, True

    def release_authority(self, name: str, reason: str) -> AuthorityStatus:
        """Give up this console's release authority on the Pi (end of a shift); what was given up."""
        ops = self.ops(name)
        with ops.lock:
            try:
                return ops.machine.release_authority(reason)
            finally:
                ops.link.close()

    def record_released(self, name: str, typed_name: str, evidence: str) -> ReleaseRecord:
        """Settle an unverified Go as released on the operator's evidence; the checklist's Go step too."""
        ops = self.ops(name)
        with ops.lock:
            record = ops.machine.record_released(typed_name, evidence)
            self._command_done(name, "fire", record.note or "released")
        self.approvals.void_capsule(name, "capsule state changed: released", self.operator)
        return record

    def host_key_offer(self, name: str) -> HostKeyOffer:
        """The host key the Pi offers now (``drs capsule enrol``), before anything is trusted."""
        capsule = self.ops(name).config
        if capsule.jump_host:
            raise LinkError(
                f"{capsule.name}: enrol through a jump host is not supported; add the key by hand"
            )
        key = scan_host_key(capsule.host, capsule.port, capsule.connect_timeout_s)
        return HostKeyOffer(
            known_hosts_name(capsule.host, capsule.port), key.get_name(), fingerprint(key), key
        )

    def enrol(self, name: str, offer: HostKeyOffer, read_on_pi: str) -> Path:
        """Trust ``offer`` only if it is the fingerprint the operator read on the Pi itself; audited."""
        capsule = self.ops(name).config
        if read_on_pi != offer.fingerprint:
            raise RefusedError(
                f"{capsule.name}: enrol refused: the Pi offers {offer.fingerprint}, not {read_on_pi}"
            )
        self.store.append_audit(
            self.operator, capsule.name, "enrol", "ok", {"fingerprint": offer.fingerprint}
        )
        enrol_host_key(capsule.known_hosts, capsule.host, capsule.port, offer.key)
        return capsule.known_hosts

    def release_state(self, name: str) -> ReleaseState:
        return self.ops(name).machine.record().state

    def authority(self, name: str) -> AuthorityStatus:
        """Who holds the capsule's release authority on its Pi (read-only), for the release screen to show."""
        ops = self.ops(name)
        with ops.lock:
            return ops.machine.authority()

    def reset(self, name: str, typed_name: str) -> list[TelemetryRecord]:
        """After recovery: the state machine checks the typed name; then ARM is possible again."""
        ops = self.ops(name)
        with ops.lock:
            flown = ops.machine.record().state in (ReleaseState.GO_SENT, ReleaseState.RELEASED)
            record = ops.machine.reset(typed_name)
            if flown:  # a new flight; a reset that settles an unknown power-on keeps this flight's ticks
                start_new_flight(self.store, name, self.operator, self.clock)
            ops.arming.after_reset()
            ops.waivers.clear()
            self.approvals.void_capsule(name, "capsule state changed: reset after recovery", self.operator)
            self._command_done(name, "reset", "release state reset")
        return self._emit([self._release_record(name, record)])

    def gateway_check(self) -> list[TelemetryRecord]:
        """Whether commands could be sent: the gateway's address and credentials are configured."""
        try:
            RockblockGateway.from_config(self.config.rockblock, self.environ)
            sample = GatewaySample(True, f"user {self.config.rockblock.username}")
        except ConfigError as exc:
            sample = GatewaySample(False, str(exc))
        return self._emit([TelemetryRecord(self.clock(), None, sample)])

    def new_reports(self, name: str) -> list[TelemetryRecord]:
        """Iridium reports of one capsule stored since the last call (webhook or importer wrote them)."""
        imei = self.ops(name).config.imei
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
        return self._emit(records)

    def stored_reports(self, name: str) -> list[StoredReport]:
        imei = self.ops(name).config.imei
        return self.reports.for_imei(imei) if imei else []

    def reports_of(self, name: str) -> list[StoredReport]:
        """The capsule's Iridium reports in time order; refused when it has no IMEI to key them by."""
        imei = self.ops(name).config.imei
        if not imei:
            raise ConfigError(
                f"capsule {name}: imei is not configured; reports and commands are keyed by IMEI"
            )
        return self.reports.for_imei(imei)

    def mt_status(self, name: str) -> list[Command]:
        """The capsule's MTs after the reports moved them on (delivered, applied), oldest first."""
        reports = self.reports_of(name)
        imei = self.ops(name).config.imei or ""
        self.lifecycle.observe(reports, imei)
        return self.lifecycle.for_imei(imei)

    def plan_parachute(
        self, name: str, requested: tuple[int, int] | None, accept_midnight: bool = False
    ) -> ParachutePlan:
        """When a PARACHUTE can fire (``requested`` HH:MM, or the next cycle): the reports, the MTs known
        (read-only: ``mt_status`` moves them on first) and the queue-before deadline ``send_mt`` re-checks."""
        return plan_parachute(
            self.reports_of(name), self.clock(), self.commands(name), requested, accept_midnight
        )

    def landed(self, name: str) -> LandedEvidence:
        """The landed evidence the PARACHUTE gate will judge, for the operator to read before sending."""
        return landed_evidence(self.reports_of(name))

    def commands(self, name: str) -> list[Command]:
        imei = self.ops(name).config.imei
        return self.lifecycle.for_imei(imei) if imei else []

    def unresolved_like(self, name: str, message: MtMessage) -> list[Command]:
        """This capsule's commands with the same text whose delivery is still unknown: a retry may queue
        the MT twice (the gateway may hold the first), which the operator is told before sending."""
        return self.lifecycle.unresolved_like(self.ops(name).config.imei or "", message.text)

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
        capsule = self.ops(name).config
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
                self.approvals, name, "parachute", bound, self.operator, self.login,
                second.on_pending or (lambda request: None), command=bound, deadline=queue_by,
                brief=ApprovalBrief(message.text, landed=evidence.summary, override=override or None),
            )  # fmt: skip
        authorised = authorize_mt(
            self.store, name, self.operator, message, reports, second_operator=second.name,
            single_operator_waiver=second.waiver,
            require_second_operator=self.config.console.require_second_operator,
            crew=self.config.console.crew,
            override_landed=override_landed, queue_by=queue_by, now=self.clock(), approval=approval,
            login=self.login if approval is not None else None, spend=False,
        )  # fmt: skip
        gateway = RockblockGateway.from_config(self.config.rockblock, self.environ)  # before it is spent
        if approval is None:
            command = self.lifecycle.request(capsule, message, flush=flush)
        else:
            request = self.approvals.get(approval)
            try:
                command = self.lifecycle.request(
                    capsule, message, flush=flush, also=lambda conn: self.approvals.spend_in(conn, request)
                )
            except RefusedError as exc:
                detail = {"text": message.text, "reason": str(exc)}
                self.store.append_audit(
                    self.operator, name, "mt.parachute", "refused", detail, when=self.clock()
                )
                raise RefusedError(f"{name}: PARACHUTE refused: {exc}") from None
            self.approvals.spent(request)
        command = self.lifecycle.send(command.id, confirmation, gateway)
        steps = complete_mt_steps(
            self.store, self.checklists, self.operator, command, self.stored_reports(name), self.clock
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
        return [command, *self.lifecycle.observe(reports, self.ops(name).config.imei or "")]

    def close(self) -> None:
        for ops in self.capsules.values():
            ops.link.close()
        if self.recorder is not None:
            self.recorder.close()

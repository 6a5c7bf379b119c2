"""One operator's capsule links: the poll of each capsule, ``drs capsule status``, power-on, reset and sync.

Every method blocks (SSH, SQLite) and is meant to be called from a worker thread; results come back as
telemetry records that a console folds into its fleet state.
"""

from __future__ import annotations

from collections.abc import Callable
from pathlib import Path

from drs_link.errors import ConfigError, LinkError
from drs_link.link import HostKeyError, SyncReport, SyncStatus, read_storage
from drs_link.ops.arming import FINISH_GO_S
from drs_link.ops.capsule import ReleaseState, record_as_dict
from drs_link.ops.checklist import start_new_flight
from drs_link.ops.ops_state import OpsState
from drs_link.ops.telemetry import GnssSample, LinkSample, StorageSample, SyncSample, TelemetryRecord

SyncProgress = Callable[[str, int, int], None]
"""Told (file, bytes done, bytes in it) while a sync uploads, for a progress bar."""


NO_SYNC_SOURCE = (
    "sync_source is not configured (set it in the capsule's [[capsule]] table: the payload data to upload)"
)
"""What go/no-go's sync item and ``drs sync`` say when the capsule has no directory to upload."""


class CapsuleLinks:
    """The capsules' SSH links: polls, the status report, power-on, reset and the data sync."""

    def __init__(self, state: OpsState) -> None:
        self.state = state

    def poll(self, name: str) -> list[TelemetryRecord]:
        """Link, release state, microcontroller/GNSS, storage and sync of one capsule, as records."""
        ops = self.state.ops(name)
        with ops.lock:
            record = ops.machine.record()
            if record.state is ReleaseState.GO_SENT:
                record = ops.machine.recheck_unverified_go(FINISH_GO_S)
                if record.state is ReleaseState.POWERED:
                    ops.arming.go_not_taken(record.note or "Go never taken")
            out = [self.state.release_record(name, record)]
            if record.state in (ReleaseState.RELEASED, ReleaseState.GO_SENT):
                out.append(TelemetryRecord(self.state.clock(), name, LinkSample(False, "released")))
                return self.state.emit(out)
            try:
                ops.link.ensure_connected()
                up = ops.link.heartbeat()
            except HostKeyError as exc:
                out.append(TelemetryRecord(self.state.clock(), name, LinkSample(False, str(exc))))
                return self.state.emit(out)
            except LinkError as exc:
                up = False
                note = str(exc)
            else:
                note = "heartbeat answered" if up else "heartbeat failed"
            out.append(TelemetryRecord(self.state.clock(), name, LinkSample(up, note)))
            if not up:
                ops.link.close()
                return self.state.emit(out)
            try:
                if record.state is ReleaseState.POWERED:
                    mcu = ops.machine.check_microcontroller()
                    gnss = mcu.gnss
                    out.append(self.state.release_record(name, ops.machine.record()))
                    out.append(TelemetryRecord(self.state.clock(), name, GnssSample(
                        has_fix=gnss.has_fix, quality=gnss.fix_quality_name, sats=gnss.satellites,
                        hdop=gnss.hdop, lat=gnss.latitude, lon=gnss.longitude, alt_m=gnss.altitude_m,
                        fix_age_s=gnss.age_s, diagnosis=mcu.diagnosis, date_problem=gnss.date_problem,
                    )))  # fmt: skip
                storage = read_storage(ops.link, ops.config.storage_mount, ops.config.raid_device)
                usage = storage.usage
                out.append(TelemetryRecord(self.state.clock(), name, StorageSample(
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
                    out.append(TelemetryRecord(self.state.clock(), name, SyncSample(
                        fraction=fraction, bytes_pending=status.bytes_pending,
                        files_pending=len(status.missing) + len(status.changed),
                    )))  # fmt: skip
                else:
                    out.append(TelemetryRecord(self.state.clock(), name, SyncSample(unknown=NO_SYNC_SOURCE)))
            except LinkError as exc:
                out.append(TelemetryRecord(self.state.clock(), name, LinkSample(False, str(exc))))
            return self.state.emit(out)

    def _sync_source(self, name: str, source: Path | None) -> Path:
        chosen = source if source is not None else self.state.ops(name).config.sync_source
        if chosen is None:
            raise ConfigError(f"capsule {name}: {NO_SYNC_SOURCE}, and no directory was given")
        return chosen

    def sync(
        self, name: str, source: Path | None = None, on_progress: SyncProgress | None = None
    ) -> SyncReport:
        """Upload ``source`` (default: the capsule's ``sync_source``) to its storage, each file verified by
        sha256 on the Pi; every verified file, the outcome and a failure are audited, whichever face asked."""
        ops = self.state.ops(name)
        chosen = self._sync_source(name, source)

        def verified(relative: str) -> None:
            self.state.store.append_audit(
                self.state.operator,
                name,
                "sync-file",
                "verified",
                {"path": relative},
                when=self.state.clock(),
            )

        with ops.lock:
            try:
                report = ops.syncer.sync(chosen, on_progress=on_progress, on_verified=verified)
            except LinkError as exc:
                self.state.store.append_audit(
                    self.state.operator, name, "sync", "failed", {"error": str(exc)}, when=self.state.clock()
                )
                raise
        detail = {"uploaded": len(report.uploaded), "bytes": report.bytes_sent}
        self.state.store.append_audit(
            self.state.operator, name, "sync", "ok", detail, when=self.state.clock()
        )
        return report

    def sync_status(self, name: str, source: Path | None = None, with_hash: bool = False) -> SyncStatus:
        """What a sync of ``source`` would upload (missing or changed files), read-only."""
        ops = self.state.ops(name)
        chosen = self._sync_source(name, source)
        with ops.lock:
            return ops.syncer.status(chosen, with_hash=with_hash)

    def power_on(self, name: str, confirmed: bool = True) -> list[TelemetryRecord]:
        """Confirmed by the operator before this is called (the relay cannot be switched off by software);
        ``confirmed`` False is refused (and audited) by the state machine. Voids the capsule's approvals."""
        ops = self.state.ops(name)
        with ops.lock:
            record = ops.machine.power_on(confirmed=confirmed)
            ops.arming.disarm("power-on")
            self.state.approvals.void_capsule(name, "capsule state changed: powered on", self.state.operator)
            self.state.command_done(name, "power-on", "relay latched")
        return self.state.emit([self.state.release_record(name, record)])

    def reset(self, name: str, typed_name: str) -> list[TelemetryRecord]:
        """After recovery: the state machine checks the typed name; then ARM is possible again."""
        ops = self.state.ops(name)
        with ops.lock:
            flown = ops.machine.record().state in (ReleaseState.GO_SENT, ReleaseState.RELEASED)
            record = ops.machine.reset(typed_name)
            if flown:  # a new flight; a reset that settles an unknown power-on keeps this flight's ticks
                start_new_flight(self.state.store, name, self.state.operator, self.state.clock)
            ops.arming.after_reset()
            ops.waivers.clear()
            self.state.approvals.void_capsule(
                name, "capsule state changed: reset after recovery", self.state.operator
            )
            self.state.command_done(name, "reset", "release state reset")
        return self.state.emit([self.state.release_record(name, record)])

    def capsule_status(self, name: str) -> tuple[dict[str, object], bool]:
        """``drs capsule status``: the release record, storage, microcontroller and GNSS as one report
        (read-only), and whether the link was up. A refused host key is raised, never reported as down."""
        ops = self.state.ops(name)
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

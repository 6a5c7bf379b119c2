"""The state one operator's operations hold, shared by their concerns (``drs_link.ops.operator_ops``).

Why shared, not one class: the capsule links, the release, Iridium and enrolment each act on the same
store, capsules and locks under one operator; each concern is its own class over this one state
(issue #29 item 3), so a server service holds the concern it serves and nothing else.
"""

from __future__ import annotations

import threading
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from shapely import Polygon

from drs_link.config import CapsuleConfig, Config
from drs_link.errors import ConfigError
from drs_link.link import CapsuleLink, Syncer
from drs_link.link.backends import build_backend
from drs_link.ops.approval import Approval, ApprovalBook, Login, current_login
from drs_link.ops.arming import ArmingController
from drs_link.ops.capsule import ReleaseRecord, ReleaseStateMachine
from drs_link.ops.checklist import PROCEDURE_DIR, complete_command, load_checklists
from drs_link.ops.gonogo import ExclusionZone, WaiverBook
from drs_link.ops.telemetry import ReleaseSample, TelemetryRecord, TelemetryRecorder
from drs_link.ops.typed_text import shown
from drs_link.store import Store, utc_now
from predictor.prediction import ZoneFileError, load_zones

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


class OpsState:
    """What the concerns of one operator share: the configuration and the store, each capsule's link,
    release state machine, ARM controller, waivers, syncer and lock (``CapsuleOps``), the approvals and
    checklists, and who acts (the operator name, the login and the ARM windows' holder)."""

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
        """``holder``: who may FIRE in an ARM window these operations open (default: this process; the
        server's desk of an account uses account@host, ``server.desks.holder_of``, so that ``drs capsule
        arm`` and ``drs capsule go`` are one holder)."""
        self.config = config
        self.store = store
        self.clock = clock
        self.recorder = recorder
        self.environ = environ
        self.operator = config.operator.name or "unknown"
        self._login = login
        self.checklists = load_checklists(PROCEDURE_DIR)
        self.approvals = ApprovalBook(store, clock)
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

    @property
    def login(self) -> Login:
        """Who is at this keyboard (``approval.current_login``), asked for only when an approval needs it."""
        if self._login is None:
            self._login = current_login()
        return self._login

    def emit(self, records: list[TelemetryRecord]) -> list[TelemetryRecord]:
        if self.recorder is not None:
            for record in records:
                self.recorder.append(record)
        return records

    def ops(self, name: str) -> CapsuleOps:
        if name not in self.capsules:
            raise ConfigError(f"no capsule named {name!r} in the configuration")
        return self.capsules[name]

    def release_record(self, name: str, record: ReleaseRecord) -> TelemetryRecord:
        sample = ReleaseSample(
            record.state.value,
            record.nmea_seen_at is not None,
            None if record.note is None else shown(record.note),
            record.released_at,
        )
        return TelemetryRecord(self.clock(), name, sample)

    def command_done(self, name: str, command: str, result: str) -> None:
        """The checklist step a release command completes, by the rule ``drs capsule`` uses too."""
        complete_command(self.store, self.checklists, name, command, self.operator, result, {}, self.clock)

    def close(self) -> None:
        for ops in self.capsules.values():
            ops.link.close()
        if self.recorder is not None:
            self.recorder.close()

"""What the console knows about each capsule, folded from telemetry records, every value with its age.

The fleet view, the checklists' automatic steps and the go/no-go poll all read this one state, so
they can never disagree. A value that has gone stale is handed to checklists as *no data* (an
automatic step is never shown met on an old number) and to go/no-go as stale (which is NO-GO).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import TypeVar, cast

from drs_link.ops.gonogo import ExclusionZone, GoNoGoInputs, PredictionCheck
from drs_link.ops.staleness import Reading
from drs_link.ops.telemetry import (
    BalloonSample,
    GatewaySample,
    GnssSample,
    LinkSample,
    PredictionSample,
    PredictionStatus,
    ReleaseSample,
    ReportSample,
    Sample,
    StorageSample,
    SyncSample,
    TelemetryRecord,
)

PERIOD_S: dict[str, float] = {
    "link": 10.0,
    "release": 10.0,
    "gnss": 10.0,
    "storage": 60.0,
    "sync": 60.0,
    "prediction": 120.0,
    "prediction_status": 120.0,
    "report": 120.0,
    "gateway": 600.0,
    "balloon": 60.0,
}
"""Expected period of each kind of telemetry; a value is stale after twice its period."""
POLLED = (LinkSample, ReleaseSample, GnssSample, StorageSample, SyncSample)
"""Kinds that come from polling the capsule: their period is at least the poller's own."""

S = TypeVar("S", bound=Sample)


@dataclass
class CapsuleTelemetry:
    name: str
    poll_period_s: float = 0.0
    """How often this console polls the capsule (a slower poller makes slower-aging values)."""
    readings: dict[str, Reading[Sample]] = field(default_factory=dict)
    reports: list[ReportSample] = field(default_factory=list)
    predictions: dict[int, Reading[PredictionSample]] = field(default_factory=dict)
    """Landing predictions by minutes until release (0 = release now)."""

    def reading(self, kind: type[S]) -> Reading[S]:
        reading = self.readings.get(kind.KIND)
        return cast(Reading[S], reading) if reading is not None else Reading.missing(PERIOD_S[kind.KIND])

    def fresh(self, kind: type[S], now: datetime) -> S | None:
        """The latest value of a kind, or ``None`` when it is missing or stale (never judge on old data)."""
        reading = self.reading(kind)
        return reading.value if reading.is_fresh(now) else None

    def release(self) -> ReleaseSample | None:
        """The latest release record at any age: a release does not stop being one when polls stop."""
        return self.reading(ReleaseSample).value

    @property
    def released(self) -> bool:
        """Go was sent, by ``ReleaseSample.released``: the link is down as expected, NMEA is history."""
        release = self.release()
        return release is not None and release.released

    @property
    def powered(self) -> bool:
        release = self.release()
        return release is not None and release.powered

    def apply(self, record: TelemetryRecord) -> None:
        period = PERIOD_S[record.kind]
        sample = record.data
        if isinstance(sample, POLLED):
            period = max(period, self.poll_period_s)
        if isinstance(sample, ReportSample):
            period = 60.0 * float(sample.interval_min or 2)
            self.reports.append(sample)
        if isinstance(sample, PredictionSample):
            self.predictions[sample.release_in_min] = Reading(sample, record.time, period)
            if sample.release_in_min != 0:
                return
        self.readings[record.kind] = Reading(sample, record.time, period)

    def facts(self, now: datetime) -> dict[str, object]:
        """The checklist facts (drs_link.ops.checklist.FACTS); stale or unknown values are None."""
        link, gnss = self.fresh(LinkSample, now), self.fresh(GnssSample, now)
        storage, sync = self.fresh(StorageSample, now), self.fresh(SyncSample, now)
        polled, release = self.fresh(ReleaseSample, now), self.release()
        free = None
        if storage is not None and storage.total_bytes and storage.used_bytes is not None:
            free = 1.0 - storage.used_bytes / storage.total_bytes
        last_report = self.reports[-1] if self.reports else None
        return {
            "link_up": link.up if link else None,
            "powered": None if release is None else release.powered,
            "nmea_seen": polled.nmea_seen if polled else None,
            "gnss_fix": gnss.has_fix if gnss else None,
            "gnss_sats": gnss.sats if gnss else None,
            "gnss_hdop": gnss.hdop if gnss else None,
            "sync_fraction": sync.fraction if sync else None,
            "raid_healthy": None if storage is None or storage.raid is None else storage.raid == "healthy",
            "storage_free_fraction": free,
            "released": None if release is None else release.released,
            "reports_received": len(self.reports),
            "landed": last_report.landed if last_report else None,
            "vbat": last_report.vbat if last_report else None,
            "interval_min": last_report.interval_min if last_report else None,
        }

    def gonogo_inputs(self, now: datetime, zones: tuple[ExclusionZone, ...]) -> GoNoGoInputs:
        release = self.release()
        return GoNoGoInputs(
            link_up=self.reading(LinkSample).map(lambda s: s.up),
            microcontroller_waiting=self.reading(ReleaseSample).map(lambda s: s.nmea_seen),
            gnss_fix=self.reading(GnssSample).map(lambda s: s.has_fix),
            sync_fraction=self.reading(SyncSample).map(lambda s: s.fraction),
            prediction=self.reading(PredictionSample).map(
                lambda p: PredictionCheck(p.landing_lat, p.landing_lon, p.outline_2sigma)
            ),
            gateway_credentials=self.reading(GatewaySample).map(lambda s: s.credentials_ok),
            powered=self.powered,
            exclusion_zones=zones,
            released=release.after_release() if release else None,
            prediction_pending=self.reading(PredictionStatus).map(lambda status: status.text).value,
            sync_pending=self.reading(SyncSample).map(lambda s: s.unknown or None).value,
        )


@dataclass
class FleetState:
    capsules: dict[str, CapsuleTelemetry] = field(default_factory=dict)
    balloon: Reading[BalloonSample] = field(default_factory=lambda: Reading.missing(PERIOD_S["balloon"]))
    gateway: Reading[GatewaySample] = field(default_factory=lambda: Reading.missing(PERIOD_S["gateway"]))

    poll_period_s: float = 0.0

    @classmethod
    def for_capsules(cls, names: list[str], poll_period_s: float = 0.0) -> FleetState:
        return cls(
            {name: CapsuleTelemetry(name, poll_period_s) for name in names}, poll_period_s=poll_period_s
        )

    def apply(self, record: TelemetryRecord) -> None:
        sample = record.data
        if isinstance(sample, BalloonSample):
            self.balloon = Reading(sample, record.time, PERIOD_S["balloon"])
            return
        if record.capsule is None:
            if isinstance(sample, GatewaySample):
                self.gateway = Reading(sample, record.time, PERIOD_S["gateway"])
                for capsule in self.capsules.values():
                    capsule.apply(record)
            return
        capsule = self.capsules.setdefault(
            record.capsule, CapsuleTelemetry(record.capsule, self.poll_period_s)
        )
        capsule.apply(record)

"""What the console knows about each capsule, folded from telemetry records, every value with its age.

The fleet view, the checklists' automatic steps and the go/no-go poll all read this one state, so
they can never disagree. A value that has gone stale is handed to checklists as *no data* (an
automatic step is never shown met on an old number) and to go/no-go as stale (which is NO-GO).
"""

from __future__ import annotations

from dataclasses import dataclass, field
from datetime import datetime
from typing import Any

from drs_link.gonogo import ExclusionZone, GoNoGoInputs, PredictionCheck
from drs_link.staleness import Reading
from drs_link.telemetry import TelemetryRecord

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
POLLED = ("link", "release", "gnss", "storage", "sync")
"""Kinds that come from polling the capsule: their period is at least the poller's own."""


def _empty(kind: str) -> Reading[dict[str, Any]]:
    return Reading.missing(PERIOD_S[kind])


@dataclass
class CapsuleTelemetry:
    name: str
    poll_period_s: float = 0.0
    """How often this console polls the capsule (a slower poller makes slower-aging values)."""
    readings: dict[str, Reading[dict[str, Any]]] = field(default_factory=dict)
    reports: list[dict[str, Any]] = field(default_factory=list)
    predictions: dict[int, Reading[dict[str, Any]]] = field(default_factory=dict)
    """Landing predictions by minutes until release (0 = release now)."""

    def reading(self, kind: str) -> Reading[dict[str, Any]]:
        return self.readings.get(kind) or _empty(kind)

    def value(self, kind: str, key: str, now: datetime, fresh_only: bool = True) -> Any:
        reading = self.reading(kind)
        if reading.value is None or (fresh_only and not reading.is_fresh(now)):
            return None
        return reading.value.get(key)

    def apply(self, record: TelemetryRecord) -> None:
        period = PERIOD_S[record.kind]
        if record.kind in POLLED:
            period = max(period, self.poll_period_s)
        if record.kind == "report":
            period = 60.0 * float(record.data.get("interval_min") or 2)
            self.reports.append({**record.data, "time": record.time})
        reading = Reading(record.data, record.time, period)
        if record.kind == "prediction":
            self.predictions[int(record.data.get("release_in_min", 0))] = reading
            if int(record.data.get("release_in_min", 0)) != 0:
                return
        self.readings[record.kind] = reading

    def facts(self, now: datetime) -> dict[str, object]:
        """The checklist facts (drs_link.checklist.FACTS); stale or unknown values are None."""
        storage = self.reading("storage")
        free = None
        if storage.is_fresh(now) and storage.value and storage.value.get("total_bytes"):
            free = 1.0 - storage.value["used_bytes"] / storage.value["total_bytes"]
        state = self.value("release", "state", now, fresh_only=False)
        last_report = self.reports[-1] if self.reports else {}
        return {
            "link_up": self.value("link", "up", now),
            "powered": None if state is None else state == "powered",
            "nmea_seen": self.value("release", "nmea_seen", now),
            "gnss_fix": self.value("gnss", "has_fix", now),
            "gnss_sats": self.value("gnss", "sats", now),
            "gnss_hdop": self.value("gnss", "hdop", now),
            "sync_fraction": self.value("sync", "fraction", now),
            "raid_healthy": None if self.value("storage", "raid", now) is None
            else self.value("storage", "raid", now) == "healthy",
            "storage_free_fraction": free,
            "released": None if state is None else state in ("released", "go-sent-unverified"),
            "reports_received": len(self.reports),
            "landed": bool(last_report.get("landed")) if last_report else None,
            "vbat": last_report.get("vbat"),
            "interval_min": last_report.get("interval_min"),
        }  # fmt: skip

    def gonogo_inputs(self, now: datetime, zones: tuple[ExclusionZone, ...]) -> GoNoGoInputs:
        def sub(kind: str, key: str) -> Reading[Any]:
            reading = self.reading(kind)
            value = None if reading.value is None else reading.value.get(key)
            return Reading(value, reading.received_at, reading.expected_period_s, reading.tolerance)

        prediction = self.reading("prediction")
        check = None
        if prediction.value is not None:
            check = PredictionCheck(
                prediction.value["landing_lat"],
                prediction.value["landing_lon"],
                tuple((float(lon), float(lat)) for lon, lat in prediction.value.get("outline_2sigma", [])),
            )
        state = self.value("release", "state", now, fresh_only=False)
        released = None
        if state in ("released", "go-sent-unverified"):
            at = self.value("release", "released_at", now, fresh_only=False)
            when = f" {at[11:16]}Z" if isinstance(at, str) and len(at) >= 16 else ""
            released = f"released{when}, Pi shut down" if state == "released" else "Go sent, not yet verified"
        return GoNoGoInputs(
            link_up=sub("link", "up"),
            microcontroller_waiting=sub("release", "nmea_seen"),
            gnss_fix=sub("gnss", "has_fix"),
            sync_fraction=sub("sync", "fraction"),
            prediction=Reading(check, prediction.received_at, prediction.expected_period_s),
            gateway_credentials=sub("gateway", "credentials_ok"),
            powered=state == "powered",
            exclusion_zones=zones,
            released=released,
        )


@dataclass
class FleetState:
    capsules: dict[str, CapsuleTelemetry] = field(default_factory=dict)
    balloon: Reading[dict[str, Any]] = field(default_factory=lambda: _empty("balloon"))
    gateway: Reading[dict[str, Any]] = field(default_factory=lambda: _empty("gateway"))

    poll_period_s: float = 0.0

    @classmethod
    def for_capsules(cls, names: list[str], poll_period_s: float = 0.0) -> FleetState:
        return cls({name: CapsuleTelemetry(name, poll_period_s) for name in names}, poll_period_s=poll_period_s)

    def apply(self, record: TelemetryRecord) -> None:
        if record.kind == "balloon":
            self.balloon = Reading(record.data, record.time, PERIOD_S["balloon"])
            return
        if record.capsule is None:
            if record.kind == "gateway":
                self.gateway = Reading(record.data, record.time, PERIOD_S["gateway"])
                for capsule in self.capsules.values():
                    capsule.apply(record)
            return
        capsule = self.capsules.setdefault(record.capsule, CapsuleTelemetry(record.capsule, self.poll_period_s))
        capsule.apply(record)

"""What the per-capsule screens show, from one source: the store in a live console, the recording in a replay.

The recovery and Iridium screens read no store themselves, so a replay (no store behind it) shows them
too: a ``ViewSource`` answers with frozen values (``RecoveryView``, ``IridiumHealthView``) that the
console's workers hand to the screens; a live console's are read by the operations server
(``drs_link.server.views``), ``RecordedViews`` rebuilds the same values from the report records a replay has played so far (no
commands, no health flags: the recording does not hold the data they are judged on, and the views
say so).
"""

from __future__ import annotations

import threading
from collections.abc import Iterable, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import Protocol

from drs_link.iridium import Command, StoredReport, TrackPoint, assess
from drs_link.ops.iridium_ops import report_position
from drs_link.ops.recovery import RecoveryView, descent_along
from drs_link.ops.telemetry import ReportSample, TelemetryRecord

REPORT_ROWS = 50
"""The newest reports the Iridium screen lists (older ones are in ``drs report export``)."""
FLAGS_SHOWN = 4


@dataclass(frozen=True)
class ReportRow:
    """One Iridium report as the screen lists it; a part the report lacks is None."""

    momsn: int | None
    fix_time: datetime | None
    """None when the report carried no GNSS fix."""
    position: tuple[float, float, str] | None
    """(lat, lon, source): the fix, else the Iridium network's estimate."""
    alt_m: float | None
    vbat: float | None
    iteration: int | None


@dataclass(frozen=True)
class IridiumHealthView:
    """One capsule's Iridium side: health from the pattern of reports, its MT commands, its reports."""

    capsule: str
    reports_count: int
    last_vbat: float | None
    flags: tuple[str, ...] | None
    """The latest health findings in words; None where they cannot be judged (a replay)."""
    commands: tuple[Command, ...]
    """Oldest first, as the lifecycle keeps them."""
    rows: tuple[ReportRow, ...]
    """Newest first, at most ``REPORT_ROWS``."""

    @property
    def summary(self) -> str:
        if self.reports_count == 0:
            return f"{self.capsule}: no Iridium reports yet"
        vbat = f"{self.last_vbat:.2f} V" if self.last_vbat is not None else "?"
        if self.flags is None:
            flags = "health flags not judged in a replay"
        else:
            flags = "; ".join(self.flags) or "no health flags"
        return f"{self.capsule}: {self.reports_count} reports, battery {vbat}. {flags}"


def row_of(stored: StoredReport) -> ReportRow:
    report = stored.report
    fix = report.fix if report else None
    position = stored_position(stored)
    return ReportRow(
        stored.delivery.momsn,
        fix.time if fix else None,
        position,
        fix.alt_m if fix else None,
        report.vbat if report else None,
        report.iteration if report else None,
    )


def stored_position(stored: StoredReport) -> tuple[float, float, str] | None:
    position = report_position(stored)
    return (position[0], position[1], position[3]) if position else None


def iridium_health_from(
    capsule: str, reports: Sequence[StoredReport], commands: Sequence[Command]
) -> IridiumHealthView:
    health = assess(list(reports), commands) if reports else None
    flags = tuple(f"{f.kind}: {f.message}" for f in health.findings[-FLAGS_SHOWN:]) if health else ()
    return IridiumHealthView(
        capsule,
        health.reports if health else 0,
        health.last_vbat if health else None,
        flags,
        tuple(commands),
        tuple(row_of(r) for r in reversed(reports[-REPORT_ROWS:])),
    )


class ViewSource(Protocol):
    """Where the screens' per-capsule views come from; called from worker threads."""

    def recovery(self, capsule: str) -> RecoveryView: ...

    def iridium(self, capsule: str) -> IridiumHealthView: ...

    def observe(self, records: Iterable[TelemetryRecord]) -> None:
        """Telemetry the console folded (a replay's only source)."""


class RecordedViews:
    """A replay: the report records played so far, the same pipeline over them."""

    def __init__(self) -> None:
        self._reports: dict[str, list[tuple[datetime, ReportSample]]] = {}
        self._lock = threading.Lock()

    def observe(self, records: Iterable[TelemetryRecord]) -> None:
        with self._lock:
            for record in records:
                if record.capsule is not None and isinstance(record.data, ReportSample):
                    self._reports.setdefault(record.capsule, []).append((record.time, record.data))

    def _played(self, capsule: str) -> list[tuple[datetime, ReportSample]]:
        with self._lock:
            return list(self._reports.get(capsule, ()))

    def recovery(self, capsule: str) -> RecoveryView:
        track = tuple(
            TrackPoint(at, s.lat, s.lon, s.alt_m, s.speed_ms or 0.0)
            for at, s in self._played(capsule)
            if s.has_fix and s.lat is not None and s.lon is not None and s.alt_m is not None
        )
        return RecoveryView(capsule, descent_along(track, capsule, None), settings=None)

    def iridium(self, capsule: str) -> IridiumHealthView:
        played = self._played(capsule)
        rows = tuple(
            ReportRow(
                s.momsn,
                at if s.has_fix else None,
                (s.lat, s.lon, s.position_source or "?") if s.lat is not None and s.lon is not None else None,
                s.alt_m,
                s.vbat,
                s.iteration,
            )
            for at, s in reversed(played[-REPORT_ROWS:])
        )
        last_vbat = next((s.vbat for _, s in reversed(played) if s.vbat is not None), None)
        return IridiumHealthView(capsule, len(played), last_vbat, None, (), rows)

"""Is the capsule on the ground? The evidence PARACHUTE needs, read from its own position reports.

Why a gate: PARACHUTE opens release B, which drops the parachute. Queued while the capsule is still
falling it is downloaded at the next cycle and, inside the firmware's ±14 min window, obeyed: the
capsule then falls the rest of the way without a canopy. The paper adds the time code precisely so
that the parachute is never released early; the console's own checklist says "Landing confirmed:
queue PARACHUTE". So the rule is the landing rule ``drs recovery`` already uses (one rule, one
place: ``recovery.detect_landing``), plus two checks that the landing still holds:

* a landing is found: after falling at least 500 m from the peak, a fix that is itself slower than
  3 m/s and is followed by a fix with neither a climb or fall faster than 1.5 m/s nor travel faster
  than 3 m/s (two reports that no longer descend);
* the capsule has not moved away from that landing site since (more than 300 m);
* where the terrain height is known (a DEM), the landing is within ``GROUND_TOLERANCE_M`` of it.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass
from typing import Any

from drs_link.iridium.recovery import (
    LandingWatch,
    TrackPoint,
    detect_landing,
    track_from_reports,
    track_point,
)
from drs_link.iridium.reports import StoredReport

GROUND_TOLERANCE_M = 150.0
"""GNSS altitude error (~±30 m) plus DEM error (SRTM ~±16 m, coarse DEMs ~±100 m in relief)."""


@dataclass(frozen=True)
class LandedEvidence:
    on_ground: bool
    summary: str
    """One line an operator reads before typing a name: the evidence, or what is missing."""
    last_fix: TrackPoint | None

    def audit(self) -> dict[str, Any]:
        """What the audit record keeps: the verdict, its reason and the last fix."""
        fix = self.last_fix
        return {
            "on_ground": self.on_ground,
            "evidence": self.summary,
            "last_fix": None if fix is None else {
                "time": fix.time.isoformat().replace("+00:00", "Z"), "lat": fix.lat, "lon": fix.lon,
                "alt_m": fix.alt_m, "speed_ms": fix.speed_ms,
            },
        }  # fmt: skip


def _describe(fix: TrackPoint) -> str:
    return f"{fix.time:%H:%M:%S}Z at {fix.alt_m:,.0f} m, {fix.speed_ms:.1f} m/s"


def landed_evidence(reports: Sequence[StoredReport], ground_m: float | None = None) -> LandedEvidence:
    """The evidence that the capsule is on the ground, from its reports (``ground_m``: terrain height
    at the landing, when a DEM is known)."""
    track = track_from_reports(list(reports))
    if not track:
        return LandedEvidence(False, "no position report with a GNSS fix yet", None)
    last = track[-1]
    landing = detect_landing(track)
    if landing is None:
        trend = ""
        if len(track) >= 2:
            before = track[-2]
            seconds = (last.time - before.time).total_seconds()
            if seconds > 0:
                rate = (last.alt_m - before.alt_m) / seconds
                trend = f", {'falling' if rate < 0 else 'climbing'} {abs(rate):.1f} m/s since the report before"
        return LandedEvidence(False, f"NOT LANDED: last fix {_describe(last)}{trend}", last)
    if landing.moved_at is not None:
        return LandedEvidence(
            False,
            f"moved: landed {landing.landed_at:%H:%M}Z but left the site at {landing.moved_at:%H:%M:%S}Z; "
            f"last fix {_describe(last)}",
            last,
        )
    if ground_m is not None and abs(landing.alt_m - ground_m) > GROUND_TOLERANCE_M:
        return LandedEvidence(
            False,
            f"still at {landing.alt_m:,.0f} m where the terrain is {ground_m:,.0f} m (more than "
            f"{GROUND_TOLERANCE_M:.0f} m apart): a tree, a slow fall, or a wrong DEM; last fix {_describe(last)}",
            last,
        )
    terrain = f", terrain {ground_m:,.0f} m" if ground_m is not None else ""
    return LandedEvidence(
        True,
        f"landed {landing.landed_at:%H:%M:%S}Z at {landing.alt_m:,.0f} m{terrain}: {landing.count} still "
        f"fix(es) within 300 m, last {_describe(last)}",
        last,
    )


class LandedVerdicts:
    """``landed_evidence(reports so far).on_ground`` (no DEM), one report at a time, in time order (as
    ``ReportStore.for_imei`` gives them).

    Why one at a time: the console marks each report with the verdict on the reports up to it, and
    asking ``landed_evidence`` of every prefix re-ran the landing rule on the whole track each time,
    which is quadratic (0.24 s for 400 reports at start-up); fed in order, each report is one step.
    """

    def __init__(self) -> None:
        self._watch = LandingWatch()

    def add(self, stored: StoredReport) -> bool:
        if (point := track_point(stored)) is not None:
            self._watch.add(point)
        return self._watch.on_site

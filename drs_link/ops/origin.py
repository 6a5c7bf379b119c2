"""Where a predicted release starts, and from what: one rule, below the screens that show it.

The capsule's own GNSS fix is where it is; the balloon feed is where the gondola is, a few metres
off and possibly older. So a fresh fix of the capsule wins, then a fresh balloon position, and a
stale one of either starts nothing (a prediction from an old position is a confident wrong answer).
The operator must see which one a prediction used, so the origin carries its source in words.
"""

from __future__ import annotations

from dataclasses import dataclass
from datetime import datetime

from drs_link.ops.fleet import FleetState
from drs_link.ops.telemetry import GnssSample
from predictor.descent import Release

GNSS_ALT_UNKNOWN_M = 30000.0
"""Release height when the capsule's fix carries no altitude: a float altitude of the flights flown."""


@dataclass(frozen=True)
class ReleaseOrigin:
    """Where a release would start, and from what: the operator must see which position a prediction used."""

    lat: float
    lon: float
    alt_m: float
    source: str

    def release(self, time: datetime, drift_minutes: float = 0.0) -> Release:
        """A release from here at ``time`` (after ``drift_minutes`` at float): what the prediction flies."""
        return Release(time, self.lat, self.lon, self.alt_m, drift_minutes=drift_minutes)


def release_origin(fleet: FleetState, capsule: str, now: datetime) -> ReleaseOrigin | None:
    """The capsule's own fresh fix, else the balloon feed's fresh position, else ``None`` (wait)."""
    fix = fleet.capsules[capsule].fresh(GnssSample, now)
    if fix is not None and fix.has_fix and fix.lat is not None and fix.lon is not None:
        return ReleaseOrigin(fix.lat, fix.lon, fix.alt_m or GNSS_ALT_UNKNOWN_M, f"{capsule} GNSS")
    balloon = fleet.balloon.value if fleet.balloon.is_fresh(now) else None
    if balloon is not None:
        source = "balloon feed" + (f" ({balloon.source})" if balloon.source else "")
        return ReleaseOrigin(balloon.lat, balloon.lon, balloon.alt_m, source)
    return None

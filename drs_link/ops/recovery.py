"""Where a dropped capsule is and is going, as typed values the recovery screen and the chase feed share.

The pipeline from stored Iridium reports to a track, a landing (if the fixes show one) and, while it
still descends, the live re-prediction from the latest fix, exists here once: the recovery screen
and the chase feed both called it separately and could disagree on whether a capsule had landed.
The live re-prediction itself needs the weather (the console's prediction service), so the caller
passes it in as ``LiveSource``; this room never loads weather.
"""

from __future__ import annotations

import math
from collections.abc import Callable, Sequence
from dataclasses import dataclass
from datetime import datetime
from typing import TYPE_CHECKING

from drs_link.iridium import (
    Command,
    CommandedSettings,
    LandingEstimate,
    StoredReport,
    TrackPoint,
    commanded_settings,
    detect_landing,
    track_from_reports,
)
from drs_link.ops.override import ParachuteOverride, drop_schedule, parachute_override
from drs_link.store import AuditRecord
from predictor.errors import PredictorError

if TYPE_CHECKING:
    from drs_link.ops.iridium_ops import IridiumOps

LiveSource = Callable[[str, Sequence[TrackPoint]], "LiveView | None"]
"""The capsule's live re-prediction from its track (``PredictionService.live``); None before a fix."""

Points = tuple[tuple[float, float], ...]


@dataclass(frozen=True)
class LiveView:
    """The live re-prediction from one fix, in the units the screen shows: built by the prediction service
    from its typed result (``console.predictions.live_view``), never parsed back from JSON."""

    report_time: datetime
    report_alt_m: float
    landing_lat: float
    landing_lon: float
    landing_time: datetime
    remaining_drift_km: float
    sigma_parallel_km: float
    sigma_perpendicular_km: float
    measured_rate_factor: float | None
    """None until two fixes measured one leg."""
    legs_used: int
    correction: str
    """Which measured correction the prediction used, in words."""
    outline_2sigma: Points
    """(lon, lat), what the map draws."""
    path: Points
    sigma_major_km: float = math.nan
    sigma_minor_km: float = math.nan
    major_axis_bearing_deg: float = 0.0
    """The ellipse's principal axes (1σ) and the major one's bearing, for the recovery picture's 1σ/2σ."""


@dataclass(frozen=True)
class Descent:
    """The track from a capsule's fixes, its landing once the fixes show one, and else the live view."""

    track: tuple[TrackPoint, ...] = ()
    landing: LandingEstimate | None = None
    live: LiveView | None = None
    live_error: str | None = None
    """Why the live re-prediction failed (shown, never hidden behind the forecast)."""

    @property
    def descending(self) -> bool:
        """Fixes arriving and no landing seen: the live re-prediction is what the team drives to."""
        return self.landing is None and bool(self.track)


@dataclass(frozen=True)
class DropView:
    """A PARACHUTE queued without landed evidence, when release B opens, and that in words."""

    override: ParachuteOverride
    opens_at: datetime | None
    words: str


@dataclass(frozen=True)
class RecoveryView:
    """Everything the recovery screen shows of one capsule that comes from the store."""

    capsule: str
    descent: Descent
    settings: CommandedSettings | None
    """What sounder, interval and parachute were commanded to; None where nothing is known (a replay)."""
    drop: DropView | None = None


def follow_descent(reports: Sequence[StoredReport], capsule: str, live: LiveSource | None) -> Descent:
    """Reports → track → landing → live re-prediction (only while descending, and only with weather)."""
    return descent_along(tuple(track_from_reports(list(reports))), capsule, live)


def descent_along(track: tuple[TrackPoint, ...], capsule: str, live: LiveSource | None) -> Descent:
    """Track → landing → live re-prediction: a replay's track comes from its recorded reports."""
    landing = detect_landing(list(track))
    if landing is not None or not track or live is None:
        return Descent(track, landing)
    try:
        view = live(capsule, track)
    except PredictorError as exc:
        return Descent(track, landing, live_error=str(exc))
    return Descent(track, landing, view)


def recovery_from(
    capsule: str,
    reports: Sequence[StoredReport],
    commands: Sequence[Command],
    parachutes: Sequence[AuditRecord],
    live: LiveSource | None,
) -> RecoveryView:
    """The recovery from what the store holds of the capsule: its reports, MT commands and PARACHUTE audit."""
    override = parachute_override(capsule, parachutes, commands)
    drop = DropView(override, *drop_schedule(override, reports)) if override is not None else None
    return RecoveryView(
        capsule, follow_descent(reports, capsule, live), commanded_settings(commands, reports), drop
    )


def recovery_view(iridium: IridiumOps, capsule: str, live: LiveSource | None) -> RecoveryView:
    """The capsule's recovery as the store has it now: read in a worker, shown by the screen as it is."""
    return recovery_from(
        capsule,
        iridium.stored_reports(capsule),
        iridium.commands(capsule),
        iridium.state.store.audit(capsule, action="mt.parachute"),
        live,
    )

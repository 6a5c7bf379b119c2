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

Which reports are evidence at all (anyone who can reach the receiver can POST an unsigned report):

* when any report of the capsule carries a verified Ground Control JWT, only JWT-verified reports
  count: with ``mo.require_jwt = false`` anyone who can reach the receiver can post a report, and a
  signed track shows the key is in use. When none is verified (no key configured, or email imports
  only) the reports are used, but the evidence says so loudly (``verified`` is False) and the gate
  then asks for a second operator, as for an override;
* a fix dated after its own arrival (beyond ``FUTURE_LEEWAY_S`` of clock skew) is refused: the
  capsule takes its fix before the session that sends it;
* a jump between consecutive fixes faster than anything the capsule can do (``MAX_VERTICAL_MS`` up
  or down, ``MAX_HORIZONTAL_MS`` across) is not a landing: the evidence is refused and names the jump.
"""

from __future__ import annotations

from collections.abc import Sequence
from dataclasses import dataclass, field, replace
from datetime import timedelta
from typing import Any

from drs_link.iridium.recovery import (
    LandingWatch,
    TrackPoint,
    detect_landing,
    distance_bearing,
    track_from_reports,
    track_point,
)
from drs_link.iridium.reports import StoredReport

GROUND_TOLERANCE_M = 150.0
"""GNSS altitude error (~±30 m) plus DEM error (SRTM ~±16 m, coarse DEMs ~±100 m in relief)."""
FUTURE_LEEWAY_S = 10.0
"""Clock skew allowed between the capsule's GNSS time and the ground's arrival stamp (NTP keeps both
within a second; the fix is taken before the session, so a real fix is never later than its arrival)."""
MAX_VERTICAL_MS = 300.0
"""Faster than a capsule falls without its parachute; the 30 real flight logs reach 43 m/s."""
MAX_HORIZONTAL_MS = 200.0
"""Twice the strongest jet stream; the 30 real flight logs reach 70 m/s between fixes."""


@dataclass(frozen=True)
class LandedEvidence:
    on_ground: bool
    summary: str
    """One line an operator reads before typing a name: the evidence, or what is missing."""
    last_fix: TrackPoint | None
    verified: bool = False
    """Every fix the verdict rests on came in a delivery with a verified Ground Control JWT."""
    trusted: dict[str, Any] = field(default_factory=dict)
    """What the verdict trusted and what it left out, by count and report id: kept in the audit."""

    def audit(self) -> dict[str, Any]:
        """What the audit record keeps: the verdict, its reason, what it trusted and the last fix."""
        fix = self.last_fix
        return {
            "on_ground": self.on_ground,
            "evidence": self.summary,
            "verified": self.verified,
            "trusted": self.trusted,
            "last_fix": None if fix is None else {
                "time": fix.time.isoformat().replace("+00:00", "Z"), "lat": fix.lat, "lon": fix.lon,
                "alt_m": fix.alt_m, "speed_ms": fix.speed_ms,
            },
        }  # fmt: skip


def _describe(fix: TrackPoint) -> str:
    return f"{fix.time:%H:%M:%S}Z at {fix.alt_m:,.0f} m, {fix.speed_ms:.1f} m/s"


def _trusted_reports(reports: Sequence[StoredReport]) -> tuple[list[StoredReport], bool, dict[str, Any]]:
    """The reports the verdict may rest on, whether they are all JWT-verified, and what was left out."""
    with_fix = [r for r in reports if track_point(r) is not None]
    verified = any(r.delivery.jwt_verified for r in with_fix)
    unverified = [r.id for r in with_fix if verified and not r.delivery.jwt_verified]
    future = [r.id for r in with_fix if _future_dated(r)]
    left_out = set(unverified) | set(future)
    kept = [r for r in with_fix if r.id not in left_out]
    trusted = {
        "reports": len(kept),
        "only_jwt_verified": verified,
        "report_ids": [r.id for r in kept],
        "ignored_unverified": unverified,
        "ignored_future_dated": future,
    }
    return kept, verified, trusted


def _future_dated(stored: StoredReport) -> bool:
    """The report's fix is dated after its own arrival, beyond the clock leeway."""
    return stored.time > stored.delivery.received_utc + timedelta(seconds=FUTURE_LEEWAY_S)


def _jump(track: list[TrackPoint]) -> str | None:
    """The first move between consecutive fixes the capsule cannot make, described; None if none."""
    for before, after in zip(track, track[1:], strict=False):
        seconds = max((after.time - before.time).total_seconds(), 1.0)
        vertical = (after.alt_m - before.alt_m) / seconds
        across = distance_bearing(before.lat, before.lon, after.lat, after.lon)[0] / seconds
        if abs(vertical) > MAX_VERTICAL_MS or across > MAX_HORIZONTAL_MS:
            return (
                f"implausible jump from {_describe(before)} to {_describe(after)}: "
                f"{abs(after.alt_m - before.alt_m) / 1000:.1f} km {'down' if vertical < 0 else 'up'} and "
                f"{across * seconds / 1000:.1f} km across in {seconds:.0f} s "
                f"(limits {MAX_VERTICAL_MS:.0f} m/s vertical, {MAX_HORIZONTAL_MS:.0f} m/s horizontal)"
            )
    return None


def landed_evidence(reports: Sequence[StoredReport], ground_m: float | None = None) -> LandedEvidence:
    """The evidence that the capsule is on the ground, from the reports it may trust (module docstring;
    ``ground_m``: terrain height at the landing, when a DEM is known)."""
    kept, verified, trusted = _trusted_reports(reports)
    evidence = _evidence(track_from_reports(kept), ground_m)
    left_out = len(trusted["ignored_unverified"]) + len(trusted["ignored_future_dated"])
    notes = []
    if trusted["ignored_unverified"]:
        notes.append(f"{len(trusted['ignored_unverified'])} report(s) without a verified JWT ignored")
    if trusted["ignored_future_dated"]:
        notes.append(f"{len(trusted['ignored_future_dated'])} fix(es) dated after their arrival ignored")
    source = (
        f"from {trusted['reports']} JWT-verified report(s)" if verified
        else f"UNVERIFIED: from {trusted['reports']} report(s) none of which carries a verified JWT"
    )  # fmt: skip
    summary = evidence.summary
    if trusted["reports"] or left_out:
        summary += f" [{'; '.join([source, *notes])}]"
    return replace(evidence, summary=summary, verified=verified, trusted=trusted)


def _evidence(track: list[TrackPoint], ground_m: float | None) -> LandedEvidence:
    if not track:
        return LandedEvidence(False, "no position report with a GNSS fix yet", None)
    last = track[-1]
    if (jump := _jump(track)) is not None:
        return LandedEvidence(False, f"NOT LANDED: {jump}; the track is not trusted", last)
    landing = detect_landing(track)
    if landing is None:
        trend = ""
        if len(track) >= 2:
            before = track[-2]
            seconds = (last.time - before.time).total_seconds()
            if seconds > 0:
                rate = (last.alt_m - before.alt_m) / seconds
                trend = (
                    f", {'falling' if rate < 0 else 'climbing'} {abs(rate):.1f} m/s since the report before"
                )
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
        self._points: list[tuple[TrackPoint, bool]] = []
        """Every fix not dated after its arrival, and whether its report was JWT-verified."""
        self._verified_only = False
        self._jumped = False

    def add(self, stored: StoredReport) -> bool:
        """The same trust as ``landed_evidence``: the first verified report drops the unverified ones
        (the track is rebuilt once), future-dated fixes are left out, and a jump ends the landing."""
        point = track_point(stored)
        if point is not None and not _future_dated(stored):
            verified = stored.delivery.jwt_verified
            self._points.append((point, verified))
            if verified and not self._verified_only:
                self._verified_only = True
                self._watch, self._jumped = LandingWatch(), False
                for earlier, trusted in self._points:
                    if trusted:
                        self._feed(earlier)
            elif verified or not self._verified_only:
                self._feed(point)
        return self._watch.on_site and not self._jumped

    def _feed(self, point: TrackPoint) -> None:
        track = self._watch.track
        if track and _jump([track[-1], point]) is not None:
            self._jumped = True
        self._watch.add(point)

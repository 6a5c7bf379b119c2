"""Where the capsule is on the ground, how sure we are, and how far it is from the recovery team.

Landing is the first fix after the peak at which the capsule stops descending and stops moving.
The landing site is the mean of the fixes that stay there, after rejecting outliers; the first
fix that leaves for good (the capsule in a car or a boat) ends the set, so a track that goes on
after recovery still gives the landing site, not the driveway at home (drs_protocol.md 5.3).
"""

from __future__ import annotations

import math
import statistics
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from drs_link.iridium.reports import StoredReport
from drs_link.positions import (
    GPSD_ADDRESS as GPSD_ADDRESS,
    parse_position as parse_position,
    read_gpsd_position as read_gpsd_position,
)
from predictor.geofiles import DEMO_LABEL, write_text
from predictor.prediction import GEOD

MIN_DESCENT_M = 500.0
"""A landing must come after the capsule has fallen at least this far from its peak."""
STEADY_VERTICAL_MS = 1.5
"""Under the parachute the capsule falls 3-8 m/s; GNSS altitude noise on the ground is below this."""
STEADY_SPEED_MS = 3.0
CLUSTER_RADIUS_M = 300.0
"""Fixes farther than this from the landing cluster mean the capsule has been moved (or drifts)."""
OUTLIER_FLOOR_M = 10.0
RAYLEIGH_MEDIAN = 1.1774
"""Median of the radial error of a 2-D Gaussian, in sigmas: turns a median distance into a sigma."""


@dataclass(frozen=True)
class TrackPoint:
    time: datetime
    lat: float
    lon: float
    alt_m: float
    speed_ms: float


@dataclass(frozen=True)
class LandingEstimate:
    lat: float
    lon: float
    alt_m: float
    std_m: float
    """Scatter of a single kept fix about the mean: 1 sigma per horizontal axis, sqrt(Σd²/(2(n-1)))."""
    count: int
    rejected: int
    landed_at: datetime
    last_fix_at: datetime
    moved_at: datetime | None
    """When the capsule left the landing site (recovered, or drifting), if the track says so."""


def track_point(stored: StoredReport) -> TrackPoint | None:
    """The report's GNSS fix as a track point (no-fix and rejected reports carry none)."""
    report = stored.report
    if report is None or report.fix is None:
        return None
    fix = report.fix
    return TrackPoint(fix.time, fix.lat, fix.lon, fix.alt_m, fix.speed_ms)


def track_from_reports(reports: list[StoredReport]) -> list[TrackPoint]:
    """The GNSS fixes of accepted reports, in time order."""
    points = [point for r in reports if (point := track_point(r)) is not None]
    return sorted(points, key=lambda p: p.time)


def _distance_m(a: TrackPoint, lat: float, lon: float) -> float:
    return float(GEOD.inv(a.lon, a.lat, lon, lat)[2])


def _still(here: TrackPoint, after: TrackPoint) -> bool:
    """The fix is itself still and is followed by no climb, fall or travel.

    Rates are taken between fixes, not from one fix, because a landing between two distant fixes
    averages a fast fall into a slow one; the fix's own speed rules that out. A lone last fix can
    not be told from a slow moment of the descent, so landing needs one more fix after it.
    """
    seconds = (after.time - here.time).total_seconds()
    if seconds <= 0:
        return False
    vertical = abs(after.alt_m - here.alt_m) / seconds
    horizontal = _distance_m(here, after.lat, after.lon) / seconds
    return here.speed_ms <= STEADY_SPEED_MS and vertical < STEADY_VERTICAL_MS and horizontal < STEADY_SPEED_MS


def _centre(points: list[TrackPoint]) -> tuple[float, float]:
    return statistics.median(p.lat for p in points), statistics.median(p.lon for p in points)


class LandingWatch:
    """The landing rule, fed one fix at a time: what ``detect_landing`` says of the fixes so far.

    Why fed: the console gives every report the verdict on the reports up to it, and re-running the
    rule on each prefix was quadratic (0.24 s for 400 reports at start-up, growing with the square).
    Each fix settles only what it can: a new peak restarts the search; otherwise the fix pair it
    completes is the one new landing candidate, and the site's walk places every fix it can already
    decide (a fix away from the site is an outlier only if the fix after it comes back).
    """

    def __init__(self) -> None:
        self.track: list[TrackPoint] = []
        self._peak = 0
        self._start: int | None = None
        """The landing: the first fix after the peak (fallen ``MIN_DESCENT_M``) that is still."""
        self._cluster: list[TrackPoint] = []
        self._outliers = 0
        self._next = 0
        """The first fix after the landing that the walk has not placed yet."""
        self._moved_at: datetime | None = None

    def add(self, point: TrackPoint) -> None:
        track = self.track
        track.append(point)
        if point.alt_m > track[self._peak].alt_m:
            self._peak, self._start = len(track) - 1, None
            return
        if self._start is None:
            candidate = len(track) - 2
            if (
                candidate > self._peak
                and track[self._peak].alt_m - track[candidate].alt_m >= MIN_DESCENT_M
                and _still(track[candidate], point)
            ):
                self._start, self._next = candidate, candidate + 1
                self._cluster, self._outliers, self._moved_at = [track[candidate]], 0, None
        if self._start is not None:
            self._walk()

    def _walk(self) -> None:
        track, cluster = self.track, self._cluster
        while self._moved_at is None and self._next < len(track):
            j = self._next
            lat, lon = _centre(cluster)
            if _distance_m(track[j], lat, lon) <= CLUSTER_RADIUS_M:
                cluster.append(track[j])
            elif j + 1 == len(track):
                return  # away: moved, unless the next fix comes back to the site
            elif _distance_m(track[j + 1], lat, lon) <= CLUSTER_RADIUS_M:
                self._outliers += 1
            else:
                self._moved_at = track[j].time
            self._next += 1

    @property
    def on_site(self) -> bool:
        """Landed, and no fix since has left the site: ``estimate()`` is not None and has not moved."""
        return self._start is not None and self._moved_at is None and self._next == len(self.track)

    def estimate(self) -> LandingEstimate | None:
        """The landing estimate, or None while the capsule has not (visibly) landed."""
        if self._start is None:
            return None
        moved_at = self._moved_at
        if moved_at is None and self._next < len(self.track):
            moved_at = self.track[self._next].time  # the last fix is away from the site
        cluster = self._cluster
        lat, lon = _centre(cluster)
        distances = [_distance_m(p, lat, lon) for p in cluster]
        limit = max(3.0 * statistics.median(distances) / RAYLEIGH_MEDIAN, OUTLIER_FLOOR_M)
        kept = [p for p, d in zip(cluster, distances, strict=True) if d <= limit]
        mean_lat = statistics.fmean(p.lat for p in kept)
        mean_lon = statistics.fmean(p.lon for p in kept)
        spread = [_distance_m(p, mean_lat, mean_lon) ** 2 for p in kept]
        std = math.sqrt(sum(spread) / (len(kept) - 1) / 2.0) if len(kept) > 1 else float("nan")
        return LandingEstimate(
            lat=mean_lat,
            lon=mean_lon,
            alt_m=statistics.fmean(p.alt_m for p in kept),
            std_m=std,
            count=len(kept),
            rejected=self._outliers + len(cluster) - len(kept),
            landed_at=self.track[self._start].time,
            last_fix_at=cluster[-1].time,
            moved_at=moved_at,
        )


def detect_landing(track: list[TrackPoint]) -> LandingEstimate | None:
    """The landing estimate, or None while the capsule has not (visibly) landed."""
    watch = LandingWatch()
    for point in track:
        watch.add(point)
    return watch.estimate()


def distance_bearing(from_lat: float, from_lon: float, to_lat: float, to_lon: float) -> tuple[float, float]:
    """Distance (m) and true bearing (0-360°) from the first point to the second, on WGS84."""
    azimuth, _, distance = GEOD.inv(from_lon, from_lat, to_lon, to_lat)
    return float(distance), float(azimuth) % 360.0


def _hemisphere(value: float, positive: str, negative: str) -> str:
    return f"{abs(value):.5f} {positive if value >= 0 else negative}"


def phone_summary(
    name: str,
    landing: LandingEstimate | None,
    last: TrackPoint | None,
    team: tuple[float, float] | None,
    coarse: tuple[float, float, float, datetime] | None = None,
) -> str:
    """One line for a text message: where it is, how sure, and how far from the team.

    ``coarse`` (lat, lon, CEP m, time) is the Iridium network's estimate, used only while no GNSS
    fix has arrived at all.
    """
    if landing is not None:
        where = f"{_hemisphere(landing.lat, 'N', 'S')} {_hemisphere(landing.lon, 'E', 'W')}"
        sigma = f"±{landing.std_m:.0f} m" if not math.isnan(landing.std_m) else "±? m"
        text = f"{name} on ground {where} {sigma} (n={landing.count})"
        lat, lon = landing.lat, landing.lon
        if landing.moved_at is not None and last is not None and last.time >= landing.moved_at:
            moved, _ = distance_bearing(lat, lon, last.lat, last.lon)
            text += (
                f", MOVED {moved / 1000:.1f} km since {landing.moved_at:%H:%M}Z "
                f"(last {_hemisphere(last.lat, 'N', 'S')} {_hemisphere(last.lon, 'E', 'W')} "
                f"{last.time:%H:%M}Z)"
            )
    elif last is not None:
        where = f"{_hemisphere(last.lat, 'N', 'S')} {_hemisphere(last.lon, 'E', 'W')}"
        text = f"{name} not landed: last fix {where} at {last.alt_m:.0f} m, {last.time:%H:%M}Z"
        lat, lon = last.lat, last.lon
    elif coarse is not None:
        lat, lon, cep_m, moment = coarse
        where = f"{_hemisphere(lat, 'N', 'S')} {_hemisphere(lon, 'E', 'W')}"
        text = (
            f"{name}: no GNSS fix yet; Iridium position {where} ±{cep_m / 1000:.1f} km (CEP), {moment:%H:%M}Z"
        )
    else:
        return f"{name}: no report with a position yet"
    if team is not None:
        distance, bearing = distance_bearing(team[0], team[1], lat, lon)
        text += f", {distance / 1000:.1f} km at {round(bearing) % 360:03d}° from you"
    return text


def _landing_note(landing: LandingEstimate) -> str:
    """How sure the landing site is, in ASCII (handhelds), without a NaN for a single fix."""
    when = f"landed {landing.landed_at:%Y-%m-%d %H:%M}Z"
    if landing.count < 2 or not math.isfinite(landing.std_m):
        return f"{when}; 1 fix kept, too few to estimate the scatter"
    return f"{when}; {landing.count} fixes kept, scatter +/-{landing.std_m:.0f} m (1 sigma)"


def _predicted(name: str, predicted_is_demo: bool) -> str:
    """What the predicted track is called: a prediction on demo weather says so, like every demo output."""
    return f"{name} predicted ({DEMO_LABEL})" if predicted_is_demo else f"{name} predicted"


def write_gpx(
    path: str | Path,
    name: str,
    measured: list[TrackPoint],
    predicted: list[tuple[float, float, float]],
    landing: LandingEstimate | None,
    *,
    predicted_is_demo: bool = False,
) -> Path:
    """``gpx_text`` written to ``path`` (``-``: standard output)."""
    return write_text(path, gpx_text(name, measured, predicted, landing, predicted_is_demo), "GPX")


def gpx_text(
    name: str,
    measured: list[TrackPoint],
    predicted: list[tuple[float, float, float]],
    landing: LandingEstimate | None,
    predicted_is_demo: bool = False,
) -> str:
    """The landing (or, before one, the last fix) and the predicted landing as waypoints, and both tracks.

    ``predicted`` is (lat, lon, alt) from release to landing, so its last point is the predicted landing.
    """
    from predictor.geofiles import gpx  # at use, as kml below

    waypoints = []
    if landing is not None:
        waypoints.append(
            gpx.Waypoint(landing.lat, landing.lon, landing.alt_m, gpx.short_name(name, "LAND"),
                         gpx.LANDING_SYMBOL, f"{name} landing: {_landing_note(landing)}", landing.landed_at)
        )  # fmt: skip
    elif measured:
        last = measured[-1]
        waypoints.append(
            gpx.Waypoint(last.lat, last.lon, last.alt_m, gpx.short_name(name, "LAST FIX"),
                         gpx.LANDING_SYMBOL, f"{name} last fix, not landed", last.time)
        )  # fmt: skip
    if predicted:
        lat, lon, alt = predicted[-1]
        label = "DEMO PRED LAND" if predicted_is_demo else "PRED LAND"
        waypoints.append(
            gpx.Waypoint(lat, lon, alt, gpx.short_name(name, label), gpx.PREDICTED_LANDING_SYMBOL,
                         f"{_predicted(name, predicted_is_demo)} landing")
        )  # fmt: skip
    tracks = [
        (f"{name} measured", [gpx.TrackPoint(p.lat, p.lon, p.alt_m, p.time) for p in measured]),
        (_predicted(name, predicted_is_demo), [gpx.TrackPoint(lat, lon, alt) for lat, lon, alt in predicted]),
    ]
    return gpx.to_gpx(f"{name} recovery", waypoints, tracks)


def write_kml(
    path: str | Path,
    name: str,
    measured: list[TrackPoint],
    predicted: list[tuple[float, float, float]],
    landing: LandingEstimate | None,
    *,
    predicted_is_demo: bool = False,
) -> Path:
    """``kml_text`` written to ``path`` (``-``: standard output)."""
    return write_text(path, kml_text(name, measured, predicted, landing, predicted_is_demo), "KML")


def kml_text(
    name: str,
    measured: list[TrackPoint],
    predicted: list[tuple[float, float, float]],
    landing: LandingEstimate | None,
    predicted_is_demo: bool = False,
) -> str:
    """The measured and predicted tracks at their altitudes, the landing and the predicted landing."""
    # Imported here: fastkml, shapely and antimeridian cost ~80 ms, and this module is on the import
    # path of every drs command through the PARACHUTE landed gate, `drs --help` included.
    from predictor.geofiles import kml, line_parts, position

    styles = [kml.style("measured", "ff0000ff", width=3), kml.style("predicted", "ffff0000", width=3)]
    tracks = (
        (f"{name} measured", "measured", [(p.lon, p.lat, p.alt_m) for p in measured]),
        (_predicted(name, predicted_is_demo), "predicted", [(lon, lat, alt) for lat, lon, alt in predicted]),
    )
    contents: list[kml.Feature] = [
        kml.line(label, line_parts(points), style, absolute=True) for label, style, points in tracks if points
    ]
    if landing is not None:
        contents.append(
            kml.point(
                f"{name} landing", position((landing.lon, landing.lat)), description=_landing_note(landing)
            )
        )
    if predicted:
        lat, lon, _ = predicted[-1]
        where = position((lon, lat))
        contents.append(kml.point(f"{_predicted(name, predicted_is_demo)} landing", where, "predicted"))
    title = f"{name} recovery" + (f" (prediction on {DEMO_LABEL})" if predicted_is_demo else "")
    return kml.document(title, f"{name}: measured and predicted tracks", styles, contents)

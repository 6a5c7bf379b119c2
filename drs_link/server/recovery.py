"""The recovery service: ``drs recovery`` read by the server from the reports it holds, for whichever
operator the kernel says is connected.

It reads; it never changes the store. What the operator's process does not have (the reports, and for
a map the live re-prediction on the weather) is computed here and answered in typed values; what is the
operator's own (their position from their gpsd, their predicted track's file, the files written) stays
in their process: the GPX and KML come back as text for the client to write, so they are the operator's.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from pathlib import Path

from drs_link.iridium import (
    LandingEstimate,
    TrackPoint,
    detect_landing,
    distance_bearing,
    gpx_text,
    kml_text,
    phone_summary,
    track_from_reports,
)
from drs_link.ops import Descent, LiveSource, OpsState, follow_descent, iso_utc
from drs_link.server.desks import Desks
from drs_link.server.paths import readable_path, readable_tree
from drs_link.server.peers import Peer
from drs_link.server.protocol import (
    DescentView,
    FixView,
    IridiumPosition,
    LandingFields,
    LastFixFields,
    LiveLandingView,
    Position,
    RecoveryDocument,
    RecoveryReadout,
    RecoveryRequest,
)

LiveFor = Callable[[list[Path], Path | None, OpsState], LiveSource]
"""The live re-prediction on GRIB2 files (and a DEM directory for the ground): the console's prediction
service, which the command line hands in (``drs_link`` cannot import the console)."""


class RecoveryService:
    def __init__(self, desks: Desks, live_for: LiveFor | None = None) -> None:
        self.desks = desks
        self.live_for = live_for

    def readout(self, peer: Peer, name: str, request: RecoveryRequest) -> RecoveryReadout:
        """Reports → track → landing → the summary line, the ``--json`` document, the GPX/KML text asked
        for, and for a map the descent (with the live re-prediction when weather is given)."""
        weather = [readable_path(peer.uid, w) for w in request.weather]
        dem = readable_tree(peer.uid, request.dem) if request.dem is not None else None
        iridium = self.desks.desk(peer).iridium
        capsule = iridium.state.config.capsule(name).name
        reports = iridium.reports_of(name)
        track = track_from_reports(reports)
        landing = detect_landing(track)
        coarse_at = None
        if reports and (position := reports[-1].iridium_position()) is not None:
            coarse_at = (*position, reports[-1].session_time)
        coarse = IridiumPosition(*coarse_at[:3], iso_utc(coarse_at[3])) if coarse_at is not None else None
        team = request.team
        last = track[-1] if track else None
        summary = phone_summary(capsule, landing, last, team, coarse_at)
        predicted = [(lat, lon, alt) for lat, lon, alt in request.predicted]
        demo = request.predicted_is_demo
        descent = None
        if request.descent:
            live = (
                self.live_for(weather, dem, iridium.state) if weather and self.live_for is not None else None
            )
            descent = descent_view(follow_descent(reports, capsule, live))
        at = (landing.lat, landing.lon) if landing else (last.lat, last.lon) if last else None
        return RecoveryReadout(
            document(capsule, summary, landing, last, team, coarse),
            landed_line(landing) if landing is not None else None,
            Position(*at) if at is not None else None,
            gpx_text(capsule, track, predicted, landing, demo) if request.gpx else None,
            kml_text(capsule, track, predicted, landing, demo) if request.kml else None,
            descent,
        )


def landed_line(landing: LandingEstimate) -> str:
    return (
        f"landed {landing.landed_at:%Y-%m-%d %H:%M:%S}Z at {landing.alt_m:.0f} m; "
        f"{landing.count} fixes kept, {landing.rejected} rejected; "
        f"last on site {landing.last_fix_at:%H:%M:%S}Z"
    )


def document(
    capsule: str,
    summary: str,
    landing: LandingEstimate | None,
    last: TrackPoint | None,
    team: tuple[float, float] | None,
    coarse: IridiumPosition | None,
) -> RecoveryDocument:
    """``drs recovery --json``: the distance and bearing are from the team to the best position there is
    (the landing, else the last fix, else Iridium's coarse one)."""
    landed = None
    if landing is not None:
        landed = LandingFields(
            landing.lat, landing.lon, landing.alt_m, None if math.isnan(landing.std_m) else landing.std_m,
            landing.count, landing.rejected, iso_utc(landing.landed_at), iso_utc(landing.last_fix_at),
            iso_utc(landing.moved_at) if landing.moved_at else None,
        )  # fmt: skip
    last_fix = None
    if last is not None:
        last_fix = LastFixFields(iso_utc(last.time), last.lat, last.lon, last.alt_m, last.speed_ms)
    best = (
        (landing.lat, landing.lon) if landing else (last.lat, last.lon) if last else
        (coarse.lat, coarse.lon) if coarse else None
    )  # fmt: skip
    distance = bearing = None
    if team is not None and best is not None:
        distance, bearing = distance_bearing(team[0], team[1], best[0], best[1])
    return RecoveryDocument(
        capsule, summary, landed, last_fix, coarse, Position(*team) if team is not None else None,
        distance, bearing,
    )  # fmt: skip


def descent_view(descent: Descent) -> DescentView:
    """The descent as the recovery map draws it."""
    live = descent.live
    landing = descent.landing
    return DescentView(
        tuple(FixView(p.time, p.lat, p.lon, p.alt_m) for p in descent.track),
        Position(landing.lat, landing.lon) if landing is not None else None,
        None if live is None else LiveLandingView(
            live.landing_lat, live.landing_lon, live.landing_time, live.correction, live.sigma_major_km,
            live.sigma_minor_km, live.major_axis_bearing_deg,
        ),
        descent.live_error,
    )  # fmt: skip

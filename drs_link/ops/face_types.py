"""The values and catalogue the faces show and compose, handed on from the rooms behind the operations layer.

Why: the console and the ``drs`` commands import ``drs_link.ops`` and nothing below it (the wall in
docs/architecture.md), yet an operator composes an MT from the catalogue, reads a command's state and a
report's time. These are
values, not actions: every action on them (send, plan, resolve, store) is a method of one of an operator's concerns (``operator_ops``).
The recovery helpers (a track from the reports, its landing, the phone line, the GPX/KML files, the
Iridium health) are pure functions of reports a face already holds, so they are handed on here too.
"""

from drs_link.iridium import (
    CATALOGUE,
    FLUSH_WARNING,
    LISTED,
    PARACHUTE,
    Command,
    CommandedSettings,
    Hazard,
    LandedEvidence,
    LandingEstimate,
    MtCommand,
    MtComposer,
    MtMessage,
    ParachutePlan,
    StoredReport,
    TrackPoint,
    assess,
    by_name,
    detect_landing,
    distance_bearing,
    export_track,
    lifecycle as lc,
    parse_hhmm,
    parse_position,
    phone_summary,
    read_gpsd_position,
    track_from_reports,
    write_gpx,
    write_kml,
)
from drs_link.store import AuditRecord, iso_utc, utc_now

QUEUED = lc.QUEUED
"""An MT the gateway accepted: what ``drs mt send`` exits 0 on."""
RETRY_WARNING = lc.RETRY_WARNING
"""What a face prints before sending the text of a command whose delivery is still unknown."""

__all__ = [
    "CATALOGUE",
    "FLUSH_WARNING",
    "LISTED",
    "PARACHUTE",
    "QUEUED",
    "RETRY_WARNING",
    "AuditRecord",
    "Command",
    "CommandedSettings",
    "Hazard",
    "LandedEvidence",
    "LandingEstimate",
    "MtCommand",
    "MtComposer",
    "MtMessage",
    "ParachutePlan",
    "StoredReport",
    "TrackPoint",
    "assess",
    "by_name",
    "detect_landing",
    "distance_bearing",
    "export_track",
    "iso_utc",
    "utc_now",
    "parse_hhmm",
    "parse_position",
    "phone_summary",
    "read_gpsd_position",
    "track_from_reports",
    "write_gpx",
    "write_kml",
]

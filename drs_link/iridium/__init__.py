"""Iridium SBD ground side: commands to a capsule through RockBLOCK and its position reports back.

Nothing here imports Textual; the console renders what these services report.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from . import commanded as commanded, commands as commands, lifecycle as lifecycle
    from .commanded import CommandedSettings as CommandedSettings, commanded_settings as commanded_settings
    from .commands import (
        CATALOGUE as CATALOGUE,
        LISTED as LISTED,
        PARACHUTE as PARACHUTE,
        Hazard as Hazard,
        MtCommand as MtCommand,
        MtEffect as MtEffect,
        apply_mt as apply_mt,
        by_name as by_name,
        is_command as is_command,
        parse_hhmm as parse_hhmm,
        read_text as read_text,
    )
    from .firmware import GnssFix as GnssFix, format_mo as format_mo
    from .gateway import FLUSH_WARNING as FLUSH_WARNING, RockblockGateway as RockblockGateway
    from .health import assess as assess
    from .importer import import_files as import_files
    from .interval import interval_track as interval_track
    from .landed import (
        LandedEvidence as LandedEvidence,
        LandedVerdicts as LandedVerdicts,
        landed_evidence as landed_evidence,
    )
    from .lifecycle import Command as Command, CommandLifecycle as CommandLifecycle
    from .mo import Fix as Fix, parse_hex as parse_hex
    from .mt import MtComposer as MtComposer, MtMessage as MtMessage
    from .parachute import (
        DEFAULT_SESSION_DELAY as DEFAULT_SESSION_DELAY,
        ParachutePlan as ParachutePlan,
        plan_parachute as plan_parachute,
    )
    from .recovery import (
        LandingEstimate as LandingEstimate,
        TrackPoint as TrackPoint,
        detect_landing as detect_landing,
        distance_bearing as distance_bearing,
        gpx_text as gpx_text,
        kml_text as kml_text,
        parse_position as parse_position,
        phone_summary as phone_summary,
        read_gpsd_position as read_gpsd_position,
        track_from_reports as track_from_reports,
        write_gpx as write_gpx,
        write_kml as write_kml,
    )
    from .reports import ReportStore as ReportStore, StoredReport as StoredReport
    from .track_export import export_track as export_track, track_csv as track_csv
    from .webhook import MoHttpServer as MoHttpServer, MoReceiver as MoReceiver

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "commanded": "commanded",
        "commands": "commands",
        "lifecycle": "lifecycle",
        "CATALOGUE": "commands",
        "Command": "lifecycle",
        "CommandLifecycle": "lifecycle",
        "CommandedSettings": "commanded",
        "FLUSH_WARNING": "gateway",
        "GnssFix": "firmware",
        "Hazard": "commands",
        "LISTED": "commands",
        "LandedEvidence": "landed",
        "LandedVerdicts": "landed",
        "LandingEstimate": "recovery",
        "MoHttpServer": "webhook",
        "MoReceiver": "webhook",
        "MtCommand": "commands",
        "MtComposer": "mt",
        "MtEffect": "commands",
        "MtMessage": "mt",
        "PARACHUTE": "commands",
        "ParachutePlan": "parachute",
        "DEFAULT_SESSION_DELAY": "parachute",
        "ReportStore": "reports",
        "RockblockGateway": "gateway",
        "StoredReport": "reports",
        "TrackPoint": "recovery",
        "apply_mt": "commands",
        "assess": "health",
        "by_name": "commands",
        "commanded_settings": "commanded",
        "detect_landing": "recovery",
        "distance_bearing": "recovery",
        "export_track": "track_export",
        "format_mo": "firmware",
        "gpx_text": "recovery",
        "import_files": "importer",
        "interval_track": "interval",
        "is_command": "commands",
        "kml_text": "recovery",
        "landed_evidence": "landed",
        "parse_hex": "mo",
        "Fix": "mo",
        "parse_hhmm": "commands",
        "parse_position": "recovery",
        "phone_summary": "recovery",
        "plan_parachute": "parachute",
        "read_gpsd_position": "recovery",
        "read_text": "commands",
        "track_csv": "track_export",
        "track_from_reports": "recovery",
        "write_gpx": "recovery",
        "write_kml": "recovery",
    },
)

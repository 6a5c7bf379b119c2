"""Iridium SBD ground side: commands to a capsule through RockBLOCK and its position reports back.

Nothing here imports Textual; the console renders what these services report.
"""

from predictor.lazy_door import lazy_door

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "Command": "lifecycle",
        "CommandLifecycle": "lifecycle",
        "CommandedSettings": "commanded",
        "FLUSH_WARNING": "gateway",
        "GnssFix": "firmware",
        "LandedVerdicts": "landed",
        "LandingEstimate": "recovery",
        "MoHttpServer": "webhook",
        "MoReceiver": "webhook",
        "MtComposer": "mt",
        "MtEffect": "firmware",
        "MtMessage": "mt",
        "ParachutePlan": "parachute",
        "ReportStore": "reports",
        "RockblockGateway": "gateway",
        "StoredReport": "reports",
        "TrackPoint": "recovery",
        "apply_mt": "firmware",
        "assess": "health",
        "commanded_settings": "commanded",
        "detect_landing": "recovery",
        "distance_bearing": "recovery",
        "export_track": "track_export",
        "format_mo": "firmware",
        "import_files": "importer",
        "interval_track": "interval",
        "landed_evidence": "landed",
        "parse_hex": "mo",
        "parse_hhmm": "mt",
        "parse_position": "recovery",
        "phone_summary": "recovery",
        "plan_parachute": "parachute",
        "read_gpsd_position": "recovery",
        "track_from_reports": "recovery",
        "write_gpx": "recovery",
        "write_kml": "recovery",
    },
)

"""The operations layer: every safety rule, below any screen, for the CLI and the console alike.

``capsule`` is the release state machine; ``arming`` ARM then FIRE; ``gonogo`` the poll before ARM;
``checklist`` and ``procedure`` the procedures as data; ``approval`` the second operator and
``identity`` which login is another person; ``authorize`` the PARACHUTE gate, ``override`` what stays
on screen after it was overridden; ``telemetry``, ``fleet``, ``staleness`` and ``origin`` what is known
of each capsule and how old it is; ``session`` a console that ends without quitting; and
``operations`` the console's engine without a screen.
"""

from predictor.lazy_door import lazy_door

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ACTIONS": "approval",
        "Approval": "approval",
        "ApprovalBook": "approval",
        "ArmState": "arming",
        "ArmingController": "arming",
        "BalloonSample": "telemetry",
        "CapsuleTelemetry": "fleet",
        "Checklist": "checklist",
        "ChecklistRun": "checklist",
        "Contour": "telemetry",
        "FleetState": "fleet",
        "Freshness": "staleness",
        "GnssSample": "telemetry",
        "GoNoGoReport": "gonogo",
        "LinkSample": "telemetry",
        "Login": "approval",
        "MISSING_TEXT": "staleness",
        "Operations": "operations",
        "PROCEDURE_DIR": "checklist",
        "PredictionSample": "telemetry",
        "PredictionStatus": "telemetry",
        "Reading": "staleness",
        "ParachuteOverride": "override",
        "ReleaseOrigin": "origin",
        "ReleaseSample": "telemetry",
        "ReleaseState": "capsule",
        "ReleaseStateMachine": "capsule",
        "ReportSample": "telemetry",
        "STALE_GLYPH": "staleness",
        "Sample": "telemetry",
        "StepKind": "checklist",
        "StepState": "checklist",
        "StorageSample": "telemetry",
        "SyncSample": "telemetry",
        "TelemetryRecord": "telemetry",
        "TelemetryRecorder": "telemetry",
        "Verdict": "gonogo",
        "WAIVABLE": "gonogo",
        "WAIVER_REASON_MAX": "gonogo",
        "approved": "approval",
        "authorize_mt": "authorize",
        "carries_parachute": "authorize",
        "complete_command": "checklist",
        "complete_mt_steps": "procedure",
        "current_login": "approval",
        "drop_schedule": "override",
        "after_drop": "override",
        "evaluate": "gonogo",
        "format_age": "staleness",
        "load_checklists": "checklist",
        "parachute_override": "override",
        "pending_text": "approval",
        "read_recording": "telemetry",
        "record_as_dict": "capsule",
        "record_loss": "session",
        "record_start": "session",
        "release_origin": "origin",
        "report_position": "operations",
        "take_over_outcome": "capsule",
        "unprotected_ssh_warning": "session",
    },
)

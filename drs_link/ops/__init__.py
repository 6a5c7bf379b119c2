"""The operations layer: every safety rule, below any screen, for the CLI and the console alike.

``capsule`` is the release state machine; ``arming`` ARM then FIRE, in the windows of ``arm_window``;
``gonogo`` the poll before ARM; ``checklist`` and ``procedure`` the procedures as data; ``approval`` the
second operator, one account one person; ``authorize`` the PARACHUTE gate,
``override`` what stays on screen after it was overridden; ``telemetry``, ``fleet``, ``staleness`` and
``origin`` what is known of each capsule and how old it is; ``recovery`` where a dropped capsule is
and is going, ``views`` what the per-capsule screens show, from the store or a replay; ``release_window``
the sweep; ``audit_log`` the audit as History reads it; ``session`` a console that ends without quitting;
``operator_ops`` all one operator may do, its concerns over one ``ops_state``: ``links`` (the capsules'
SSH links), ``release``, ``iridium_ops`` and ``enrolment``; ``typed_text`` the one rule for text an operator types
and ``shown`` for showing another person's; ``brief`` what an approver reads; and ``face_types`` the values below it that the
faces show and compose, so that they import this door alone.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .approval import (
        ACTIONS as ACTIONS,
        Approval as Approval,
        ApprovalBook as ApprovalBook,
        Login as Login,
        approved as approved,
    )
    from .arm_window import ArmWindow as ArmWindow
    from .arming import (
        SECOND_LOGIN_HOWTO as SECOND_LOGIN_HOWTO,
        ArmingController as ArmingController,
        ArmState as ArmState,
        ArmStatus as ArmStatus,
    )
    from .audit_log import (
        HISTORY_ROWS as HISTORY_ROWS,
        AuditLog as AuditLog,
        shown_record as shown_record,
        write_audit_export as write_audit_export,
    )
    from .authorize import (
        authorize_mt as authorize_mt,
        carries_parachute as carries_parachute,
        hazard_of as hazard_of,
    )
    from .capsule import (
        ReleaseRecord as ReleaseRecord,
        ReleaseState as ReleaseState,
        ReleaseStateMachine as ReleaseStateMachine,
        record_as_dict as record_as_dict,
        take_over_outcome as take_over_outcome,
    )
    from .checklist import (
        PROCEDURE_DIR as PROCEDURE_DIR,
        Checklist as Checklist,
        ChecklistRun as ChecklistRun,
        StepKind as StepKind,
        StepRecord as StepRecord,
        StepState as StepState,
        StepStatus as StepStatus,
        complete_command as complete_command,
        load_checklists as load_checklists,
        statuses_of as statuses_of,
        step_records as step_records,
    )
    from .enrolment import Enrolment as Enrolment
    from .face_types import (
        CATALOGUE as CATALOGUE,
        FLUSH_WARNING as FLUSH_WARNING,
        LISTED as LISTED,
        PARACHUTE as PARACHUTE,
        QUEUED as QUEUED,
        RETRY_WARNING as RETRY_WARNING,
        AuditRecord as AuditRecord,
        Command as Command,
        CommandedSettings as CommandedSettings,
        Hazard as Hazard,
        LandedEvidence as LandedEvidence,
        LandingEstimate as LandingEstimate,
        MtCommand as MtCommand,
        MtComposer as MtComposer,
        MtMessage as MtMessage,
        ParachutePlan as ParachutePlan,
        StoredReport as StoredReport,
        TrackPoint as TrackPoint,
        assess as assess,
        by_name as by_name,
        detect_landing as detect_landing,
        distance_bearing as distance_bearing,
        export_track as export_track,
        iso_utc as iso_utc,
        parse_hhmm as parse_hhmm,
        parse_position as parse_position,
        phone_summary as phone_summary,
        read_gpsd_position as read_gpsd_position,
        track_from_reports as track_from_reports,
        utc_now as utc_now,
        write_gpx as write_gpx,
        write_kml as write_kml,
    )
    from .fleet import CapsuleTelemetry as CapsuleTelemetry, FleetState as FleetState
    from .gonogo import (
        WAIVABLE as WAIVABLE,
        WAIVER_REASON_MAX as WAIVER_REASON_MAX,
        ExclusionZone as ExclusionZone,
        GoNoGoReport as GoNoGoReport,
        Verdict as Verdict,
        Waiver as Waiver,
        WaiverBook as WaiverBook,
        evaluate as evaluate,
    )
    from .iridium_ops import IridiumOps as IridiumOps, report_position as report_position
    from .links import CapsuleLinks as CapsuleLinks
    from .operator_ops import OperatorOps as OperatorOps
    from .ops_state import (
        OnPending as OnPending,
        OpsState as OpsState,
        SecondOperator as SecondOperator,
        load_exclusion_zones as load_exclusion_zones,
    )
    from .origin import ReleaseOrigin as ReleaseOrigin, release_origin as release_origin
    from .override import (
        ParachuteOverride as ParachuteOverride,
        after_drop as after_drop,
        drop_schedule as drop_schedule,
        parachute_override as parachute_override,
    )
    from .procedure import complete_mt_steps as complete_mt_steps
    from .recovery import (
        Descent as Descent,
        DropView as DropView,
        LiveSource as LiveSource,
        LiveView as LiveView,
        RecoveryView as RecoveryView,
        descent_along as descent_along,
        follow_descent as follow_descent,
        recovery_view as recovery_view,
    )
    from .release import Predict as Predict, Release as Release
    from .release_window import ReleaseCandidate as ReleaseCandidate, ReleaseWindow as ReleaseWindow
    from .session import (
        SessionLoss as SessionLoss,
        record_loss as record_loss,
        record_start as record_start,
        unprotected_ssh_warning as unprotected_ssh_warning,
    )
    from .staleness import (
        MISSING_TEXT as MISSING_TEXT,
        STALE_GLYPH as STALE_GLYPH,
        Freshness as Freshness,
        Reading as Reading,
        format_age as format_age,
    )
    from .telemetry import (
        BalloonSample as BalloonSample,
        Contour as Contour,
        GnssSample as GnssSample,
        LinkSample as LinkSample,
        PredictionSample as PredictionSample,
        PredictionStatus as PredictionStatus,
        ReleaseSample as ReleaseSample,
        ReportSample as ReportSample,
        Sample as Sample,
        StorageSample as StorageSample,
        SyncSample as SyncSample,
        TelemetryRecord as TelemetryRecord,
        TelemetryRecorder as TelemetryRecorder,
        read_recording as read_recording,
    )
    from .typed_text import shown as shown, typed_text as typed_text
    from .views import (
        IridiumHealthView as IridiumHealthView,
        RecordedViews as RecordedViews,
        ReportRow as ReportRow,
        ViewSource as ViewSource,
        iridium_health_from as iridium_health_from,
    )

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ACTIONS": "approval",
        "HISTORY_ROWS": "audit_log",
        "WaiverBook": "gonogo",
        "iridium_health_from": "views",
        "by_name": "face_types",
        "MtCommand": "face_types",
        "LandedEvidence": "face_types",
        "Hazard": "face_types",
        "CATALOGUE": "face_types",
        "FLUSH_WARNING": "face_types",
        "LISTED": "face_types",
        "PARACHUTE": "face_types",
        "QUEUED": "face_types",
        "RETRY_WARNING": "face_types",
        "Command": "face_types",
        "MtComposer": "face_types",
        "MtMessage": "face_types",
        "ParachutePlan": "face_types",
        "StoredReport": "face_types",
        "iso_utc": "face_types",
        "utc_now": "face_types",
        "parse_hhmm": "face_types",
        "AuditRecord": "face_types",
        "CommandedSettings": "face_types",
        "LandingEstimate": "face_types",
        "TrackPoint": "face_types",
        "assess": "face_types",
        "detect_landing": "face_types",
        "distance_bearing": "face_types",
        "export_track": "face_types",
        "parse_position": "face_types",
        "phone_summary": "face_types",
        "read_gpsd_position": "face_types",
        "track_from_reports": "face_types",
        "write_gpx": "face_types",
        "write_kml": "face_types",
        "Approval": "approval",
        "ApprovalBook": "approval",
        "ArmState": "arming",
        "ArmStatus": "arming",
        "ArmWindow": "arm_window",
        "ArmingController": "arming",
        "AuditLog": "audit_log",
        "shown_record": "audit_log",
        "write_audit_export": "audit_log",
        "BalloonSample": "telemetry",
        "CapsuleTelemetry": "fleet",
        "Checklist": "checklist",
        "ChecklistRun": "checklist",
        "Contour": "telemetry",
        "Descent": "recovery",
        "DropView": "recovery",
        "ExclusionZone": "gonogo",
        "FleetState": "fleet",
        "Freshness": "staleness",
        "IridiumHealthView": "views",
        "GnssSample": "telemetry",
        "GoNoGoReport": "gonogo",
        "LinkSample": "telemetry",
        "LiveSource": "recovery",
        "LiveView": "recovery",
        "Login": "approval",
        "MISSING_TEXT": "staleness",
        "CapsuleLinks": "links",
        "OperatorOps": "operator_ops",
        "OnPending": "ops_state",
        "OpsState": "ops_state",
        "Enrolment": "enrolment",
        "IridiumOps": "iridium_ops",
        "Release": "release",
        "PROCEDURE_DIR": "checklist",
        "Predict": "release",
        "PredictionSample": "telemetry",
        "PredictionStatus": "telemetry",
        "ParachuteOverride": "override",
        "Reading": "staleness",
        "SECOND_LOGIN_HOWTO": "arming",
        "SecondOperator": "ops_state",
        "RecoveryView": "recovery",
        "RecordedViews": "views",
        "ReleaseCandidate": "release_window",
        "ReleaseOrigin": "origin",
        "ReleaseSample": "telemetry",
        "ReleaseRecord": "capsule",
        "ReleaseState": "capsule",
        "ReleaseStateMachine": "capsule",
        "ReleaseWindow": "release_window",
        "ReportRow": "views",
        "ReportSample": "telemetry",
        "STALE_GLYPH": "staleness",
        "Sample": "telemetry",
        "StepKind": "checklist",
        "StepRecord": "checklist",
        "StepStatus": "checklist",
        "StepState": "checklist",
        "StorageSample": "telemetry",
        "SyncSample": "telemetry",
        "TelemetryRecord": "telemetry",
        "TelemetryRecorder": "telemetry",
        "Verdict": "gonogo",
        "ViewSource": "views",
        "WAIVABLE": "gonogo",
        "Waiver": "gonogo",
        "WAIVER_REASON_MAX": "gonogo",
        "approved": "approval",
        "authorize_mt": "authorize",
        "carries_parachute": "authorize",
        "complete_command": "checklist",
        "complete_mt_steps": "procedure",
        "drop_schedule": "override",
        "after_drop": "override",
        "evaluate": "gonogo",
        "descent_along": "recovery",
        "follow_descent": "recovery",
        "format_age": "staleness",
        "hazard_of": "authorize",
        "load_checklists": "checklist",
        "load_exclusion_zones": "ops_state",
        "statuses_of": "checklist",
        "step_records": "checklist",
        "parachute_override": "override",
        "read_recording": "telemetry",
        "record_as_dict": "capsule",
        "record_loss": "session",
        "record_start": "session",
        "SessionLoss": "session",
        "recovery_view": "recovery",
        "release_origin": "origin",
        "report_position": "iridium_ops",
        "take_over_outcome": "capsule",
        "unprotected_ssh_warning": "session",
        "shown": "typed_text",
        "typed_text": "typed_text",
    },
)

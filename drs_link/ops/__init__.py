"""The operations layer: every safety rule, below any screen, for the CLI and the console alike.

``capsule`` is the release state machine; ``arming`` ARM then FIRE, in the windows of ``arm_window``;
``gonogo`` the poll before ARM; ``checklist`` and ``procedure`` the procedures as data; ``approval`` the
second operator and ``identity`` which login is another person; ``authorize`` the PARACHUTE gate,
``override`` what stays on screen after it was overridden; ``telemetry``, ``fleet``, ``staleness`` and
``origin`` what is known of each capsule and how old it is; ``recovery`` where a dropped capsule is
and is going, ``views`` what the per-capsule screens show, from the store or a replay; ``release_window``
the sweep; ``session`` a console that ends without quitting; ``operations`` the console's engine
without a screen; and ``face_types`` the values below it that the faces show and compose, so that
they import this door alone.
"""

from typing import TYPE_CHECKING

from predictor.lazy_door import lazy_door

if TYPE_CHECKING:
    from .approval import ACTIONS as ACTIONS
    from .approval import Approval as Approval
    from .approval import ApprovalBook as ApprovalBook
    from .approval import Login as Login
    from .approval import approved as approved
    from .approval import current_login as current_login
    from .approval import pending_text as pending_text
    from .arm_window import ArmWindow as ArmWindow
    from .arming import SECOND_LOGIN_HOWTO as SECOND_LOGIN_HOWTO
    from .arming import ArmingController as ArmingController
    from .arming import ArmState as ArmState
    from .arming import ArmStatus as ArmStatus
    from .authorize import authorize_mt as authorize_mt
    from .authorize import carries_parachute as carries_parachute
    from .authorize import hazard_of as hazard_of
    from .capsule import ReleaseState as ReleaseState
    from .capsule import ReleaseStateMachine as ReleaseStateMachine
    from .capsule import record_as_dict as record_as_dict
    from .capsule import take_over_outcome as take_over_outcome
    from .checklist import PROCEDURE_DIR as PROCEDURE_DIR
    from .checklist import Checklist as Checklist
    from .checklist import ChecklistRun as ChecklistRun
    from .checklist import StepKind as StepKind
    from .checklist import StepState as StepState
    from .checklist import complete_command as complete_command
    from .checklist import load_checklists as load_checklists
    from .face_types import CATALOGUE as CATALOGUE
    from .face_types import FLUSH_WARNING as FLUSH_WARNING
    from .face_types import LISTED as LISTED
    from .face_types import PARACHUTE as PARACHUTE
    from .face_types import QUEUED as QUEUED
    from .face_types import RETRY_WARNING as RETRY_WARNING
    from .face_types import Command as Command
    from .face_types import Hazard as Hazard
    from .face_types import LandedEvidence as LandedEvidence
    from .face_types import MtCommand as MtCommand
    from .face_types import MtComposer as MtComposer
    from .face_types import MtMessage as MtMessage
    from .face_types import ParachutePlan as ParachutePlan
    from .face_types import StoredReport as StoredReport
    from .face_types import by_name as by_name
    from .face_types import iso_utc as iso_utc
    from .face_types import parse_hhmm as parse_hhmm
    from .fleet import CapsuleTelemetry as CapsuleTelemetry
    from .fleet import FleetState as FleetState
    from .gonogo import WAIVABLE as WAIVABLE
    from .gonogo import WAIVER_REASON_MAX as WAIVER_REASON_MAX
    from .gonogo import GoNoGoReport as GoNoGoReport
    from .gonogo import Verdict as Verdict
    from .gonogo import evaluate as evaluate
    from .operations import Operations as Operations
    from .operations import Predict as Predict
    from .operations import SecondOperator as SecondOperator
    from .operations import cli_holder as cli_holder
    from .operations import report_position as report_position
    from .origin import ReleaseOrigin as ReleaseOrigin
    from .origin import release_origin as release_origin
    from .override import ParachuteOverride as ParachuteOverride
    from .override import after_drop as after_drop
    from .override import drop_schedule as drop_schedule
    from .override import parachute_override as parachute_override
    from .procedure import complete_mt_steps as complete_mt_steps
    from .recovery import Descent as Descent
    from .recovery import DropView as DropView
    from .recovery import LiveSource as LiveSource
    from .recovery import LiveView as LiveView
    from .recovery import RecoveryView as RecoveryView
    from .recovery import capsule_descent as capsule_descent
    from .recovery import descent_along as descent_along
    from .recovery import follow_descent as follow_descent
    from .recovery import recovery_view as recovery_view
    from .release_window import ReleaseCandidate as ReleaseCandidate
    from .release_window import ReleaseWindow as ReleaseWindow
    from .session import record_loss as record_loss
    from .session import record_start as record_start
    from .session import unprotected_ssh_warning as unprotected_ssh_warning
    from .staleness import MISSING_TEXT as MISSING_TEXT
    from .staleness import STALE_GLYPH as STALE_GLYPH
    from .staleness import Freshness as Freshness
    from .staleness import Reading as Reading
    from .staleness import format_age as format_age
    from .telemetry import BalloonSample as BalloonSample
    from .telemetry import Contour as Contour
    from .telemetry import GnssSample as GnssSample
    from .telemetry import LinkSample as LinkSample
    from .telemetry import PredictionSample as PredictionSample
    from .telemetry import PredictionStatus as PredictionStatus
    from .telemetry import ReleaseSample as ReleaseSample
    from .telemetry import ReportSample as ReportSample
    from .telemetry import Sample as Sample
    from .telemetry import StorageSample as StorageSample
    from .telemetry import SyncSample as SyncSample
    from .telemetry import TelemetryRecord as TelemetryRecord
    from .telemetry import TelemetryRecorder as TelemetryRecorder
    from .telemetry import read_recording as read_recording
    from .views import IridiumHealthView as IridiumHealthView
    from .views import RecordedViews as RecordedViews
    from .views import ReportRow as ReportRow
    from .views import StoreViews as StoreViews
    from .views import ViewSource as ViewSource

__getattr__, __dir__, __all__ = lazy_door(
    __name__,
    {
        "ACTIONS": "approval",
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
        "BalloonSample": "telemetry",
        "CapsuleTelemetry": "fleet",
        "Checklist": "checklist",
        "ChecklistRun": "checklist",
        "Contour": "telemetry",
        "Descent": "recovery",
        "DropView": "recovery",
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
        "Operations": "operations",
        "PROCEDURE_DIR": "checklist",
        "Predict": "operations",
        "PredictionSample": "telemetry",
        "PredictionStatus": "telemetry",
        "ParachuteOverride": "override",
        "Reading": "staleness",
        "SECOND_LOGIN_HOWTO": "arming",
        "SecondOperator": "operations",
        "RecoveryView": "recovery",
        "RecordedViews": "views",
        "ReleaseCandidate": "release_window",
        "ReleaseOrigin": "origin",
        "ReleaseSample": "telemetry",
        "ReleaseState": "capsule",
        "ReleaseStateMachine": "capsule",
        "ReleaseWindow": "release_window",
        "ReportRow": "views",
        "ReportSample": "telemetry",
        "STALE_GLYPH": "staleness",
        "Sample": "telemetry",
        "StepKind": "checklist",
        "StepState": "checklist",
        "StorageSample": "telemetry",
        "StoreViews": "views",
        "SyncSample": "telemetry",
        "TelemetryRecord": "telemetry",
        "TelemetryRecorder": "telemetry",
        "Verdict": "gonogo",
        "ViewSource": "views",
        "WAIVABLE": "gonogo",
        "WAIVER_REASON_MAX": "gonogo",
        "approved": "approval",
        "authorize_mt": "authorize",
        "capsule_descent": "recovery",
        "carries_parachute": "authorize",
        "cli_holder": "operations",
        "complete_command": "checklist",
        "complete_mt_steps": "procedure",
        "current_login": "approval",
        "drop_schedule": "override",
        "after_drop": "override",
        "evaluate": "gonogo",
        "descent_along": "recovery",
        "follow_descent": "recovery",
        "format_age": "staleness",
        "hazard_of": "authorize",
        "load_checklists": "checklist",
        "parachute_override": "override",
        "pending_text": "approval",
        "read_recording": "telemetry",
        "record_as_dict": "capsule",
        "record_loss": "session",
        "record_start": "session",
        "recovery_view": "recovery",
        "release_origin": "origin",
        "report_position": "operations",
        "take_over_outcome": "capsule",
        "unprotected_ssh_warning": "session",
    },
)

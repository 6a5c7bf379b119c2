"""The operations server's protocol: every message a client and the server exchange, as typed values.

Why msgspec: each message is a frozen ``Struct`` decoded straight from JSON bytes with its types checked
(a string where an int belongs, an unknown field, a missing one: refused with the field's path), so the
server never parses a dict back into a value, and a malformed message is a one-line error that changes
nothing. It is one small C extension, faster than pydantic on both ends, and it validates on decode
only, which is where an untrusted message enters.

Why versioned twice: the routes live under ``/v1/`` and every request carries ``protocol``; a client
and a server of different versions (an old ``drs`` on a new ground machine) are refused with both
numbers named, before anything is read as a command.
"""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Literal

import msgspec

from drs_link.feeds import KeptLanding

PROTOCOL = 1
"""Bumped on any change a client of the previous version would misread."""
ROOT = f"/v{PROTOCOL}"
MAX_BODY_BYTES = 64 * 1024
"""A request is a few hundred bytes; anything larger is refused before it is read as JSON."""
MAX_RECOVERY_BYTES = 4 * 1024 * 1024
"""``drs recovery`` alone carries the operator's predicted track (tens of thousands of points at most)."""
MAX_TEXT = 400
"""The longest free text (a reason, a waiver, a typed name) a request may carry."""


class Request(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    protocol: int


class Waive(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """One go/no-go item waived for this request (``drs capsule arm/go --waive ITEM=REASON``)."""

    item: str
    reason: str


class Second(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """How the two-person rule is met: a typed crew name or a waiver (refused under
    ``require_second_operator``), or another account's live approval (``await_approval``)."""

    name: str | None = None
    waiver: str | None = None
    await_approval: bool = False


class ArmRequest(Request, frozen=True):
    waivers: tuple[Waive, ...] = ()
    weather: tuple[str, ...] = ()
    """GRIB2 files the server reads for the "release now" prediction go/no-go judges."""
    held_waivers: bool = False
    """Judge with the waivers this account holds at the server (a console's ``w``, audited when granted)
    instead of ``waivers`` (a command's ``--waive``, granted for this request)."""


class FireRequest(Request, frozen=True):
    typed_name: str
    waivers: tuple[Waive, ...] = ()
    weather: tuple[str, ...] = ()
    second: Second = Second()
    held_waivers: bool = False


class DisarmRequest(Request, frozen=True):
    reason: str = "operator disarmed (drs capsule disarm)"


class MtSendRequest(Request, frozen=True):
    """``drs mt send``: each catalogue command's option as typed (``{"interval": 5, "parachute": "next"}``)."""

    options: dict[str, int | str]
    confirm: str | None = None
    dry_run: bool = False
    flush: bool = False
    accept_midnight: bool = False
    override_landed: str | None = None
    second: Second = Second()


class DecideRequest(Request, frozen=True):
    approve: bool
    reason: str = ""


class PowerOnRequest(Request, frozen=True):
    confirmed: bool
    """The operator confirmed it (``--yes`` or the typed name); False is refused, and audited, by the
    state machine, as the console's dialog answered no."""


class TypedNameRequest(Request, frozen=True):
    """A step confirmed by typing the capsule's name (``drs capsule reset``)."""

    typed_name: str


class ReleasedRequest(Request, frozen=True):
    typed_name: str
    evidence: str


class ReasonRequest(Request, frozen=True):
    """Giving up release authority, or asking whether a take-over could be right, for this reason."""

    reason: str = ""


class AuthoritySeen(msgspec.Struct, frozen=True, forbid_unknown_fields=True):
    """The release authority the operator was shown, as the Pi's owner file said it: a take-over hands it
    back and the Pi goes ahead only if its file still says exactly that."""

    holder: str | None
    lease_end_s: int
    pi_time_s: int


class TakeOverRequest(Request, frozen=True):
    seen: AuthoritySeen
    typed_name: str
    reason: str
    second: Second = Second()


class EnrolRequest(Request, frozen=True):
    fingerprint: str
    """The fingerprint the operator read on the Pi itself."""


class SyncRequest(Request, frozen=True):
    """``drs sync``: upload ``source`` (an absolute path the caller's account can read; None: the capsule's
    configured ``sync_source``)."""

    source: str | None = None


class SyncStatusRequest(Request, frozen=True):
    """``drs sync --status``: what an upload of ``source`` would send (``with_hash``: sha256 compared too)."""

    source: str | None = None
    with_hash: bool = False


class TrackRequest(Request, frozen=True):
    """``drs mo export``: the stored fixes of a configured capsule, or of a modem by its IMEI."""

    capsule: str | None = None
    imei: str | None = None


class RecoveryRequest(Request, frozen=True):
    """``drs recovery``: the caller's position (read by the caller: its own gpsd), its predicted track
    (read from its own file), which files it wants the content of, and for ``--map`` the weather (and
    terrain) the live re-prediction flies, read by the server only if the caller's account could."""

    team: tuple[float, float] | None = None
    predicted: tuple[tuple[float, float, float], ...] = ()
    """(lat, lon, alt) from release to landing."""
    predicted_is_demo: bool = False
    gpx: bool = False
    kml: bool = False
    descent: bool = False
    weather: tuple[str, ...] = ()
    dem: str | None = None


class KeepLandingRequest(Request, frozen=True):
    """A console's newest predicted landing of a capsule, for every ``drs chase`` to send."""

    landing: KeptLanding


class ResolveMtRequest(Request, frozen=True):
    """``drs mt resolve``: what the RockBLOCK portal shows for an MT whose delivery is unknown."""

    command_id: int
    gateway_id: int | None
    """Queued with this id, or None: never sent."""
    note: str = ""


class WaiveRequest(Request, frozen=True):
    """A console's ``w``: waive ``item`` for this account until it is withdrawn or the capsule is reset."""

    item: str
    reason: str


class ItemRequest(Request, frozen=True):
    """Withdraw this account's waiver of ``item``."""

    item: str


class StepRequest(Request, frozen=True):
    """Tick a checklist step (``reason`` None), or skip it for ``reason``."""

    checklist: str
    step: str
    reason: str | None = None


class HistoryRequest(Request, frozen=True):
    """The audit log as History reads it: the newest ``limit`` entries containing ``text``, or (``after``)
    every entry after that id, oldest first, or (``limit`` 0) every entry containing ``text``."""

    text: str | None = None
    limit: int = 0
    after: int | None = None


class SessionLossRequest(Request, frozen=True):
    """A console cut off (SIGHUP, SIGTERM): the signal, the windows it had disarmed, the Go in flight."""

    signal: str
    disarmed: tuple[str, ...] = ()
    go_in_flight: tuple[str, ...] = ()


class PlanRequest(Request, frozen=True):
    """A PARACHUTE time to check (HH, MM), or None: the helper picks the next cycle."""

    requested: tuple[int, int] | None = None


# Answers ------------------------------------------------------------------------------------------


class Hello(msgspec.Struct, frozen=True):
    """Who the server says you are (from the kernel, never from you) and what it is."""

    protocol: int
    mode: Literal["private", "shared"]
    uid: int
    account: str
    operator: str
    require_second_operator: bool
    capsules: tuple[str, ...]


class ArmState(msgspec.Struct, frozen=True):
    capsule: str
    state: str
    window: int | None
    until_utc: str | None
    remaining_s: float
    reason: str | None
    lines: tuple[str, ...] = ()
    """The go/no-go poll it was judged on, one line per item."""
    armed_until: datetime | None = None
    """When the open window closes (a console counts it down on its own clock between pushes)."""
    mine: bool = True
    """Whether the asking account holds the window (only its holder can FIRE in it)."""
    holder: str = ""
    """Who holds another account's window (``held by account@host …``), empty when it is the asker's."""


class ApprovalView(msgspec.Struct, frozen=True):
    id: int
    capsule: str
    action: str
    summary: str
    command: str | None
    requested_by: str
    requester_account: str
    state: str
    expires_utc: str
    decided_by: str | None
    decider_account: str | None
    described: str
    """The request as ``drs approve`` prints it (``Approval.describe``)."""
    expires: datetime | None = None
    """``expires_utc`` as a time, for a console's countdown."""


class AuthorityView(msgspec.Struct, frozen=True):
    """Who holds a capsule's release authority on its Pi, and who the caller would hold it as."""

    capsule: str
    seen: AuthoritySeen
    described: str
    """``AuthorityStatus.describe``: holder, lease end and what is left of it, by the Pi's clock."""
    this_console: str
    """The caller's holder name (``default_holder`` of its operator)."""

    @property
    def mine(self) -> bool:
        return self.seen.holder == self.this_console


class ReleaseView(msgspec.Struct, frozen=True):
    """The release record, as ``drs capsule status --json`` has always printed it."""

    capsule: str
    state: str
    powered_at: str | None
    nmea_seen_at: str | None
    go_at: str | None
    released_at: str | None
    failed_go_at: str | None
    note: str | None


class LinkView(msgspec.Struct, frozen=True, omit_defaults=True):
    up: bool
    error: str | None = None
    note: str | None = None


class StorageView(msgspec.Struct, frozen=True):
    mount: str | None
    total_bytes: int | None
    used_bytes: int | None
    available_bytes: int | None
    raid_device: str | None
    raid_state: str
    raid_members: str | None


class MicrocontrollerView(msgspec.Struct, frozen=True):
    waiting_for_go: bool
    diagnosis: str


class GnssView(msgspec.Struct, frozen=True):
    nmea_seen: bool
    fix_quality: int | None
    fix_quality_name: str
    has_fix: bool
    satellites: int | None
    hdop: float | None
    latitude: float | None
    longitude: float | None
    altitude_m: float | None
    fix_time_utc: str | None
    age_s: float | None
    sentences_parsed: int
    sentences_malformed: int
    sentences_bad_checksum: int
    date_problem: str | None


class CapsuleStatus(msgspec.Struct, frozen=True, omit_defaults=True):
    """``drs capsule status``: what is absent (the Pi unreachable, not powered) is left out."""

    release: ReleaseView
    link: LinkView
    storage: StorageView | None = None
    microcontroller: MicrocontrollerView | None = None
    gnss: GnssView | None = None


class HostKeyView(msgspec.Struct, frozen=True):
    """The host key a capsule's Pi offers (``drs capsule enrol``), and where it was saved once confirmed."""

    address: str
    key_type: str
    fingerprint: str
    saved_to: str | None = None


class SyncStatusView(msgspec.Struct, frozen=True):
    """What an upload would send, in the fields ``drs sync --status --json`` has always printed."""

    missing: tuple[str, ...]
    changed: tuple[str, ...]
    up_to_date: int
    bytes_pending: int
    last_sync_utc: str | None
    left_out: tuple[str, ...]


class SyncReportView(msgspec.Struct, frozen=True):
    """An upload's outcome: every file uploaded was verified by sha256 on the Pi."""

    uploaded: tuple[str, ...]
    skipped: int
    bytes_sent: int
    left_out: tuple[str, ...]


class MtView(msgspec.Struct, frozen=True):
    """One MT's lifecycle, in the order ``drs mt status --json`` prints its fields."""

    id: int
    text: str
    state: str
    detail: str
    operator: str
    flush: bool
    requested_utc: str
    updated_utc: str
    queued_utc: str | None
    gateway_id: int | None
    delivered_report_id: int | None
    effects: dict[str, str]


class MtStatus(msgspec.Struct, frozen=True):
    capsule: str
    imei: str | None
    commands: tuple[MtView, ...]


class FindingView(msgspec.Struct, frozen=True):
    kind: str
    report_id: int
    message: str


class HealthView(msgspec.Struct, frozen=True):
    """``drs mo health``: battery, resets, gaps and spacing, judged by the server from the reports it holds."""

    capsule: str
    imei: str | None
    reports: int
    last_report: datetime | None
    last_vbat: float | None
    findings: tuple[FindingView, ...]


class TrackCsv(msgspec.Struct, frozen=True):
    """``drs mo export``: the canonical track CSV, for the client to write where its operator chose (the
    file is then the operator's own), and what was left out."""

    who: str
    csv: str
    fixes: int
    without_fix: int
    rejected: int


class Position(msgspec.Struct, frozen=True):
    lat: float
    lon: float


class LandingFields(msgspec.Struct, frozen=True):
    lat: float
    lon: float
    alt_m: float
    std_m: float | None
    """None with one fix kept: too few to estimate the scatter."""
    fixes: int
    rejected: int
    landed_utc: str
    last_fix_utc: str
    moved_utc: str | None


class LastFixFields(msgspec.Struct, frozen=True):
    time_utc: str
    lat: float
    lon: float
    alt_m: float
    speed_ms: float


class IridiumPosition(msgspec.Struct, frozen=True):
    lat: float
    lon: float
    cep_m: float
    time_utc: str


class RecoveryDocument(msgspec.Struct, frozen=True, omit_defaults=True):
    """``drs recovery --json``: what the summary line says, as numbers; the distance and bearing are from
    the team to the best position there is (the landing, else the last fix, else Iridium's coarse one)."""

    capsule: str
    summary: str
    landing: LandingFields | None
    last_fix: LastFixFields | None
    iridium_position: IridiumPosition | None
    team: Position | None = msgspec.field(name="from")
    distance_m: float | None = None
    bearing_deg: float | None = None


class FixView(msgspec.Struct, frozen=True):
    time: datetime
    lat: float
    lon: float
    alt_m: float


class LiveLandingView(msgspec.Struct, frozen=True):
    """The live re-prediction's landing, its 1σ ellipse and the correction it used, for the map."""

    lat: float
    lon: float
    time: datetime
    correction: str
    sigma_major_km: float
    sigma_minor_km: float
    major_axis_bearing_deg: float


class DescentView(msgspec.Struct, frozen=True):
    """The track, the landing the fixes show, else the live re-prediction (or why there is none)."""

    track: tuple[FixView, ...]
    landed: Position | None
    live: LiveLandingView | None
    live_error: str | None


class RecoveryReadout(msgspec.Struct, frozen=True):
    """``drs recovery``: the server's reading of the stored reports; the files' content (GPX, KML) for
    the client to write where its operator chose, so they are the operator's own."""

    document: RecoveryDocument
    landed: str | None
    """The landing in one line (time, altitude, fixes kept), when the fixes show one."""
    capsule_at: Position | None
    """The landing, else the last fix: where the team's distance warning measures to."""
    gpx: str | None = None
    kml: str | None = None
    descent: DescentView | None = None


class Failure(msgspec.Struct, frozen=True, tag="failure"):
    """A refusal or an error, as the operator reads it: ``kind`` picks the client's exception."""

    kind: Literal["refused", "config", "link", "store", "usage", "protocol", "identity"]
    error: str


# A long action (FIRE, an MT) answers with a stream of these, one JSON line each: what to say while it
# works, the approval request it waits on, then its end (Done or Failure).


class Said(msgspec.Struct, frozen=True, tag="said"):
    line: str


class Pending(msgspec.Struct, frozen=True, tag="pending"):
    approval: int
    line: str


class Done(msgspec.Struct, frozen=True, tag="done"):
    lines: tuple[str, ...]
    ok: bool = True
    arm: ArmState | None = None
    """ARM's answer: the window it opened."""
    sync: SyncReportView | None = None
    """An upload's answer (``drs sync``)."""


Step = Said | Pending | Done | Failure


class Event(msgspec.Struct, frozen=True):
    """What ``/v1/events`` pushes whenever the store changed: every capsule's release and ARM state and
    the approvals that wait, for a view to redraw without asking."""

    release: dict[str, str]
    armed: dict[str, str]
    approvals: tuple[ApprovalView, ...]
    arms: dict[str, ArmState] = {}
    """Each capsule's ARM window as the subscribing account sees it (``mine`` is that account's)."""
    audit_id: int = 0
    """The newest audit entry's id: every waiver, tick, send and session is audited, so a console asks
    for its desk (``drs_link.server.desk``) and the entries of others when this moves on."""


class TelemetryBatch(msgspec.Struct, frozen=True):
    """What ``/v1/telemetry`` pushes (the snapshot first, then each new batch) and a capsule's poll
    answers: records, each a line of the telemetry recording format (``TelemetryRecord.to_json``).

    Why the recording's lines inside a Struct rather than the records as Structs: the records are
    dataclasses of a union of sample kinds, and the recording format is their one versioned encoding
    with a strict parser (``TelemetryRecord.from_json``: format version, kind, every field checked); a
    second, msgspec-typed mirror of every sample kind would be a second encoding to keep in step."""

    records: tuple[str, ...]


def iso_utc(moment: datetime) -> str:
    """A typed time as the store and every ``--json`` output write it (ISO 8601, milliseconds, ``Z``)."""
    return moment.astimezone(UTC).isoformat(timespec="milliseconds").replace("+00:00", "Z")


def encode(value: object) -> bytes:
    return msgspec.json.encode(value)


def decode_step(line: bytes) -> Step:
    return msgspec.json.decode(line, type=Step)

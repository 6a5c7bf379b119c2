"""The console's telemetry as records: one JSON line each, written as they arrive, replayable later.

Live polling, the demo and ``drs console --replay FILE`` all feed the same records into the same
views (Project Horus' log-playback idea), so what an operator saw on launch day can be shown
again exactly. Each line is written and fsynced before it is shown, so a crash loses nothing
that was on screen. A bad line in a recording is reported with its file, line and field.

Each kind of record is a frozen dataclass (``LinkSample``, ``GnssSample``, …), so a producer
cannot misspell a key and a consumer matches on the class instead of comparing strings. The
JSONL format is unchanged (format version 1: ``kind`` names the class in ``SAMPLES``, ``data``
holds its fields), so recordings made before the kinds were typed replay as they always did.
"""

from __future__ import annotations

import json
import os
import threading
import types
from dataclasses import MISSING, dataclass, fields, is_dataclass
from datetime import datetime
from pathlib import Path
from typing import Any, ClassVar, Union, get_args, get_origin, get_type_hints

from drs_link.errors import LinkError
from drs_link.ops.capsule import ReleaseState
from drs_link.store import iso_utc, parse_iso_utc
from predictor.geofiles import EXPORT_MODE

FORMAT_VERSION = 1


class TelemetryFormatError(LinkError):
    """A telemetry recording cannot be read: the message names the file, line and field."""


@dataclass(frozen=True)
class LinkSample:
    """Whether the capsule's Pi answers over SSH, and why not."""

    KIND: ClassVar[str] = "link"
    up: bool
    note: str | None = None


@dataclass(frozen=True)
class ReleaseSample:
    """The release state machine's record of one capsule.

    The states derived from it (released, powered, the go/no-go line after Go) are read here and
    only here, so the fleet, the footer, the predictions and go/no-go never disagree about them.
    """

    KIND: ClassVar[str] = "release"
    state: str
    """A ``ReleaseState`` value; kept as text so a state this console does not know still shows."""
    nmea_seen: bool = False
    note: str | None = None
    released_at: datetime | None = None

    @property
    def released(self) -> bool:
        """Go has been sent: the Pi shuts down, the link is down as expected and NMEA is history."""
        return self.state in (ReleaseState.RELEASED, ReleaseState.GO_SENT)

    @property
    def powered(self) -> bool:
        return self.state == ReleaseState.POWERED

    def after_release(self) -> str | None:
        """What go/no-go says once Go was sent ("released 12:03Z, Pi shut down"); ``None`` before."""
        if self.state == ReleaseState.GO_SENT:
            return "Go sent, not yet verified"
        if self.state != ReleaseState.RELEASED:
            return None
        when = f" {self.released_at:%H:%M}Z" if self.released_at is not None else ""
        return f"released{when}, Pi shut down"


@dataclass(frozen=True)
class GnssSample:
    """The capsule's own GNSS, read from the microcontroller's NMEA while it is powered."""

    KIND: ClassVar[str] = "gnss"
    has_fix: bool
    quality: str | None = None
    sats: int | None = None
    hdop: float | None = None
    lat: float | None = None
    lon: float | None = None
    alt_m: float | None = None
    fix_age_s: float | None = None
    diagnosis: str | None = None
    date_problem: str | None = None


@dataclass(frozen=True)
class StorageSample:
    """The capsule's data disk: usage and RAID state."""

    KIND: ClassVar[str] = "storage"
    used_bytes: int | None = None
    total_bytes: int | None = None
    raid: str | None = None

    @property
    def free_bytes(self) -> int | None:
        """``None`` unless both numbers are known (a disk of size 0 is not known either)."""
        if not self.total_bytes or self.used_bytes is None:
            return None
        return self.total_bytes - self.used_bytes


@dataclass(frozen=True)
class SyncSample:
    """How much of the payload data has reached the capsule."""

    KIND: ClassVar[str] = "sync"
    fraction: float | None = None
    bytes_pending: int = 0
    files_pending: int = 0
    unknown: str = ""
    """Why there is no fraction (no ``sync_source`` configured), for go/no-go to say instead of "no data"."""


@dataclass(frozen=True)
class Contour:
    """One nσ ellipse of a prediction and the probability it holds."""

    n_sigma: float
    probability: float
    major_km: float
    minor_km: float


@dataclass(frozen=True)
class PredictionSample:
    """A landing prediction as the screens and go/no-go need it, so a replay shows it without recomputing."""

    KIND: ClassVar[str] = "prediction"
    release_in_min: int
    release_lat: float
    release_lon: float
    release_time: datetime
    landing_lat: float
    landing_lon: float
    landing_time: datetime
    descent_s: float
    distance_km: float
    bearing_deg: float
    sigma_par_km: float
    sigma_perp_km: float
    major_axis_bearing_deg: float
    contours: tuple[Contour, ...]
    outline_2sigma: tuple[tuple[float, float], ...]
    """The 2σ ellipse as (lon, lat)."""
    path: tuple[tuple[float, float], ...]
    """The descent, thinned, as (lon, lat)."""
    origin_source: str | None = None
    warnings: tuple[str, ...] = ()
    is_demo: bool = False
    model: str | None = None


@dataclass(frozen=True)
class PredictionStatus:
    """What the console is doing about a capsule's first prediction, shown until it has one."""

    KIND: ClassVar[str] = "prediction_status"
    short: str
    text: str


@dataclass(frozen=True)
class ReportSample:
    """One Iridium report: every part may be missing (no fix, an undecodable payload)."""

    KIND: ClassVar[str] = "report"
    momsn: int | None = None
    has_fix: bool = False
    lat: float | None = None
    lon: float | None = None
    uncertainty_m: float | None = None
    position_source: str | None = None
    alt_m: float | None = None
    speed_ms: float | None = None
    sats: int | None = None
    vbat: float | None = None
    iteration: int | None = None
    interval_min: int | None = None
    """The longest time the next report may take, so the report is not stale before then."""
    landed: bool = False


@dataclass(frozen=True)
class BalloonSample:
    """The balloon's position from the ground station's feed."""

    KIND: ClassVar[str] = "balloon"
    lat: float
    lon: float
    alt_m: float
    format: str | None = None
    source: str | None = None
    received_at: datetime | None = None
    callsign: str | None = None


@dataclass(frozen=True)
class GatewaySample:
    """Whether MT commands could be sent: the gateway's address and credentials are configured."""

    KIND: ClassVar[str] = "gateway"
    credentials_ok: bool
    note: str | None = None


Sample = (
    LinkSample | ReleaseSample | GnssSample | StorageSample | SyncSample | PredictionSample | PredictionStatus
    | ReportSample | BalloonSample | GatewaySample
)  # fmt: skip
SAMPLES: dict[str, type[Sample]] = {cls.KIND: cls for cls in get_args(Sample)}
"""The recording format's ``kind`` names and the class each one reads into."""


def _plain(value: object) -> object:
    """A sample's value as JSON: tuples as lists, times in full ISO 8601 (a round trip is exact)."""
    if is_dataclass(value) and not isinstance(value, type):
        return {f.name: _plain(getattr(value, f.name)) for f in fields(value)}
    if isinstance(value, datetime):
        return value.isoformat()
    if isinstance(value, tuple):
        return [_plain(v) for v in value]
    return value


_NAMES: dict[type, str] = {
    bool: "true or false",
    int: "a whole number",
    float: "a number",
    str: "text",
    datetime: "an ISO 8601 time",
}
"""How a malformed field says what it should have been."""


def _decode(hint: Any, value: object, where: str) -> Any:
    """``value`` read as ``hint``, or a ``TelemetryFormatError`` naming ``where`` (file:line: kind.field)."""
    if get_origin(hint) in (Union, types.UnionType):
        options = [h for h in get_args(hint) if h is not type(None)]
        if value is None and len(options) < len(get_args(hint)):
            return None
        [hint] = options
    if get_origin(hint) is tuple:
        if not isinstance(value, list):
            raise TelemetryFormatError(f"{where}: expected a list, got {value!r}")
        args = get_args(hint)
        items = args[:1] * len(value) if args[-1] is Ellipsis else args
        if len(items) != len(value):
            raise TelemetryFormatError(f"{where}: expected {len(items)} items, got {len(value)}")
        return tuple(
            _decode(h, v, f"{where}[{i}]") for i, (h, v) in enumerate(zip(items, value, strict=True))
        )
    if isinstance(hint, type) and is_dataclass(hint):
        if not isinstance(value, dict):
            raise TelemetryFormatError(f"{where}: expected an object, got {value!r}")
        return _from_dict(hint, value, where)
    if hint is datetime:
        if isinstance(value, str):
            try:
                return parse_iso_utc(value)
            except ValueError:
                pass
    elif hint is bool:
        if isinstance(value, bool):
            return value
    elif hint is int:
        if isinstance(value, int | float) and not isinstance(value, bool) and float(value).is_integer():
            return int(value)
    elif hint is float:
        if isinstance(value, int | float) and not isinstance(value, bool):
            return float(value)
    elif isinstance(value, hint):
        return value
    raise TelemetryFormatError(f"{where}: expected {_NAMES.get(hint, hint.__name__)}, got {value!r}")


def _from_dict(cls: type[Any], data: dict[str, object], where: str) -> Any:
    """A dataclass from its JSON object; keys it does not have are ignored, so older lines still read."""
    hints = get_type_hints(cls)
    values = {}
    for f in fields(cls):
        if f.name in data:
            values[f.name] = _decode(hints[f.name], data[f.name], f"{where}.{f.name}")
        elif f.default is MISSING and f.default_factory is MISSING:
            raise TelemetryFormatError(f"{where}.{f.name}: missing")
    return cls(**values)


@dataclass(frozen=True)
class TelemetryRecord:
    """One sample of one capsule (``capsule`` is ``None`` for the balloon and the gateway) at a time."""

    time: datetime
    capsule: str | None
    data: Sample

    @property
    def kind(self) -> str:
        return self.data.KIND

    def to_json(self) -> str:
        return json.dumps(
            {"v": FORMAT_VERSION, "t": iso_utc(self.time), "capsule": self.capsule, "kind": self.kind,
             "data": _plain(self.data)},
            sort_keys=True,
        )  # fmt: skip

    @classmethod
    def from_json(cls, line: str, where: str) -> TelemetryRecord:
        try:
            raw = json.loads(line)
        except json.JSONDecodeError as exc:
            raise TelemetryFormatError(f"{where}: not JSON ({exc.msg})") from None
        if not isinstance(raw, dict):
            raise TelemetryFormatError(f"{where}: expected a JSON object")
        if raw.get("v") != FORMAT_VERSION:
            raise TelemetryFormatError(f"{where}: unknown format version {raw.get('v')!r} (expected 1)")
        kind = raw.get("kind")
        if kind not in SAMPLES:
            raise TelemetryFormatError(f"{where}: unknown kind {kind!r} (known: {', '.join(SAMPLES)})")
        capsule = raw.get("capsule")
        if capsule is not None and not isinstance(capsule, str):
            raise TelemetryFormatError(f"{where}: capsule must be a name or null")
        data = raw.get("data")
        if not isinstance(data, dict):
            raise TelemetryFormatError(f"{where}: data must be an object")
        try:
            moment = parse_iso_utc(str(raw.get("t")))
        except ValueError:
            raise TelemetryFormatError(f"{where}: t {raw.get('t')!r} is not an ISO 8601 UTC time") from None
        return cls(moment, capsule, _from_dict(SAMPLES[kind], data, f"{where}: {kind}"))


class TelemetryRecorder:
    """Appends records to a JSONL file; thread-safe, each line durable before ``append`` returns.

    The file is created like an export (``EXPORT_MODE``, 0640): it repeats what the console showed,
    capsule positions and operators' notes among it, so no other user of the laptop may read it.
    """

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._lock = threading.Lock()
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            fd = os.open(self.path, os.O_WRONLY | os.O_APPEND | os.O_CREAT, EXPORT_MODE)
            self._file = os.fdopen(fd, "a", encoding="utf-8")
        except OSError as exc:
            raise LinkError(f"cannot record telemetry to {self.path}: {exc}") from None

    def append(self, record: TelemetryRecord) -> None:
        with self._lock:
            self._file.write(record.to_json() + "\n")
            self._file.flush()
            os.fsync(self._file.fileno())

    def close(self) -> None:
        with self._lock:
            self._file.close()


def read_recording(path: Path) -> list[TelemetryRecord]:
    """All records of a recording, oldest first; empty lines are allowed, bad ones are not."""
    try:
        text = Path(path).read_text(encoding="utf-8")
    except (OSError, UnicodeDecodeError) as exc:
        raise TelemetryFormatError(f"cannot read the recording {path}: {exc}") from None
    records = [
        TelemetryRecord.from_json(line, f"{Path(path).name}:{number}")
        for number, line in enumerate(text.splitlines(), start=1)
        if line.strip()
    ]
    if not records:
        raise TelemetryFormatError(f"{path}: the recording holds no telemetry records")
    return sorted(records, key=lambda r: r.time)

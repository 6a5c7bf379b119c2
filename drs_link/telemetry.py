"""The console's telemetry as records: one JSON line each, written as they arrive, replayable later.

Live polling, the demo and ``drs console --replay FILE`` all feed the same records into the same
views (Project Horus' log-playback idea), so what an operator saw on launch day can be shown
again exactly. Each line is written and fsynced before it is shown, so a crash loses nothing
that was on screen. A bad line in a recording is reported with its file and line number.
"""

from __future__ import annotations

import json
import os
import threading
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path
from typing import Any

from drs_link.errors import LinkError
from drs_link.store import iso_utc, parse_iso_utc

KINDS = (
    "link", "release", "gnss", "storage", "sync", "prediction", "prediction_status", "report", "balloon", "gateway",
)  # fmt: skip
FORMAT_VERSION = 1


class TelemetryFormatError(LinkError):
    """A telemetry recording cannot be read: the message names the file and line."""


@dataclass(frozen=True)
class TelemetryRecord:
    time: datetime
    capsule: str | None
    kind: str
    data: dict[str, Any]

    def to_json(self) -> str:
        return json.dumps(
            {"v": FORMAT_VERSION, "t": iso_utc(self.time), "capsule": self.capsule, "kind": self.kind,
             "data": self.data},
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
        if kind not in KINDS:
            raise TelemetryFormatError(f"{where}: unknown kind {kind!r} (known: {', '.join(KINDS)})")
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
        return cls(moment, capsule, kind, data)


class TelemetryRecorder:
    """Appends records to a JSONL file; thread-safe, each line durable before ``append`` returns."""

    def __init__(self, path: Path) -> None:
        self.path = Path(path)
        self._lock = threading.Lock()
        try:
            self.path.parent.mkdir(parents=True, exist_ok=True)
            self._file = self.path.open("a", encoding="utf-8")
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

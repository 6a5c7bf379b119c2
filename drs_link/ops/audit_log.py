"""The audit log as the History screen reads it: entries to search and show, and their export as JSON lines.

The screen used to query the store and write the export itself, so the one record of who did what had a
second reader and a second file format outside the operations layer. Here both are one typed query over
the store, the same in a live console and a replay (which shows this machine's log).
"""

from __future__ import annotations

import json
from collections.abc import Sequence
from dataclasses import replace
from pathlib import Path
from typing import Any

from drs_link.ops.typed_text import shown
from drs_link.store import AuditRecord, Store, iso_utc

HISTORY_ROWS = 500
"""The newest entries History lists; the export has them all."""


class AuditLog:
    """Read-only: nothing here writes an audit row."""

    def __init__(self, store: Store) -> None:
        self.store = store

    def newest(self, text: str | None = None, limit: int = HISTORY_ROWS) -> list[AuditRecord]:
        """The newest ``limit`` entries containing ``text`` (all when empty), newest first, every text in
        them as it may reach a terminal (``shown``): a reason stored before the typed-text rule, or written
        into the store by hand, cannot rewrite History's screen."""
        return [shown_record(r) for r in reversed(self.store.audit(text=text or None, limit=limit))]

    def elsewhere(self, record: AuditRecord) -> str | None:
        """The console that wrote ``record`` when it is not this one (account@host pid), else None."""
        return record.session if record.session and record.session != self.store.session else None

    def export(self, path: Path, text: str | None = None) -> int:
        """Every entry containing ``text``, oldest first, one JSON object a line; how many were written."""
        return write_audit_export(path, self.store.audit(text=text or None))


def write_audit_export(path: Path, records: Sequence[AuditRecord]) -> int:
    """``records``, oldest first, one JSON object a line, written by the process that asked (a console
    writes the entries the server read to a file of its own operator's); how many were written."""
    path.parent.mkdir(parents=True, exist_ok=True)
    with path.open("w", encoding="utf-8") as out:
        for r in records:
            row = {"time_utc": iso_utc(r.time_utc), "operator": r.operator, "capsule": r.capsule,
                   "action": r.action, "result": r.result, "detail": r.detail}  # fmt: skip
            out.write(json.dumps(row) + "\n")
    return len(records)


def shown_record(record: AuditRecord) -> AuditRecord:
    """Every text of an entry as it may reach a terminal (``shown``)."""
    return replace(
        record, operator=shown(record.operator), capsule=None if record.capsule is None else shown(record.capsule),
        action=shown(record.action), result=shown(record.result),
        detail=None if record.detail is None else _shown_value(record.detail),
        session=None if record.session is None else shown(record.session),
    )  # fmt: skip


def _shown_value(value: Any) -> Any:
    """Every string in a detail, keys too, through ``shown``; numbers and the rest as they are."""
    if isinstance(value, str):
        return shown(value)
    if isinstance(value, dict):
        return {shown(k): _shown_value(v) for k, v in value.items()}
    if isinstance(value, list):
        return [_shown_value(v) for v in value]
    return value

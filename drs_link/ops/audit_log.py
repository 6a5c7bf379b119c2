"""The audit log as the History screen reads it: entries to search and show, and their export as JSON lines.

The screen used to query the store and write the export itself, so the one record of who did what had a
second reader and a second file format outside the operations layer. Here both are one typed query over
the store, the same in a live console and a replay (which shows this machine's log).
"""

from __future__ import annotations

import json
from pathlib import Path

from drs_link.store import AuditRecord, Store, iso_utc

HISTORY_ROWS = 500
"""The newest entries History lists; the export has them all."""


class AuditLog:
    """Read-only: nothing here writes an audit row."""

    def __init__(self, store: Store) -> None:
        self.store = store

    def newest(self, text: str | None = None, limit: int = HISTORY_ROWS) -> list[AuditRecord]:
        """The newest ``limit`` entries containing ``text`` (all when empty), newest first."""
        return list(reversed(self.store.audit(text=text or None, limit=limit)))

    def elsewhere(self, record: AuditRecord) -> str | None:
        """The console that wrote ``record`` when it is not this one (account@host pid), else None."""
        return record.session if record.session and record.session != self.store.session else None

    def export(self, path: Path, text: str | None = None) -> int:
        """Every entry containing ``text``, oldest first, one JSON object a line; how many were written."""
        records = self.store.audit(text=text or None)
        path.parent.mkdir(parents=True, exist_ok=True)
        with path.open("w", encoding="utf-8") as out:
            for r in records:
                row = {"time_utc": iso_utc(r.time_utc), "operator": r.operator, "capsule": r.capsule,
                       "action": r.action, "result": r.result, "detail": r.detail}  # fmt: skip
                out.write(json.dumps(row) + "\n")
        return len(records)

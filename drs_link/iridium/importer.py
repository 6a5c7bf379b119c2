"""`drs mo import FILES`: the email route, one ``<imei>-<momsn>.bin`` attachment per report.

The DRS team received reports by email (drs_protocol.md 4.2); saved attachments carry the IMEI
and MOMSN only in their file name, so the name is checked as strictly as the content. Importing
the same file twice is harmless (de-duplicated), and one bad file never stops the others.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import datetime
from pathlib import Path

from drs_link.iridium.reports import Delivery, ReportStore, StoredReport
from drs_link.store import utc_now

ATTACHMENT_NAME = re.compile(r"^(\d{15})-(\d{1,5})\.(?:bin|sbd)$")
MAX_ATTACHMENT_BYTES = 340


@dataclass(frozen=True)
class ImportOutcome:
    path: Path
    status: str
    """``new``, ``duplicate`` (already stored), ``rejected`` (stored, not a DRS report) or ``error``."""
    message: str
    stored: StoredReport | None = None


def import_file(path: Path, reports: ReportStore, now: datetime) -> ImportOutcome:
    match = ATTACHMENT_NAME.match(path.name)
    if match is None:
        return ImportOutcome(path, "error", "name is not <15-digit imei>-<momsn>.bin")
    imei, momsn = match.group(1), int(match.group(2))
    if momsn > 65535:
        return ImportOutcome(path, "error", f"MOMSN {momsn} is over 65535")
    try:
        with path.open("rb") as handle:
            payload = handle.read(MAX_ATTACHMENT_BYTES + 1)
    except OSError as exc:
        return ImportOutcome(path, "error", f"cannot read: {exc.strerror or exc}")
    if len(payload) > MAX_ATTACHMENT_BYTES:
        return ImportOutcome(path, "error", f"over {MAX_ATTACHMENT_BYTES} bytes: not an SBD MO attachment")
    stored, new = reports.add(Delivery(imei, momsn, payload.hex(), "email-file", now))
    if not new:
        return ImportOutcome(path, "duplicate", "already stored", stored)
    if not stored.parsed.accepted:
        return ImportOutcome(path, "rejected", f"stored but not a DRS report: {stored.parsed.reason}", stored)
    return ImportOutcome(path, "new", "stored", stored)


def import_files(
    paths: Iterable[Path], reports: ReportStore, clock: Callable[[], datetime] = utc_now
) -> list[ImportOutcome]:
    return [import_file(Path(path), reports, clock()) for path in paths]

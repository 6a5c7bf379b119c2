"""`drs mo import FILES`: the email route, one attachment per report.

The DRS team received reports by email (drs_protocol.md 4.2); saved attachments carry the IMEI
and MOMSN only in their file name, so the name is checked as strictly as the content. Two namings
are in use: RockBLOCK's ``<imei>-<momsn>.bin`` (or ``.sbd``, or ``<imei>_<momsn>``), and Iridium's
direct SBD service,
``YY-MM-DD_hh-mm-ss_<imei>_<momsn>.sbd`` with the transmit time in UTC; either may zero-pad the
MOMSN. Importing the same file twice is harmless (de-duplicated), and one bad file never stops the
others.
"""

from __future__ import annotations

import re
from collections.abc import Callable, Iterable
from dataclasses import dataclass
from datetime import UTC, datetime
from pathlib import Path

from drs_link.iridium.reports import Delivery, ReportStore, StoredReport
from drs_link.store import utc_now

ROCKBLOCK_NAME = re.compile(r"\A(?P<imei>\d{15})[-_]0*(?P<momsn>\d{1,5})\.(?:bin|sbd)\Z", re.ASCII)
"""``<imei>-<momsn>`` and ``<imei>_<momsn>``: both are seen on saved attachments (#25 item 8)."""
IRIDIUM_DIRECT_NAME = re.compile(
    r"^(?P<when>\d{2}-\d{2}-\d{2}_\d{2}-\d{2}-\d{2})_(?P<imei>\d{15})_0*(?P<momsn>\d{1,5})\.sbd$", re.ASCII
)
NAMES_ACCEPTED = (
    "<imei>-<momsn>.bin or .sbd, or <imei>_<momsn>.sbd (RockBLOCK), "
    "or YY-MM-DD_hh-mm-ss_<imei>_<momsn>.sbd (Iridium)"
)
MAX_ATTACHMENT_BYTES = 340


@dataclass(frozen=True)
class ImportOutcome:
    path: Path
    status: str
    """``new``, ``duplicate`` (already stored), ``rejected`` (stored, not a DRS report) or ``error``."""
    message: str
    stored: StoredReport | None = None


def import_file(path: Path, reports: ReportStore, now: datetime) -> ImportOutcome:
    match = ROCKBLOCK_NAME.match(path.name) or IRIDIUM_DIRECT_NAME.match(path.name)
    if match is None:
        return ImportOutcome(path, "error", f"name is not {NAMES_ACCEPTED}")
    imei, momsn = match.group("imei"), int(match.group("momsn"))
    if momsn > 65535:
        return ImportOutcome(path, "error", f"MOMSN {momsn} is over 65535")
    transmitted = None
    if "when" in match.groupdict():
        try:
            transmitted = datetime.strptime(match.group("when"), "%y-%m-%d_%H-%M-%S").replace(tzinfo=UTC)
        except ValueError:
            return ImportOutcome(path, "error", f"{match.group('when')} in the name is not a date and time")
    if path.exists() and not path.is_file():
        return ImportOutcome(path, "error", "not a regular file (a FIFO or a device would block the import)")
    try:
        with path.open("rb") as handle:
            payload = handle.read(MAX_ATTACHMENT_BYTES + 1)
    except OSError as exc:
        return ImportOutcome(path, "error", f"cannot read: {exc.strerror or exc}")
    if len(payload) > MAX_ATTACHMENT_BYTES:
        return ImportOutcome(path, "error", f"over {MAX_ATTACHMENT_BYTES} bytes: not an SBD MO attachment")
    stored, new = reports.add(
        Delivery(imei, momsn, payload.hex(), "email-file", now, transmit_utc=transmitted)
    )
    if not new:
        return ImportOutcome(path, "duplicate", "already stored", stored)
    if not stored.parsed.accepted:
        return ImportOutcome(path, "rejected", f"stored but not a DRS report: {stored.parsed.reason}", stored)
    return ImportOutcome(path, "new", "stored", stored)


def import_files(
    paths: Iterable[Path], reports: ReportStore, clock: Callable[[], datetime] = utc_now
) -> list[ImportOutcome]:
    return [import_file(Path(path), reports, clock()) for path in paths]

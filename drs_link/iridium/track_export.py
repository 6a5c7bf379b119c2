"""A capsule's stored position reports as the canonical track CSV, so recorded flights feed calibration.

The calibration tools read ``time,lat,lon,alt_m[,pressure_pa[,speed_mps]]`` (``predictor.tracks.reading``);
writing through that module's own writer keeps one definition of the format. Only reports with a
GNSS fix become rows: a no-fix report's Iridium position is kilometres wide and would poison a
residual, so it is skipped and counted, as are payloads that were stored as rejected. Nothing
else is filtered here: cleaning (landing, driven home, bad rows) is calibration's job, by its
stated rules, on the full record.
"""

from __future__ import annotations

import tempfile
from dataclasses import dataclass
from pathlib import Path

from drs_link.errors import LinkError
from drs_link.exports import write_export
from drs_link.iridium.reports import StoredReport
from predictor.tracks import Fix, write_canonical_csv


@dataclass(frozen=True)
class TrackExport:
    """What an export wrote and what it left out, so the operator sees the count of every kind."""

    path: Path
    fixes: int
    without_fix: int
    rejected: int


def fixes_from_reports(reports: list[StoredReport]) -> list[Fix]:
    """The GNSS fixes of accepted reports, in the store's time order.

    The DRS firmware always sends pressure 0 (it has no sensor), so only a positive pressure is
    kept, as in the gateway-log reader of the test flights whose beacon did measure it.
    """
    fixes = []
    for stored in reports:
        report = stored.report
        if report is None or report.fix is None:
            continue
        fix = report.fix
        fixes.append(
            Fix(
                time=fix.time,
                lat=fix.lat,
                lon=fix.lon,
                alt_m=float(fix.alt_m),
                pressure_pa=float(report.pressure) if report.pressure > 0 else None,
                speed_ms=fix.speed_ms,
                course_deg=float(fix.course_deg),
                sats=fix.sats,
            )
        )
    return fixes


def track_csv(reports: list[StoredReport], who: str) -> tuple[str, int, int, int]:
    """The canonical CSV of the fixes as text (for the operations server to hand to the client that
    writes it), with the counts of fixes, reports without a fix and rejected ones."""
    fixes = fixes_from_reports(reports)
    rejected = sum(1 for r in reports if r.report is None)
    without_fix = len(reports) - rejected - len(fixes)
    if not fixes:
        raise LinkError(
            f"no position fix stored for {who} ({len(reports)} report(s): {without_fix} without a fix, "
            f"{rejected} rejected); nothing written"
        )
    with tempfile.TemporaryDirectory(prefix="drs-export-") as folder:
        temporary = Path(folder) / "track.csv"
        write_canonical_csv(fixes, temporary)
        return temporary.read_bytes().decode("utf-8"), len(fixes), without_fix, rejected


def export_track(reports: list[StoredReport], path: Path, who: str, overwrite: bool = False) -> TrackExport:
    """Write the fixes to ``path`` (``drs_link.exports.write_export``: atomic, never over a file without
    ``overwrite``; ``-`` is standard output)."""
    text, fixes, without_fix, rejected = track_csv(reports, who)
    write_export(text, path, overwrite)
    return TrackExport(path, fixes, without_fix, rejected)

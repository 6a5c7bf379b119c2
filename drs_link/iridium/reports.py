"""Every MO delivery kept durably, raw and parsed, whichever route it came by (webhook, email file).

The raw hex is the record; the parsed columns are derived from it by ``mo.parse_hex`` so that a
better parser can re-read old deliveries. De-duplication is on (imei, momsn, payload): the gateway
may deliver one report twice, while MOMSN alone wraps at 65536 and can legitimately repeat.
"""

from __future__ import annotations

import logging
import sqlite3
from dataclasses import dataclass
from datetime import datetime

from drs_link.errors import StoreError
from drs_link.iridium.mo import ParseResult, Report, parse_hex
from drs_link.store import Store, iso_utc, parse_iso_utc

log = logging.getLogger(__name__)

REPORTS_DDL = """
CREATE TABLE IF NOT EXISTS mo_report (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    imei TEXT NOT NULL,
    momsn INTEGER NOT NULL,
    serial INTEGER,
    source TEXT NOT NULL,
    received_utc TEXT NOT NULL,
    transmit_utc TEXT,
    sort_utc TEXT NOT NULL,
    iridium_lat REAL,
    iridium_lon REAL,
    iridium_cep_km REAL,
    jwt_verified INTEGER NOT NULL DEFAULT 0,
    raw_hex TEXT NOT NULL,
    raw_delivery TEXT,
    status TEXT NOT NULL,
    reason TEXT,
    fix_utc TEXT,
    lat REAL,
    lon REAL,
    alt_m INTEGER,
    vbat REAL,
    iteration INTEGER,
    UNIQUE (imei, momsn, raw_hex)
);
CREATE INDEX IF NOT EXISTS mo_report_imei_sort ON mo_report (imei, sort_utc);
CREATE INDEX IF NOT EXISTS mo_report_imei_session ON mo_report (imei, COALESCE(transmit_utc, fix_utc, received_utc));
CREATE TABLE IF NOT EXISTS mo_delivery_rejected (
    id INTEGER PRIMARY KEY AUTOINCREMENT,
    received_utc TEXT NOT NULL,
    remote TEXT,
    reason TEXT NOT NULL,
    body TEXT
);
"""


REJECTED_KEPT = 1000
REJECTED_BODY_CHARS = 4096


@dataclass(frozen=True)
class Delivery:
    """One MO as it arrived, before parsing."""

    imei: str
    momsn: int
    data_hex: str
    source: str
    received_utc: datetime
    transmit_utc: datetime | None = None
    serial: int | None = None
    iridium_lat: float | None = None
    iridium_lon: float | None = None
    iridium_cep_km: float | None = None
    jwt_verified: bool = False
    raw_delivery: str | None = None


@dataclass(frozen=True)
class StoredReport:
    id: int
    delivery: Delivery
    parsed: ParseResult

    @property
    def report(self) -> Report | None:
        return self.parsed.report

    @property
    def time(self) -> datetime:
        """The best time of the report: GNSS fix, else gateway transmit time, else arrival."""
        report = self.parsed.report
        if report is not None and report.fix is not None:
            return report.fix.time
        return self.delivery.transmit_utc or self.delivery.received_utc

    @property
    def session_time(self) -> datetime:
        """When the SBD session (and so any MT download) happened, as well as it is known.

        An email attachment carries no transmit time and may be imported long after; its fix
        (taken just before the session) is then a far better bound than the import time.
        """
        if self.delivery.transmit_utc is not None:
            return self.delivery.transmit_utc
        report = self.parsed.report
        if report is not None and report.fix is not None:
            return report.fix.time
        return self.delivery.received_utc

    def iridium_position(self) -> tuple[float, float, float] | None:
        """(lat, lon, CEP in m) estimated by the Iridium network: the only position of a no-fix report."""
        d = self.delivery
        if d.iridium_lat is None or d.iridium_lon is None:
            return None
        return d.iridium_lat, d.iridium_lon, (d.iridium_cep_km or 0.0) * 1000.0


def _opt_time(text: str | None) -> datetime | None:
    return parse_iso_utc(text) if text else None


class ReportStore:
    """The MO reports of every capsule, in the shared durable store."""

    def __init__(self, store: Store, write_wait_s: float | None = None) -> None:
        self.store = store
        self.write_wait_s = write_wait_s
        """How long a write may wait for the store's lock (None: the store's default); the receiver's is
        short, as the gateway gives up after 3 s and retries a 503 later."""
        store.ensure_schema(REPORTS_DDL)

    def add(self, delivery: Delivery) -> tuple[StoredReport, bool]:
        """Store one delivery durably; returns it and whether it was new (False: a duplicate)."""
        parsed = parse_hex(delivery.data_hex)
        raw_hex = delivery.data_hex.strip().upper()
        report = parsed.report
        fix = report.fix if report is not None else None
        stored = StoredReport(0, delivery, parsed)
        with self.store.transaction(self.write_wait_s) as conn:
            cursor = conn.execute(
                "INSERT OR IGNORE INTO mo_report (imei, momsn, serial, source, received_utc, transmit_utc, "
                "sort_utc, iridium_lat, iridium_lon, iridium_cep_km, jwt_verified, raw_hex, raw_delivery, "
                "status, reason, fix_utc, lat, lon, alt_m, vbat, iteration) "
                "VALUES (?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?, ?)",
                (
                    delivery.imei,
                    delivery.momsn,
                    delivery.serial,
                    delivery.source,
                    iso_utc(delivery.received_utc),
                    iso_utc(delivery.transmit_utc) if delivery.transmit_utc else None,
                    iso_utc(stored.time),
                    delivery.iridium_lat,
                    delivery.iridium_lon,
                    delivery.iridium_cep_km,
                    int(delivery.jwt_verified),
                    raw_hex,
                    delivery.raw_delivery,
                    "accepted" if parsed.accepted else "rejected",
                    parsed.reason,
                    iso_utc(fix.time) if fix else None,
                    fix.lat if fix else None,
                    fix.lon if fix else None,
                    fix.alt_m if fix else None,
                    report.vbat if report else None,
                    report.iteration if report else None,
                ),
            )
            new = cursor.rowcount == 1
            row_id = (
                cursor.lastrowid
                if new
                else conn.execute(
                    "SELECT id FROM mo_report WHERE imei = ? AND momsn = ? AND raw_hex = ?",
                    (delivery.imei, delivery.momsn, raw_hex),
                ).fetchone()["id"]
            )
        return StoredReport(int(row_id or 0), delivery, parsed), new

    def reject_delivery(self, received_utc: datetime, remote: str, reason: str, body: str) -> None:
        """Keep a delivery that could not be accepted at all (bad signature, missing fields) for forensics.

        Bounded: the newest ``REJECTED_KEPT`` deliveries, each body cut at ``REJECTED_BODY_CHARS``; 1,000
        garbage posts once wrote 19 MB in 1.9 s, and an attacker could fill the disk the reports need.
        Best effort: the delivery is refused either way, and a store that cannot be written (a full disk)
        once left the gateway with no answer at all; it is logged instead.
        """
        try:
            with self.store.transaction(self.write_wait_s) as conn:
                newest = conn.execute(
                    "INSERT INTO mo_delivery_rejected (received_utc, remote, reason, body) VALUES (?, ?, ?, ?)",
                    (iso_utc(received_utc), remote, reason, body[:REJECTED_BODY_CHARS]),
                ).lastrowid
                conn.execute(
                    "DELETE FROM mo_delivery_rejected WHERE id <= ?", ((newest or 0) - REJECTED_KEPT,)
                )
        except StoreError as exc:
            log.error("rejected MO delivery from %s (%s) not kept: %s", remote, reason, exc)

    def rejected_deliveries(self) -> list[tuple[str, str]]:
        return [
            (row["reason"], row["body"])
            for row in self.store.query("SELECT reason, body FROM mo_delivery_rejected ORDER BY id")
        ]

    def for_imei(self, imei: str, after_id: int = 0) -> list[StoredReport]:
        """The reports of one modem in time order (arrival order breaks ties); ``after_id``: only those
        stored after that one (ids grow with every store, as SQLite has one writer at a time)."""
        rows = self.store.query(
            "SELECT * FROM mo_report WHERE imei = ? AND id > ? ORDER BY sort_utc, id", (imei, after_id)
        )
        return [_row_to_report(row) for row in rows]

    def tail(self, imei: str, session_after: datetime | None, report_ids: list[int]) -> list[StoredReport]:
        """The end of ``for_imei`` from the first report that came in a session after ``session_after``
        or is one of ``report_ids`` (nothing if neither exists).

        Why: a command's lifecycle only ever looks at reports from those on, and reading them alone keeps
        the work after each post to the few reports still open instead of the whole flight. The session
        time is the one ``StoredReport.session_time`` gives, from the columns the parser filled at insert.
        """
        keys = []
        if session_after is not None:
            keys += self.store.query(
                "SELECT sort_utc, id FROM mo_report WHERE imei = ? "
                "AND COALESCE(transmit_utc, fix_utc, received_utc) > ? ORDER BY sort_utc, id LIMIT 1",
                (imei, iso_utc(session_after)),
            )
        if report_ids:
            marks = ", ".join("?" * len(report_ids))
            keys += self.store.query(
                f"SELECT sort_utc, id FROM mo_report WHERE imei = ? AND id IN ({marks})", (imei, *report_ids)
            )
        if not keys:
            return []
        first = min((row["sort_utc"], row["id"]) for row in keys)
        rows = self.store.query(
            "SELECT * FROM mo_report WHERE imei = ? AND (sort_utc, id) >= (?, ?) ORDER BY sort_utc, id",
            (imei, *first),
        )
        return [_row_to_report(row) for row in rows]


def _row_to_report(row: sqlite3.Row) -> StoredReport:
    """A stored row as the report it was, parsed again from its raw hex (module docstring)."""
    return StoredReport(
        row["id"],
        Delivery(
            imei=row["imei"],
            momsn=row["momsn"],
            data_hex=row["raw_hex"],
            source=row["source"],
            received_utc=parse_iso_utc(row["received_utc"]),
            transmit_utc=_opt_time(row["transmit_utc"]),
            serial=row["serial"],
            iridium_lat=row["iridium_lat"],
            iridium_lon=row["iridium_lon"],
            iridium_cep_km=row["iridium_cep_km"],
            jwt_verified=bool(row["jwt_verified"]),
            raw_delivery=row["raw_delivery"],
        ),
        parse_hex(row["raw_hex"]),
    )

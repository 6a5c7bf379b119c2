"""The 30 real SuperBIT/pyBalloon test-flight logs, turned into DRS MO reports.

Their rows are RockBLOCK deliveries of the beacon's report (same field order as the DRS MO,
drs_protocol.md 3.7, but with ``dd/mm/YYYY,HH:MM:SS`` for the time): each row is re-encoded with
the firmware model's ``format_mo`` and parsed back with ``mo.parse_payload``, so the recovery
code is tested on the path real reports take.
"""

from __future__ import annotations

import csv
from datetime import UTC, datetime
from pathlib import Path

from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.mo import parse_payload
from drs_link.iridium.reports import Delivery, StoredReport

IMEI = "300234010753370"


def flight_reports(path: Path) -> list[StoredReport]:
    reports = []
    with path.open(newline="") as handle:
        for index, row in enumerate(csv.reader(handle)):
            fields = [f for f in row]
            destination = source = 0
            if fields[0].startswith("RB"):
                destination, source = int(fields[0][2:]), int(fields[-1][2:])
                fields = fields[1:-1]
            day, clock = fields[0], fields[1]
            moment = datetime.strptime(f"{day} {clock}", "%d/%m/%Y %H:%M:%S").replace(tzinfo=UTC)
            lat, lon, alt, speed, course, hdop, sats = (float(v) for v in fields[2:9])
            vbat, iteration = float(fields[11]), int(fields[12])
            fix = (
                None
                if moment.year == 1970
                else GnssFix(moment, lat, lon, alt, speed, course, hdop, int(sats))
            )
            payload = format_mo(fix, vbat, iteration, destination, source if destination else 0)
            delivery = Delivery(IMEI, index, payload.hex(), "flight-log", moment)
            reports.append(StoredReport(index + 1, delivery, parse_payload(payload)))
    return reports


def summary(shared_data: Path) -> dict[str, dict[str, str]]:
    folder = shared_data / "tracks" / "pyballoon_superbit"
    with (folder / "flights_summary_derived.csv").open(newline="") as handle:
        return {row["file"]: row for row in csv.DictReader(handle)}

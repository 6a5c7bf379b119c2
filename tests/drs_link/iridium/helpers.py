"""Shared builders for the Iridium tests: a capsule flying through the simulated gateway into a store."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from drs_link.iridium.firmware import GnssFix
from drs_link.iridium.reports import Delivery, ReportStore, StoredReport
from drs_link.sim.rockblock import MoDelivery, SimulatedCapsule, SimulatedRockblock

IMEI = "300234010753370"
T0 = datetime(2026, 7, 1, 10, 0, 7, tzinfo=UTC)


def fix_at(
    moment: datetime, lat: float = 46.5, lon: float = 6.6, alt: float = 500.0, speed: float = 0.0
) -> GnssFix:
    return GnssFix(moment, lat, lon, alt, speed, 0.0, 1.0, 9)


def to_delivery(mo: MoDelivery, received: datetime | None = None) -> Delivery:
    return Delivery(
        imei=mo.imei,
        momsn=mo.momsn,
        data_hex=mo.payload.hex(),
        source="test",
        received_utc=received or mo.transmit_time + timedelta(seconds=5),
        transmit_utc=mo.transmit_time,
        serial=mo.serial,
        iridium_lat=mo.iridium_latitude,
        iridium_lon=mo.iridium_longitude,
        iridium_cep_km=mo.iridium_cep,
    )


def fly(
    capsule: SimulatedCapsule,
    gateway: SimulatedRockblock,
    reports: ReportStore,
    start: datetime,
    cycles: int,
    session_delay_s: float = 40.0,
) -> datetime:
    """Run ``cycles`` capsule cycles on its own interval grid from ``start``; returns the next alarm time."""
    alarm = start
    for _ in range(cycles):
        fix_time = alarm.replace(microsecond=0)
        mo = capsule.session(gateway, fix_at(fix_time), fix_time + timedelta(seconds=session_delay_s))
        reports.add(to_delivery(mo))
        alarm = capsule.next_cycle(alarm)
    return alarm


def accepted(reports: list[StoredReport]) -> list[StoredReport]:
    return [r for r in reports if r.report is not None]

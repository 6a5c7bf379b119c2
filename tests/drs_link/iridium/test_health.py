"""Health findings from report patterns, reports built by the firmware model."""

from __future__ import annotations

from datetime import timedelta

from drs_link.iridium.firmware import format_mo
from drs_link.iridium.health import assess
from drs_link.iridium.mo import parse_payload
from drs_link.iridium.reports import Delivery, StoredReport

from .helpers import IMEI, T0, fix_at


def report(index: int, minute: float, momsn: int, iteration: int, vbat: float = 8.9) -> StoredReport:
    moment = T0 + timedelta(minutes=minute)
    payload = format_mo(fix_at(moment), vbat, iteration)
    return StoredReport(index, Delivery(IMEI, momsn, payload.hex(), "test", moment), parse_payload(payload))


def test_a_clean_two_minute_series_has_no_findings() -> None:
    health = assess([report(i, 2 * i, i, i) for i in range(6)])
    assert health.findings == () and health.last_vbat == 8.9


def test_low_battery_reset_gaps_and_spacing_are_each_flagged() -> None:
    reports = [
        report(1, 0, 10, 5),
        report(2, 2, 11, 6, vbat=6.49),
        report(3, 4, 12, 7, vbat=6.4),
        report(4, 6, 15, 0),
        report(5, 8, 16, 3),
        report(6, 16, 17, 4),
    ]
    health = assess(reports)
    assert health.kinds() == ["low_battery", "momsn_gap", "reset", "iteration_gap", "spacing"]
    assert "6.49 V is below" in health.findings[0].message
    assert "2 report(s) missing before MOMSN 15" in health.findings[1].message
    assert "about 3 cycle(s) missed" in health.findings[4].message


def test_momsn_wraps_without_a_finding_and_spacing_faster_than_the_interval_seen_is_flagged() -> None:
    """Without a command from this console the INTERVAL is the spacing seen (test_interval.py: commanded)."""
    reports = [report(1, 0, 65534, 1), report(2, 2, 65535, 2), report(3, 4, 0, 3), report(4, 6, 1, 4)]
    assert assess(reports).findings == ()
    fast = assess([*reports, report(5, 6.5, 2, 5)])
    assert (
        fast.kinds() == ["spacing"]
        and "0.5 min apart, faster than the INTERVAL of 2 min" in fast.findings[0].message
    )


def test_rejected_payload_is_a_finding_not_a_crash() -> None:
    bad = StoredReport(9, Delivery(IMEI, 3, "00FF", "test", T0), parse_payload(b"\x00\xff"))
    health = assess([report(1, 0, 2, 1), bad])
    assert health.kinds() == ["rejected"]


def test_a_report_imported_late_without_a_transmit_time_is_not_a_65534_report_gap() -> None:
    """An email attachment sorts by its import time; continuity is judged in MOMSN order."""
    in_time_order = [report(1, 0, 20, 1), report(2, 2, 22, 3), report(3, 4, 23, 4), report(4, 60, 21, 2)]
    kinds = assess(in_time_order).kinds()
    assert "momsn_gap" not in kinds and "momsn_repeat" not in kinds


def test_a_real_gap_is_found_across_the_wrap_whatever_the_order() -> None:
    reports = [report(1, 0, 65534, 1), report(2, 2, 1, 4), report(3, 4, 65535, 2), report(4, 6, 2, 5)]
    gaps = [f for f in assess(reports).findings if f.kind.startswith("momsn")]
    assert [f.message for f in gaps] == [
        "1 report(s) missing before MOMSN 1: sent by the capsule, never received here"
    ]

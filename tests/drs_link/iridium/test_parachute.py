"""PARACHUTE timing: the chosen HH:MM is accepted by the firmware model at the fix that downloads it."""

from __future__ import annotations

import random
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from drs_link.iridium.commands import apply_mt
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.mo import parse_payload
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.parachute import OPERATOR_MARGIN, ParachuteRefused, plan_parachute
from drs_link.iridium.reports import Delivery, ReportStore, StoredReport
from drs_link.store import Store

from .helpers import IMEI, fix_at


def history(
    tmp_path: Path, last_fix: datetime, interval_min: int, jitter_s: list[float], no_fix_last: bool = False
) -> list[StoredReport]:
    """Reports on an INTERVAL grid ending at ``last_fix``; each fix is late on its alarm by a jitter."""
    store = ReportStore(Store.open(tmp_path / f"h{interval_min}.sqlite"))
    for report in in_memory_history(last_fix, interval_min, jitter_s, no_fix_last):
        store.add(report.delivery)
    return store.for_imei(IMEI)


def in_memory_history(
    last_fix: datetime, interval_min: int, jitter_s: list[float], no_fix_last: bool = False
) -> list[StoredReport]:
    reports = []
    count = len(jitter_s)
    alarm0 = last_fix - timedelta(seconds=jitter_s[-1]) - (count - 1) * timedelta(minutes=interval_min)
    for i, jitter in enumerate(jitter_s):
        fix_time = (alarm0 + i * timedelta(minutes=interval_min) + timedelta(seconds=jitter)).replace(
            microsecond=0
        )
        fix = None if (no_fix_last and i == count - 1) else fix_at(fix_time)
        payload = format_mo(fix, 8.9, i)
        delivery = Delivery(
            IMEI, i, payload.hex(), "test", fix_time + timedelta(seconds=60), fix_time + timedelta(seconds=35)
        )
        reports.append(StoredReport(i + 1, delivery, parse_payload(payload)))
    return reports


def downloaded_at(plan_text: str, fix_time: datetime) -> bool:
    return apply_mt(plan_text.encode(), fix_at(fix_time)).parachute_opens


def test_two_minute_grid_gives_a_time_accepted_over_many_cycles(tmp_path: Path) -> None:
    last = datetime(2026, 7, 1, 14, 2, 40, tzinfo=UTC)
    reports = history(tmp_path, last, 2, [30, 45, 38, 52, 40])
    plan = plan_parachute(reports, now=last + timedelta(seconds=50), commands=())
    assert plan.interval_min == 2
    assert len(plan.cycles) >= 10
    text = MtComposer().add("PARACHUTE", (plan.hour, plan.minute)).build().text
    for cycle in plan.cycles:
        for second in range(0, int((cycle.fix_latest - cycle.fix_earliest).total_seconds()) + 1, 10):
            assert downloaded_at(text, cycle.fix_earliest + timedelta(seconds=second))
    assert "queue before" in plan.window_text()


def test_send_too_late_for_the_next_session_targets_the_cycle_after(tmp_path: Path) -> None:
    last = datetime(2026, 7, 1, 14, 0, 40, tzinfo=UTC)
    reports = history(tmp_path, last, 30, [40, 40, 40])
    plan = plan_parachute(reports, now=last + timedelta(minutes=29, seconds=50), commands=())
    assert plan.cycles[0].offset == 2
    assert any("INTERVAL is 30 min" in w for w in plan.warnings)


def test_a_plan_never_leaves_the_operator_less_than_the_margin_to_queue_it(tmp_path: Path) -> None:
    """#23: the helper offered "queue before … 5 s left"; such a cycle moves to the next one."""
    last = datetime(2026, 7, 1, 14, 2, 40, tzinfo=UTC)
    reports = history(tmp_path, last, 2, [30, 45, 38, 52, 40])
    first = plan_parachute(reports, now=last + timedelta(seconds=5), commands=())
    for left_s in (60, 44, 20, 5, 1):
        now = first.queue_by - timedelta(seconds=left_s)
        plan = plan_parachute(reports, now=now, commands=())
        assert plan.queue_by - now >= OPERATOR_MARGIN, left_s
        moved = left_s < OPERATOR_MARGIN.total_seconds()
        assert (plan.queue_by > first.queue_by) == moved, left_s


def test_every_interval_gives_an_hhmm_the_firmware_accepts_at_the_downloading_fix() -> None:
    for interval in range(1, 1441):
        rng = random.Random(interval)
        jitter = [rng.uniform(5, 70) for _ in range(4)]
        last = datetime(2026, 7, 1, tzinfo=UTC) + timedelta(minutes=rng.randrange(1440), seconds=jitter[-1])
        reports = in_memory_history(last, interval, jitter)
        now = last + timedelta(minutes=rng.uniform(0, interval))
        plan = plan_parachute(reports, now=now, commands=(), accept_midnight=True)
        assert plan.interval_min == interval
        alarm = last - timedelta(seconds=jitter[-1]) + plan.cycles[0].offset * timedelta(minutes=interval)
        actual_fix = (alarm + timedelta(seconds=rng.uniform(min(jitter), max(jitter)))).replace(microsecond=0)
        assert actual_fix > now, interval
        text = MtComposer().add("PARACHUTE", (plan.hour, plan.minute)).build().text
        assert downloaded_at(text, actual_fix), (interval, plan.window_text(), actual_fix)
        long_warning = any("only" in w for w in plan.warnings)
        assert long_warning == (interval > 10 or len(plan.cycles) == 1), interval


def test_window_near_midnight_is_refused_unless_confirmed_and_then_works_across_it(tmp_path: Path) -> None:
    last = datetime(2026, 7, 1, 23, 56, 30, tzinfo=UTC)
    reports = history(tmp_path, last, 2, [30, 25, 30])
    with pytest.raises(ParachuteRefused, match="within 15 min of 00:00 UTC"):
        plan_parachute(reports, now=last + timedelta(seconds=40), commands=())
    plan = plan_parachute(reports, now=last + timedelta(seconds=40), commands=(), accept_midnight=True)
    text = MtComposer().add("PARACHUTE", (plan.hour, plan.minute)).build().text
    assert downloaded_at(text, datetime(2026, 7, 2, 0, 0, 30, tzinfo=UTC))
    assert any("crosses midnight" in w for w in plan.warnings)


def test_last_report_without_fix_is_refused(tmp_path: Path) -> None:
    last = datetime(2026, 7, 1, 14, 2, 40, tzinfo=UTC)
    reports = history(tmp_path, last, 2, [30, 30, 30], no_fix_last=True)
    with pytest.raises(ParachuteRefused, match="no GNSS fix"):
        plan_parachute(reports, now=last, commands=())


def test_operator_time_outside_the_window_is_refused_and_inside_accepted(tmp_path: Path) -> None:
    last = datetime(2026, 7, 1, 14, 2, 40, tzinfo=UTC)
    reports = history(tmp_path, last, 2, [30, 40, 40])
    with pytest.raises(ParachuteRefused, match=r"13:30 would be rejected .* accepts \d\d:\d\d-\d\d:\d\d"):
        plan_parachute(reports, now=last + timedelta(seconds=30), commands=(), requested=(13, 30))
    plan = plan_parachute(reports, now=last + timedelta(seconds=30), commands=(), requested=(14, 10))
    assert plan.hhmm == "14:10"


def test_no_history_and_single_fix_without_interval_are_refused(tmp_path: Path) -> None:
    with pytest.raises(ParachuteRefused, match="no reports"):
        plan_parachute([], now=datetime(2026, 7, 1, tzinfo=UTC), commands=())
    last = datetime(2026, 7, 1, 14, 2, 40, tzinfo=UTC)
    reports = history(tmp_path, last, 2, [30])
    with pytest.raises(ParachuteRefused, match="only one fix so far and no INTERVAL sent from this console"):
        plan_parachute(reports, now=last, commands=())

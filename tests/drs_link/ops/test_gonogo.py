"""Go/no-go: computed from telemetry; stale is NO-GO; only GNSS and sync can be waived, and audited."""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import pytest

from drs_link.errors import RefusedError
from drs_link.ops.fleet import FleetState
from drs_link.ops.gonogo import (
    ExclusionZone,
    GoNoGoInputs,
    PredictionCheck,
    Verdict,
    WaiverBook,
    evaluate,
)
from drs_link.ops.staleness import Reading
from drs_link.ops.telemetry import GnssSample, ReleaseSample, TelemetryRecord
from drs_link.store import Store

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)


def square(lon: float, lat: float, half: float) -> tuple[tuple[float, float], ...]:
    return (
        (lon - half, lat - half),
        (lon + half, lat - half),
        (lon + half, lat + half),
        (lon - half, lat + half),
    )


def all_go(now: datetime = T0) -> GoNoGoInputs:
    return GoNoGoInputs(
        link_up=Reading(True, now, 10.0),
        microcontroller_waiting=Reading(True, now, 10.0),
        gnss_fix=Reading(True, now, 10.0),
        sync_fraction=Reading(1.0, now, 60.0),
        prediction=Reading(PredictionCheck(-31.0, -64.0, square(-64.0, -31.0, 0.05)), now, 120.0),
        gateway_credentials=Reading(True, now, 600.0),
        powered=True,
        exclusion_zones=(ExclusionZone("Cordoba city", square(-64.2, -31.4, 0.1)),),
    )


def verdicts(inputs: GoNoGoInputs, now: datetime = T0) -> dict[str, Verdict]:
    return {item.key: item.verdict for item in evaluate("DRS1", inputs, now).items}


def test_every_input_good_and_fresh_is_go() -> None:
    report = evaluate("DRS1", all_go(), T0 + timedelta(seconds=5))
    assert report.go and report.summary() == "GO"
    assert len(report.items) == 7


def test_a_stale_gnss_fix_is_no_go_and_says_stale() -> None:
    report = evaluate("DRS1", all_go(), T0 + timedelta(seconds=25))
    gnss = next(i for i in report.items if i.key == "gnss")
    assert not report.go and gnss.verdict is Verdict.NO_GO and gnss.detail.startswith("STALE")


def test_link_down_or_no_power_on_is_no_go() -> None:
    assert verdicts(replace(all_go(), link_up=Reading(False, T0, 10.0)))["link"] is Verdict.NO_GO
    assert verdicts(replace(all_go(), powered=False))["power"] is Verdict.NO_GO


def test_an_ellipse_touching_an_exclusion_zone_is_no_go() -> None:
    over_city = PredictionCheck(-31.4, -64.2, square(-64.2, -31.35, 0.1))
    report = evaluate("DRS1", replace(all_go(), prediction=Reading(over_city, T0, 120.0)), T0)
    item = next(i for i in report.items if i.key == "prediction")
    assert item.verdict is Verdict.NO_GO and "Cordoba city" in item.detail


def test_partial_sync_is_no_go_until_waived_and_the_waiver_is_audited(tmp_path: Path) -> None:
    store = Store.open(tmp_path / "drs.sqlite")
    inputs = replace(all_go(), sync_fraction=Reading(0.82, T0, 60.0))
    assert not evaluate("DRS1", inputs, T0).go
    book = WaiverBook(store, "DRS1", clock=lambda: T0)
    book.grant("sync", "EL", "last 18% are duplicates of the ground copy")
    report = evaluate("DRS1", inputs, T0, book.waivers)
    assert report.go
    sync = next(i for i in report.items if i.key == "sync")
    assert sync.verdict is Verdict.WAIVED and "waived by EL" in sync.detail and "82.0%" in sync.detail
    assert [(a.action, a.result, a.detail) for a in store.audit("DRS1")] == [
        ("waiver", "granted", {"item": "sync", "reason": "last 18% are duplicates of the ground copy"})
    ]


def test_the_link_and_the_prediction_cannot_be_waived(tmp_path: Path) -> None:
    book = WaiverBook(Store.open(tmp_path / "drs.sqlite"), "DRS1")
    for item in ("link", "prediction", "gateway", "microcontroller"):
        with pytest.raises(RefusedError, match="cannot be waived"):
            book.grant(item, "EL", "in a hurry")
    with pytest.raises(RefusedError, match="reason"):
        book.grant("gnss", "EL", "  ")


def test_the_fingerprint_follows_the_verdicts_not_ages_or_small_moves(tmp_path: Path) -> None:
    base = evaluate("DRS1", all_go(), T0).fingerprint
    later = replace(all_go(), link_up=Reading(True, T0 + timedelta(seconds=3), 10.0))
    assert evaluate("DRS1", later, T0 + timedelta(seconds=3)).fingerprint == base
    moved = PredictionCheck(-31.01, -64.0, square(-64.0, -31.01, 0.05))
    assert evaluate("DRS1", replace(all_go(), prediction=Reading(moved, T0, 120.0)), T0).fingerprint == base
    no_fix = replace(all_go(), gnss_fix=Reading(False, T0, 10.0))
    assert evaluate("DRS1", no_fix, T0).fingerprint != base
    book = WaiverBook(Store.open(tmp_path / "drs.sqlite"), "DRS1", clock=lambda: T0)
    book.grant("gnss", "EL", "drop without a fix")
    assert evaluate("DRS1", no_fix, T0, book.waivers).fingerprint not in (
        base,
        evaluate("DRS1", no_fix, T0).fingerprint,
    )


def test_after_release_the_poll_says_released_and_greys_every_pre_release_check() -> None:
    """With the Pi shut down, "Microcontroller talking ✔ GO, NMEA 0 s old" contradicted the release."""
    now = datetime(2026, 9, 1, 12, 5, tzinfo=UTC)
    fleet = FleetState.for_capsules(["DRS1"], 10.0)
    released_at = datetime(2026, 9, 1, 12, 3, 41, tzinfo=UTC)
    fleet.apply(
        TelemetryRecord(now, "DRS1", ReleaseSample("released", nmea_seen=True, released_at=released_at))
    )
    fleet.apply(TelemetryRecord(now, "DRS1", GnssSample(has_fix=True)))
    report = evaluate("DRS1", fleet.capsules["DRS1"].gonogo_inputs(now, ()), now)
    assert not report.go and report.summary() == "NO-GO: Released: released 12:03Z, Pi shut down"
    assert [i.verdict for i in report.items][1:] == [Verdict.NOT_APPLICABLE] * (len(report.items) - 1)
    assert all(i.detail == "no longer applies after release" for i in report.items[1:])

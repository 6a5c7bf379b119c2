"""The fleet state folded from telemetry: stale values reach checklists as no data, periods follow the source."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

from drs_link.ops.fleet import FleetState
from drs_link.ops.gonogo import evaluate
from drs_link.ops.staleness import Freshness
from drs_link.ops.telemetry import (
    GatewaySample,
    GnssSample,
    LinkSample,
    PredictionSample,
    ReportSample,
    TelemetryRecord,
)
from tests.samples import prediction

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)


def test_a_stale_fix_reaches_the_checklists_as_no_data() -> None:
    fleet = FleetState.for_capsules(["DRS1"])
    fleet.apply(TelemetryRecord(T0, "DRS1", GnssSample(has_fix=True, sats=9)))
    assert fleet.capsules["DRS1"].facts(T0 + timedelta(seconds=5))["gnss_fix"] is True
    assert fleet.capsules["DRS1"].facts(T0 + timedelta(seconds=25))["gnss_fix"] is None


def test_a_slower_poller_makes_polled_values_age_more_slowly_but_not_reports() -> None:
    fleet = FleetState.for_capsules(["DRS1"], poll_period_s=60.0)
    fleet.apply(TelemetryRecord(T0, "DRS1", LinkSample(up=True)))
    fleet.apply(TelemetryRecord(T0, "DRS1", ReportSample(vbat=8.8, interval_min=10)))
    telemetry = fleet.capsules["DRS1"]
    assert telemetry.reading(LinkSample).freshness(T0 + timedelta(seconds=100)) is Freshness.FRESH
    assert telemetry.reading(ReportSample).expected_period_s == 600.0
    assert telemetry.facts(T0)["interval_min"] == 10


def test_gateway_health_reaches_every_capsule_poll() -> None:
    fleet = FleetState.for_capsules(["DRS1", "DRS2"])
    fleet.apply(TelemetryRecord(T0, None, GatewaySample(credentials_ok=False)))
    for name in ("DRS1", "DRS2"):
        report = evaluate(name, fleet.capsules[name].gonogo_inputs(T0, ()), T0)
        gateway = next(item for item in report.items if item.key == "gateway")
        assert gateway.detail == "invalid or missing"


def test_a_prediction_for_later_does_not_replace_the_release_now_one() -> None:
    fleet = FleetState.for_capsules(["DRS1"])
    now = prediction(release_in_min=0, landing_lat=1.0, landing_lon=2.0)
    later = prediction(release_in_min=10, landing_lat=3.0, landing_lon=4.0)
    fleet.apply(TelemetryRecord(T0, "DRS1", now))
    fleet.apply(TelemetryRecord(T0, "DRS1", later))
    telemetry = fleet.capsules["DRS1"]
    assert telemetry.reading(PredictionSample).value == now
    assert telemetry.predictions[10].value == later

"""Where a predicted release starts: the capsule's fresh fix, else the balloon's fresh position, else nothing."""

from __future__ import annotations

from dataclasses import replace
from datetime import UTC, datetime, timedelta

from drs_link.ops.fleet import FleetState
from drs_link.ops.origin import release_origin
from drs_link.ops.telemetry import BalloonSample, GnssSample, TelemetryRecord

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)
FIX = GnssSample(has_fix=True, lat=67.9, lon=21.1, alt_m=31400.0)
BALLOON = BalloonSample(lat=67.8, lon=21.3, alt_m=31500.0, source="ozimux via udp")


def fleet(gnss_age_s: float | None, balloon_age_s: float | None, fix: GnssSample = FIX) -> FleetState:
    state = FleetState.for_capsules(["DRS1"])
    if gnss_age_s is not None:
        state.apply(TelemetryRecord(T0 - timedelta(seconds=gnss_age_s), "DRS1", fix))
    if balloon_age_s is not None:
        state.apply(TelemetryRecord(T0 - timedelta(seconds=balloon_age_s), None, BALLOON))
    return state


def test_a_fresh_capsule_fix_wins_over_the_balloon_feed() -> None:
    origin = release_origin(fleet(5, 1), "DRS1", T0)
    assert origin is not None and (origin.lat, origin.alt_m, origin.source) == (67.9, 31400.0, "DRS1 GNSS")


def test_the_balloon_feed_when_the_capsule_fix_is_stale_or_has_no_fix() -> None:
    for state in (fleet(60, 1), fleet(5, 1, replace(FIX, has_fix=False)), fleet(None, 1)):
        origin = release_origin(state, "DRS1", T0)
        assert origin is not None and origin.source == "balloon feed (ozimux via udp)" and origin.lat == 67.8


def test_nothing_starts_from_a_stale_position() -> None:
    assert release_origin(fleet(60, 600), "DRS1", T0) is None
    assert release_origin(fleet(None, None), "DRS1", T0) is None

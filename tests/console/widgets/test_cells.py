"""The wording of each field: short forms that fit their column, long forms in words, ages and STALE."""

from __future__ import annotations

from datetime import timedelta
from typing import Any

import pytest
from rich.cells import cell_len

from console.widgets.cells import FIELDS, Field, age_shown, balloon_lines, short_age
from drs_link.feeds.balloon_feed import FeedStatus
from drs_link.ops.fleet import PERIOD_S, CapsuleTelemetry, FleetState
from drs_link.ops.staleness import MISSING_TEXT, STALE_GLYPH, Reading
from drs_link.ops.telemetry import SAMPLES, BalloonSample, TelemetryRecord
from tests.console.conftest import T0
from tests.samples import REQUIRED

BY_KIND = {field.kind: field for field in FIELDS}


def telemetry(kind: str, data: dict[str, Any], age_s: float) -> CapsuleTelemetry:
    capsule = CapsuleTelemetry("DRS1")
    capsule.apply(TelemetryRecord(T0 - timedelta(seconds=age_s), "DRS1", SAMPLES[kind](**data)))
    return capsule


def short(kind: str, data: dict[str, Any], age_s: float = 3.0) -> str:
    return BY_KIND[kind].cell(telemetry(kind, data, age_s), T0).text


def long(kind: str, data: dict[str, Any], age_s: float = 3.0) -> str:
    return BY_KIND[kind].line(telemetry(kind, data, age_s), T0).text


PREDICTION = REQUIRED["prediction"]
"""Landing 67.9501, 22.2289, 47.4 km at 81.2°, σ∥ 1.97 σ⊥ 1.73 km."""
STORAGE = {"used_bytes": 12_400_000_000, "total_bytes": 128_000_000_000, "raid": "healthy"}


@pytest.mark.parametrize(
    ("kind", "data", "age_s", "expected"),
    [
        ("link", {"up": True}, 3, "UP 3s"),
        ("link", {"up": False}, 150, f"{STALE_GLYPH}DOWN 2m"),
        ("release", {"state": "powered", "nmea_seen": False}, 3, "PWR noNMEA 3s"),
        ("release", {"state": "power-on-unknown"}, 3, "PWR ? 3s"),
        ("gnss", {"has_fix": True, "sats": 9, "hdop": 0.9}, 3, "9sv H0.9 3s"),
        ("gnss", {"has_fix": False, "sats": 2}, 3, "NOFIX 2sv 3s"),
        ("storage", STORAGE, 4, "116G free 4s"),
        ("storage", {**STORAGE, "raid": "degraded"}, 4, "RAID! 116G 4s"),
        ("sync", {"fraction": 0.63, "bytes_pending": 10}, 5, "63% 5s"),
        ("sync", {"fraction": 0.999, "bytes_pending": 10}, 5, "99% 5s"),
        ("report", {"vbat": 7.93, "alt_m": 12_300.0}, 30, "7.9V 12km 30s"),
        ("prediction", PREDICTION, 5, "47km σ2.0 5s"),
    ],
)
def test_short_forms(kind: str, data: dict[str, Any], age_s: float, expected: str) -> None:
    assert short(kind, data, age_s) == expected


def test_long_forms_say_everything_in_words() -> None:
    gnss = {"has_fix": True, "sats": 9, "hdop": 0.9, "lat": 67.8887, "lon": 21.0856, "alt_m": 31_500.0}
    assert long("gnss", gnss) == "fix, 9 satellites, HDOP 0.9, 67.8887 21.0856 31.5 km — 3s ago"
    storage = long("storage", {**STORAGE, "raid": "degraded"}, age_s=150)
    assert storage == f"12.4 of 128 GB used, 116 GB free, RAID degraded — {STALE_GLYPH}STALE 2m30s ago"
    assert long("prediction", PREDICTION, age_s=5) == (
        "landing 67.950, 22.229, 47.4 km at 81° from release, σ∥ 1.97 σ⊥ 1.73 km — 5s ago"
    )
    assert long("sync", {"fraction": 0.5, "bytes_pending": 400_000, "files_pending": 3}) == (
        "50% synced, 400 kB in 3 files pending — 3s ago"
    )


def test_a_missing_value_is_a_dash() -> None:
    empty = CapsuleTelemetry("DRS1")
    for field in FIELDS:
        assert field.cell(empty, T0).text == MISSING_TEXT
        assert field.line(empty, T0).text.startswith(MISSING_TEXT)


def test_staleness_follows_each_kinds_period() -> None:
    for field in FIELDS:
        data = REQUIRED.get(field.kind, {})
        limit = 2 * PERIOD_S[field.kind]
        assert not short(field.kind, data, age_s=limit).startswith(STALE_GLYPH), field.kind
        assert short(field.kind, data, age_s=limit + 1).startswith(STALE_GLYPH), field.kind
        assert "STALE" in long(field.kind, data, age_s=limit + 1), field.kind


WIDEST: dict[str, list[dict[str, Any]]] = {
    "link": [{"up": False}],
    "release": [{"state": "powered", "nmea_seen": False}, {"state": "go-sent-unverified"},
                {"state": "some-new-state-name"}],
    "gnss": [{"has_fix": False, "sats": 12}, {"has_fix": True, "sats": 12, "hdop": 99.99}],
    "storage": [{"used_bytes": 0, "total_bytes": 12_000_000_000_000, "raid": "degraded"},
                {"used_bytes": 0, "total_bytes": 9_999_000_000, "raid": "unknown"}],
    "sync": [{"fraction": 1.0}, {"fraction": None}],
    "report": [{"vbat": 12.6, "landed": True}, {"vbat": 18.0, "alt_m": 9_950.0}, {}],
    "prediction": [{**PREDICTION, "distance_km": 1200.0, "sigma_par_km": 1500.0}],
}  # fmt: skip


@pytest.mark.parametrize("field", FIELDS, ids=[f.kind for f in FIELDS])
def test_the_widest_stale_cell_fits_its_column(field: Field) -> None:
    for data in WIDEST[field.kind]:
        for age_s in (9.0, 59 * 60.0, 23 * 3600.0, 999 * 86400.0, -59.0):
            text = short(field.kind, data, age_s)
            assert cell_len(text) <= field.width, (text, field.width)


def test_short_ages_use_one_unit() -> None:
    assert [short_age(s) for s in (0, 59.9, 60, 3599, 3600, 86399, 86400 * 3, -5)] == [
        "0s", "59s", "1m", "59m", "1h", "23h", "3d", "-5s",
    ]  # fmt: skip


def test_old_ages_change_in_steps_that_grow_with_them() -> None:
    assert [age_shown(s) for s in (0.0, 4.9, 59.9, 60.0, 125.0, 599.0, 600.0, 3599.0, 7265.0, -3.0)] == [
        0.0, 4.9, 59.9, 60.0, 120.0, 590.0, 600.0, 3540.0, 7265.0, -3.0,
    ]  # fmt: skip
    assert [short_age(s) for s in (125.0, 3599.0)] == ["2m", "59m"]


def test_telemetry_of_the_wrong_shape_is_named_not_raised() -> None:
    bad = {"has_fix": True, "sats": 9, "hdop": "0.9"}
    cell = BY_KIND["gnss"].cell(telemetry("gnss", bad, 1), T0)
    assert (cell.text, cell.level) == ("BAD DATA 1s", "bad")
    line = BY_KIND["gnss"].line(telemetry("gnss", bad, 1), T0)
    assert line.text.startswith("unreadable gnss data (") and line.level == "bad"
    stale = BY_KIND["gnss"].cell(telemetry("gnss", bad, 2 * PERIOD_S["gnss"] + 1), T0)
    assert stale.text.startswith(f"{STALE_GLYPH}BAD DATA") and stale.level == "bad"


BALLOON = {"lat": 67.9, "lon": 21.1, "alt_m": 31_200.0, "format": "ozimux", "source": "udp 0.0.0.0:8942"}


def balloon_reading(age_s: float) -> Reading[BalloonSample]:
    fleet = FleetState()
    fleet.apply(TelemetryRecord(T0 - timedelta(seconds=age_s), None, BalloonSample(**BALLOON)))
    return fleet.balloon


def test_balloon_line_names_where_the_position_came_from() -> None:
    assert balloon_lines(balloon_reading(4), None, T0) == [
        "Balloon: 67.9000, 21.1000 at 31.2 km (ozimux via udp 0.0.0.0:8942) (4s)"
    ]


def test_balloon_line_marks_an_old_position_stale_in_words() -> None:
    line = balloon_lines(balloon_reading(PERIOD_S["balloon"] * 2 + 1), None, T0)[0]
    assert line.startswith(f"Balloon: {STALE_GLYPH}STALE 67.9000")


def test_without_a_feed_or_position_the_line_says_what_predictions_wait_for() -> None:
    assert balloon_lines(FleetState().balloon, None, T0) == [
        f"Balloon: {MISSING_TEXT} (no [balloon_feed] configured: predictions wait for a capsule's own GNSS)"
    ]


def test_a_feed_that_rejects_lines_or_fails_says_so_under_the_position() -> None:
    status = FeedStatus(
        source="tcp 10.0.0.5:8942", state="reconnecting in 4 s", accepted=12, rejected=3, out_of_order=1,
        last_rejection="bad checksum: the sentence does not match its *hh", last_error="connection refused",
    )  # fmt: skip
    assert balloon_lines(balloon_reading(4), status, T0)[1] == (
        "Feed tcp 10.0.0.5:8942 reconnecting in 4 s: 12 fixes, 3 rejected (last: bad checksum: the sentence"
        " does not match its *hh), 1 out of order; connection refused"
    )


def test_after_release_what_came_from_the_pi_is_history_not_an_alarm() -> None:
    # Go shuts the Pi down: a link down and NMEA minutes old are what Go leaves, not faults.
    capsule = telemetry("link", {"up": False, "note": "released: the Pi shut down"}, 150)
    capsule.apply(
        TelemetryRecord(T0 - timedelta(seconds=400), "DRS1", SAMPLES["gnss"](has_fix=True, sats=9, hdop=0.9))
    )
    before = BY_KIND["link"].cell(capsule, T0)
    assert before.text == f"{STALE_GLYPH}DOWN 2m" and before.level == "stale"
    capsule.apply(TelemetryRecord(T0 - timedelta(seconds=150), "DRS1", SAMPLES["release"](state="released")))
    link, gnss = BY_KIND["link"].cell(capsule, T0), BY_KIND["gnss"].cell(capsule, T0)
    assert (link.text, link.level) == ("DOWN 2m", "none") and (gnss.text, gnss.level) == (
        "9sv H0.9 6m",
        "none",
    )
    assert BY_KIND["gnss"].line(capsule, T0).text.endswith("6m40s ago; history: the Pi shut down at Go")
    assert BY_KIND["release"].cell(capsule, T0).level == "ok", "the release itself is news"


@pytest.mark.parametrize("ahead_s", [0.5, 4.0, 9.0])
def test_a_reading_newer_than_the_view_time_is_fresh_not_from_the_future(ahead_s: float) -> None:
    """The view time trails the clock by up to one step, so a reading taken since reads as 0 s old."""
    assert short("link", {"up": True}, -ahead_s) == "UP 0s"
    assert long("link", {"up": True}, -ahead_s).endswith("— 0s ago")


def test_a_reading_further_ahead_than_a_view_step_says_the_clock_is_wrong() -> None:
    assert short("link", {"up": True}, -60.0) == "UP -1m"
    assert long("link", {"up": True}, -60.0).endswith("timestamped in the future (clock skew?)")

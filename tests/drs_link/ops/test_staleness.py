"""Staleness: every value carries its age and says STALE in words, not only in colour."""

from __future__ import annotations

from datetime import UTC, datetime, timedelta

import pytest

from drs_link.ops.staleness import STALE_GLYPH, Freshness, Reading, format_age

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)


def test_a_reading_is_fresh_within_twice_its_period_and_stale_after() -> None:
    reading = Reading(9, T0, expected_period_s=10.0)
    assert reading.freshness(T0 + timedelta(seconds=20)) is Freshness.FRESH
    assert reading.freshness(T0 + timedelta(seconds=20.5)) is Freshness.STALE


def test_a_stale_label_carries_a_glyph_and_the_word_stale() -> None:
    reading = Reading(9, T0, expected_period_s=10.0)
    assert reading.label(T0 + timedelta(seconds=5), lambda v: f"{v} sats") == "9 sats (5s)"
    stale = reading.label(T0 + timedelta(seconds=125), lambda v: f"{v} sats")
    assert stale == f"{STALE_GLYPH}STALE 9 sats (2m05s)"


def test_a_never_received_value_is_missing_not_fresh() -> None:
    reading: Reading[int] = Reading.missing(10.0)
    assert reading.freshness(T0) is Freshness.MISSING
    assert not reading.is_fresh(T0)
    assert reading.label(T0) == "—"


def test_ages_read_naturally_at_every_scale() -> None:
    assert [format_age(s) for s in (0, 59, 61, 3599, 3600 * 2 + 60 * 14, 86400 * 3)] == [
        "0s",
        "59s",
        "1m01s",
        "59m59s",
        "2h14m",
        "3d",
    ]


def test_a_naive_time_or_a_silly_period_is_refused() -> None:
    with pytest.raises(ValueError, match="naive"):
        Reading(1, datetime(2026, 1, 1), 10.0)
    with pytest.raises(ValueError, match="period"):
        Reading(1, T0, 0.0)

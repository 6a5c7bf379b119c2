"""The release-window sweep read once into typed values: times as datetimes, reasons kept in order."""

from __future__ import annotations

from datetime import UTC, datetime

from drs_link.ops.release_window import ReleaseCandidate, ReleaseWindow


def test_the_sweep_is_read_into_typed_candidates_with_their_times_and_reasons() -> None:
    window = ReleaseWindow.from_sweep({
        "computed_at": "2026-09-01T11:59:30+00:00", "origin_source": "DRS1 GNSS", "every_minutes": 5,
        "verdict": "go", "recommended": 1,
        "candidates": [
            {"time": "2026-09-01T12:00:00+00:00", "go": False, "landed": False,
             "reasons": ["left the weather"]},
            {"time": "2026-09-01T12:05:00+00:00", "go": True, "landed": True, "reasons": []},
        ],
    })  # fmt: skip
    assert window.computed_at == datetime(2026, 9, 1, 11, 59, 30, tzinfo=UTC)
    assert window.every_minutes == 5.0 and window.recommended == 1
    assert window.candidates == (
        ReleaseCandidate(datetime(2026, 9, 1, 12, 0, tzinfo=UTC), False, False, ("left the weather",)),
        ReleaseCandidate(datetime(2026, 9, 1, 12, 5, tzinfo=UTC), True, True, ()),
    )

"""Each telemetry kind is a typed sample; recordings keep format version 1, and a bad field is named."""

from __future__ import annotations

import os
import stat
from datetime import UTC, datetime
from pathlib import Path

import pytest

from drs_link.ops.telemetry import (
    SAMPLES,
    BalloonSample,
    Contour,
    PredictionSample,
    ReleaseSample,
    ReportSample,
    TelemetryFormatError,
    TelemetryRecord,
    TelemetryRecorder,
    read_recording,
)
from tests.samples import REQUIRED, prediction

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)

V1_LINES = [
    # As the console wrote them before the kinds were typed: times in both ISO forms, lists for tuples.
    '{"capsule": "DRS1", "data": {"nmea_seen": true, "note": null, "released_at": "2026-09-01T12:03:41+00:00",'
    ' "state": "released"}, "kind": "release", "t": "2026-09-01T12:04:00.000Z", "v": 1}',
    '{"capsule": null, "data": {"alt_m": 31200.0, "format": "ozimux", "lat": 67.9, "lon": 21.1,'
    ' "received_at": "2026-09-01T12:00:01.500Z", "source": "udp 0.0.0.0:8942"}, "kind": "balloon",'
    ' "t": "2026-09-01T12:00:01.000Z", "v": 1}',
    '{"capsule": "DRS1", "data": {"alt_m": 412.0, "has_fix": true, "interval_min": 5, "iteration": 7,'
    ' "landed": true, "lat": 67.7, "lon": 21.6, "momsn": 7, "position_source": "gnss", "sats": 9,'
    ' "speed_ms": 0.0, "uncertainty_m": 4.5, "vbat": 8.7}, "kind": "report", "t": "2026-09-01T12:30:00.000Z",'
    ' "v": 1}',
    '{"capsule": "DRS1", "data": {"bearing_deg": 81.2, "contours": [{"major_km": 3.94, "minor_km": 3.46,'
    ' "n_sigma": 2.0, "probability": 0.865}], "descent_s": 2460.0, "distance_km": 47.4, "is_demo": true,'
    ' "landing_lat": 67.95, "landing_lon": 22.23, "landing_time": "2026-09-01T12:41:00+00:00",'
    ' "major_axis_bearing_deg": 81.2, "model": "drs profile", "origin_source": "DRS1 GNSS",'
    ' "outline_2sigma": [[22.1, 67.93], [22.3, 67.97]], "path": [[21.08, 67.88], [22.23, 67.95]],'
    ' "release_in_min": 0, "release_lat": 67.88, "release_lon": 21.08,'
    ' "release_time": "2026-09-01T12:00:00+00:00", "sigma_par_km": 1.97, "sigma_perp_km": 1.73,'
    ' "warnings": []}, "kind": "prediction", "t": "2026-09-01T12:00:00.000Z", "v": 1}',
]


def test_a_version_1_recording_made_before_the_kinds_were_typed_still_replays(tmp_path: Path) -> None:
    path = tmp_path / "old.jsonl"
    path.write_text("\n".join(V1_LINES) + "\n")
    prediction_now, balloon, release, report = (r.data for r in read_recording(path))
    assert isinstance(release, ReleaseSample) and release.released
    assert release.after_release() == "released 12:03Z, Pi shut down"
    assert balloon == BalloonSample(67.9, 21.1, 31200.0, "ozimux", "udp 0.0.0.0:8942",
                                    datetime(2026, 9, 1, 12, 0, 1, 500_000, tzinfo=UTC))  # fmt: skip
    assert isinstance(prediction_now, PredictionSample)
    assert prediction_now.contours == (Contour(2.0, 0.865, 3.94, 3.46),)
    assert prediction_now.outline_2sigma == ((22.1, 67.93), (22.3, 67.97))
    assert prediction_now.release_time == T0
    assert isinstance(report, ReportSample) and report.landed and report.interval_min == 5


def test_every_kind_round_trips_exactly() -> None:
    samples = [cls(**REQUIRED.get(kind, {})) for kind, cls in SAMPLES.items()]
    samples.append(prediction(warnings=("demo weather",), model="drs profile", origin_source="DRS1 GNSS"))
    for sample in samples:
        record = TelemetryRecord(T0, "DRS1", sample)
        assert TelemetryRecord.from_json(record.to_json(), "test") == record


@pytest.mark.parametrize(
    ("kind", "data", "message"),
    [
        ("gnss", '{"has_fix": true, "hdop": "0.9"}', "t.jsonl:1: gnss.hdop: expected a number, got '0.9'"),
        ("link", '{"note": "up"}', "t.jsonl:1: link.up: missing"),
        ("release", '{"state": "released", "released_at": "noon"}',
         "t.jsonl:1: release.released_at: expected an ISO 8601 time, got 'noon'"),
        ("report", '{"interval_min": 2.5}', "t.jsonl:1: report.interval_min: expected a whole number, got 2.5"),
        ("report", '{"landed": "yes"}', "t.jsonl:1: report.landed: expected true or false, got 'yes'"),
        ("prediction_status", '{"short": null, "text": "x"}', "prediction_status.short: expected text, got None"),
    ],
)  # fmt: skip
def test_a_malformed_field_is_named_by_file_line_kind_and_field(
    tmp_path: Path, kind: str, data: str, message: str
) -> None:
    path = tmp_path / "t.jsonl"
    path.write_text(
        f'{{"v": 1, "t": "2026-09-01T12:00:00Z", "capsule": "DRS1", "kind": "{kind}", "data": {data}}}\n'
    )
    with pytest.raises(TelemetryFormatError, match=message.replace(".", r"\.")):
        read_recording(path)


def test_a_malformed_part_of_a_prediction_is_named_down_to_the_item(tmp_path: Path) -> None:
    line = TelemetryRecord(T0, "DRS1", prediction()).to_json().replace("[22.3, 67.93]", '[22.3, "north"]')
    (tmp_path / "t.jsonl").write_text(line + "\n")
    with pytest.raises(
        TelemetryFormatError, match=r"t\.jsonl:1: prediction\.outline_2sigma\[1\]\[1\]: expected a"
    ):
        read_recording(tmp_path / "t.jsonl")


def test_a_recording_is_created_for_its_owner_and_group_only(tmp_path: Path) -> None:
    """Like an export (#16: files were 0644, readable by every user of the laptop); the umask is cleared so
    that a mode coming from it, not from the recorder, would show."""
    old = os.umask(0)
    try:
        recorder = TelemetryRecorder(tmp_path / "launch.jsonl")
    finally:
        os.umask(old)
    recorder.append(TelemetryRecord(T0, "DRS1", ReleaseSample("idle")))
    recorder.close()
    assert stat.S_IMODE((tmp_path / "launch.jsonl").stat().st_mode) == 0o640
    assert [r.data for r in read_recording(tmp_path / "launch.jsonl")] == [ReleaseSample("idle")]

"""Track readers: every format, the real files, and malformed input that must fail clearly."""

from __future__ import annotations

import re
import tempfile
from datetime import UTC, date, datetime
from pathlib import Path

import pytest
from hypothesis import HealthCheck, given, settings, strategies as st

from predictor.errors import PredictorError
from predictor.tracks.reading import (
    Fix,
    TrackError,
    read_canonical_csv,
    read_gpx,
    read_superbit_log,
    read_track,
    read_v4_csv,
    write_canonical_csv,
)

FLIGHT_FILE = re.compile(r"^\d+-\d+-\d+(_\d)?\.csv$")


def superbit_files(shared_data: Path) -> list[Path]:
    folder = shared_data / "tracks" / "pyballoon_superbit"
    return sorted(p for p in folder.iterdir() if FLIGHT_FILE.match(p.name))


def test_all_thirty_superbit_logs_read_every_row(shared_data: Path) -> None:
    files = superbit_files(shared_data)
    assert len(files) == 30
    for path in files:
        rows = [line for line in path.read_text().splitlines() if line.strip()]
        track = read_track(path)
        assert track.format == "superbit-rockblock"
        assert len(track.fixes) == len(rows), path.name
        assert [f.line for f in track.fixes] == list(range(1, len(rows) + 1))


def test_superbit_rb_row_fields_land_in_the_right_places(shared_data: Path) -> None:
    fix = read_superbit_log(shared_data / "tracks/pyballoon_superbit/18-10-28.csv").fixes[0]
    # RB0013660,28/10/2018,08:56:40,30.849157,-6.819067,1168,0.1,0,1.6,6,87812,17.4,4.7,0,RB0013661
    assert fix.time == datetime(2018, 10, 28, 8, 56, 40, tzinfo=UTC)
    assert (fix.lat, fix.lon, fix.alt_m) == (30.849157, -6.819067, 1168.0)
    assert (fix.speed_ms, fix.course_deg, fix.sats, fix.pressure_pa) == (0.1, 0.0, 6, 87812.0)


def test_superbit_padded_row_without_serials_reads_like_the_rb_rows(shared_data: Path) -> None:
    track = read_superbit_log(shared_data / "tracks/pyballoon_superbit/18-12-15.csv")
    padded = next(f for f in track.fixes if f.line == 49)
    # 15/12/2018,10:29:16,45.790962,8.041806,11887,40.3,144,0.9,7,19704,-13.4,4.07,48,,
    assert padded.time == datetime(2018, 12, 15, 10, 29, 16, tzinfo=UTC)
    assert (padded.lat, padded.lon, padded.alt_m, padded.pressure_pa) == (
        45.790962,
        8.041806,
        11887.0,
        19704.0,
    )
    assert track.fixes[0].pressure_pa == 94919.0


def test_superbit_invalid_1970_row_is_read_not_dropped(shared_data: Path) -> None:
    """Dropping it is a cleaning rule, reported there; the reader keeps every parseable row."""
    track = read_superbit_log(shared_data / "tracks/pyballoon_superbit/18-8-13.csv")
    row = next(f for f in track.fixes if f.line == 31)
    assert row.time.year == 1970 and row.lat == 0.0 and row.lon == 0.0


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("RB0013660,28/10/2018,08:56:40,30.8,-6.8,1168,0.1,0\n", r":1: expected 13 data fields"),
        (
            "28/10/2018,08:56:40,30.8,-6.8,1168,0.1,0,1.6,6,87812,17.4,4.7,0\n2018-10-28,x\n",
            r":2: expected 13",
        ),
        (
            "28/10/2018,08:56:40,30.8,north,1168,0.1,0,1.6,6,87812,17.4,4.7,0\n",
            r":1: longitude 'north' is not a number",
        ),
        (
            "28/13/2018,08:56:40,30.8,-6.8,1168,0.1,0,1.6,6,87812,17.4,4.7,0\n",
            r":1: date/time .* is not 'dd/mm/YYYY",
        ),
        (
            "28/10/2018,08:56:40,30.8,-6.8,nan,0.1,0,1.6,6,87812,17.4,4.7,0\n",
            r":1: altitude 'nan' is not a finite",
        ),
    ],
)
def test_superbit_malformed_rows_name_file_and_line(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.csv"
    path.write_text(content)
    with pytest.raises(TrackError, match=re.escape(str(path)) + message):
        read_superbit_log(path)


def test_canonical_csv_round_trips_a_real_flight(tmp_path: Path, shared_data: Path) -> None:
    original = read_track(shared_data / "tracks/pyballoon_superbit/18-3-4.csv")
    out = tmp_path / "18-3-4.csv"
    write_canonical_csv(original.fixes, out)
    back = read_track(out)
    assert back.format == "canonical-csv"
    assert len(back.fixes) == len(original.fixes)
    for a, b in zip(original.fixes, back.fixes, strict=True):
        assert (a.time, a.lat, a.lon, a.alt_m, a.pressure_pa, a.speed_ms) == (
            b.time,
            b.lat,
            b.lon,
            b.alt_m,
            b.pressure_pa,
            b.speed_ms,
        )


def test_canonical_csv_without_pressure_and_with_offsets_reads_as_utc(tmp_path: Path) -> None:
    path = tmp_path / "t.csv"
    path.write_text(
        "time,lat,lon,alt_m\n2024-05-01T12:00:00Z,46.2,6.1,30000\n2024-05-01T14:00:30+02:00,46.3,6.2,29000\n"
    )
    fixes = read_canonical_csv(path).fixes
    assert fixes[0].pressure_pa is None
    assert fixes[1].time == datetime(2024, 5, 1, 12, 0, 30, tzinfo=UTC)
    assert fixes[1].line == 3


def test_canonical_writer_keeps_subsecond_times(tmp_path: Path) -> None:
    fix = Fix(time=datetime(2024, 5, 1, 12, 0, 0, 250000, tzinfo=UTC), lat=1.5, lon=-2.5, alt_m=100.25)
    path = tmp_path / "t.csv"
    write_canonical_csv([fix], path)
    assert "2024-05-01T12:00:00.25Z" in path.read_text()
    assert read_canonical_csv(path).fixes[0].time == fix.time


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("", r": empty file"),
        ("when,lat,lon,alt\n", r":1: header must be"),
        ("time,lat,lon,alt_m\n2024-05-01T12:00:00Z,46.2,6.1\n", r":2: expected 4 fields, got 3"),
        ("time,lat,lon,alt_m\n2024-05-01T12:00:00,46.2,6.1,100\n", r":2: time .* has no time zone"),
        ("time,lat,lon,alt_m\n01/05/2024 12:00,46.2,6.1,100\n", r":2: time .* is not ISO 8601"),
        ("time,lat,lon,alt_m,pressure_pa\n2024-05-01T12:00:00Z,46.2,6.1,100,low\n", r":2: pressure_pa 'low'"),
        ("time,lat,lon,alt_m\n", r": no fixes in the file"),
        ("time,lat,lon,alt_m\n2024-05-01T12:00:00Z,46.2,6.1,\xff\n", r":2: not text"),
        ("time,lat,lon,alt_m\n0001-01-01T00:00:00+01:00,46.2,6.1,100\n", r":2: time .* is out of range"),
        ("time,lat,lon,alt_m\n" + "x" * 140_000 + "\n", r":2: not a CSV line"),
    ],
)
def test_canonical_csv_malformed_input_names_file_and_line(
    tmp_path: Path, content: str, message: str
) -> None:
    path = tmp_path / "bad.csv"
    path.write_bytes(content.encode("latin-1"))
    with pytest.raises(TrackError, match=re.escape(str(path)) + message):
        read_canonical_csv(path)


GPX = """<?xml version="1.0" encoding="UTF-8"?>
<gpx version="1.1" creator="test" xmlns="http://www.topografix.com/GPX/1/1">
  <trk><name>t</name><trkseg>
    <trkpt lat="46.5" lon="6.5"><ele>30000.5</ele><time>2024-05-01T12:00:00Z</time><sat>9</sat></trkpt>
    <trkpt lat="46.51" lon="6.52"><ele>29000</ele><time>2024-05-01T12:02:00Z</time></trkpt>
  </trkseg><trkseg>
    <trkpt lat="46.52" lon="6.54"><ele>28000</ele><time>2024-05-01T12:04:00.500Z</time></trkpt>
  </trkseg></trk>
</gpx>
"""


def test_gpx_reads_every_point_of_every_segment(tmp_path: Path) -> None:
    path = tmp_path / "t.gpx"
    path.write_text(GPX)
    track = read_track(path)
    assert track.format == "gpx"
    assert [(f.lat, f.lon, f.alt_m) for f in track.fixes] == [
        (46.5, 6.5, 30000.5),
        (46.51, 6.52, 29000.0),
        (46.52, 6.54, 28000.0),
    ]
    assert track.fixes[0].sats == 9 and track.fixes[1].sats is None
    assert track.fixes[2].time == datetime(2024, 5, 1, 12, 4, 0, 500000, tzinfo=UTC)
    assert [f.line for f in track.fixes] == [4, 5, 7]


@pytest.mark.parametrize(
    ("content", "message"),
    [
        (GPX.replace("<ele>29000</ele>", ""), r":5: trkpt has no ele"),
        (GPX.replace('lat="46.52" ', ""), r":7: trkpt has no lat"),
        (GPX.replace("2024-05-01T12:02:00Z", "yesterday"), r":5: time 'yesterday' is not ISO 8601"),
        (GPX.replace("</trkseg><trkseg>", "</trkseg><trk>"), r":\d+: not well-formed XML"),
        ('<?xml version="1.0"?><kml><Placemark/></kml>', r":1: not a GPX file"),
        ("", r":1: not well-formed XML"),
    ],
)
def test_gpx_malformed_input_names_file_and_line(tmp_path: Path, content: str, message: str) -> None:
    path = tmp_path / "bad.gpx"
    path.write_text(content)
    with pytest.raises(TrackError, match=re.escape(str(path)) + message):
        read_gpx(path)


def test_v4_logger_csv_reads_with_the_given_date(shared_data: Path) -> None:
    path = shared_data / "tracks/astra_meridiaz_V4_spain/V4_flight_1hz_DERIVED.csv"
    track = read_track(path, day=date(2021, 6, 1))
    assert track.format == "v4-1hz"
    assert len(track.fixes) == 6654
    first = track.fixes[0]
    assert first.time == datetime(2021, 6, 1, 8, 15, 38, tzinfo=UTC)
    assert (first.lat, first.lon, first.alt_m, first.sats) == (39.573517, -3.5172, 722.0, 6)
    assert max(f.alt_m for f in track.fixes) == pytest.approx(15352, abs=1)


def test_v4_logger_without_a_date_is_refused_with_the_fix(shared_data: Path) -> None:
    path = shared_data / "tracks/astra_meridiaz_V4_spain/V4_flight_1hz_DERIVED.csv"
    with pytest.raises(TrackError, match=r"no date; give the flight date \(--date YYYY-MM-DD\)"):
        read_track(path)


def test_v4_logger_crossing_midnight_moves_to_the_next_day(tmp_path: Path) -> None:
    path = tmp_path / "v4.csv"
    path.write_text(
        "record,time_hhmmss,lat_deg,lon_deg,alt_m,sats,gps_quality,T2_degC,RH_pct\n"
        "1,23:59:59,39.5,-3.5,700,6,1,20.0,40.0\n"
        "2,00:00:00,39.5,-3.5,705,6,1,20.0,40.0\n"
    )
    fixes = read_v4_csv(path, date(2021, 12, 31)).fixes
    assert fixes[1].time == datetime(2022, 1, 1, 0, 0, 0, tzinfo=UTC)


def test_unknown_format_says_which_formats_exist(tmp_path: Path) -> None:
    path = tmp_path / "x.csv"
    path.write_text("hello,world\n")
    with pytest.raises(TrackError, match=r"x\.csv:1: unknown track format \(expected a canonical CSV"):
        read_track(path)


def test_missing_file_is_a_track_error(tmp_path: Path) -> None:
    with pytest.raises(TrackError, match=r"cannot read"):
        read_track(tmp_path / "absent.csv")


@settings(max_examples=150, deadline=None, suppress_health_check=[HealthCheck.too_slow])
@given(
    data=st.one_of(
        st.binary(max_size=400),
        st.text(alphabet="0123456789,./:-TZRB \n\txyz", max_size=400).map(str.encode),
        st.text(max_size=200).map(lambda t: ("time,lat,lon,alt_m\n" + t).encode()),
        st.text(max_size=200).map(lambda t: ('<gpx><trk><trkseg><trkpt lat="1" lon="2">' + t).encode()),
    ),
    suffix=st.sampled_from([".csv", ".gpx", ".txt"]),
)
def test_garbage_never_crashes_a_reader(data: bytes, suffix: str) -> None:
    """Any bytes give a Track or a one-line PredictorError, never another exception."""
    with tempfile.TemporaryDirectory() as folder:
        path = Path(folder) / f"garbage{suffix}"
        path.write_bytes(data)
        try:
            track = read_track(path, day=date(2024, 1, 1))
        except PredictorError as exc:
            assert "\n" not in str(exc)
        else:
            assert track.fixes

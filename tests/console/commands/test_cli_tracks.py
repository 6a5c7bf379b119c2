"""`drs tracks summary` on real flights, in text and JSON; a bad file is one error line, not a stop."""

from __future__ import annotations

import argparse
import json
import re
from pathlib import Path

import pytest

from console.commands import tracks as cli
from console.commands.main import main
from predictor.tracks.reading import TrackError


def run(argv: list[str]) -> int:
    parser = argparse.ArgumentParser(prog="drs")
    cli.register(parser.add_subparsers(dest="command", required=True))
    args = parser.parse_args(argv)
    return args.func(args)


def flight_file(shared_data: Path, name: str) -> str:
    return str(shared_data / "tracks" / "pyballoon_superbit" / f"{name}.csv")


def test_text_summary_shows_rules_key_fixes_descent_and_flags(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert (
        run(["tracks", "summary", flight_file(shared_data, "18-8-13"), flight_file(shared_data, "19-2-9")])
        == 0
    )
    out = capsys.readouterr().out
    assert "fixes: 64 read, 26 kept, 38 dropped" in out
    assert "- 1 invalid-date: date before 2000" in out and "(lines 31)" in out
    assert "- 30 after-landing:" in out and "(lines 35-64)" in out
    assert "descent start 2018-08-13 17:00:46Z" in out
    assert "landing       2018-08-13 17:43:05Z" in out
    assert "descent       42.3 min, 7 fixes, drift 15.15 km" in out
    assert (
        "flag: floater: floated 42 min after the 16829 m peak, falling slower than 3 m/s down to 14905 m"
        in out
    )
    assert out.count("usable for calibration") == 2


def test_json_summary_has_every_field_for_every_flight(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert run(["tracks", "summary", "--json", flight_file(shared_data, "19-3-11")]) == 0
    (flight,) = json.loads(capsys.readouterr().out)
    assert flight["name"] == "19-3-11"
    assert flight["fixes_read"] == flight["fixes_kept"] + flight["fixes_dropped"] == 95
    assert flight["dropped"][0]["rule"] == "other-session" and flight["dropped"][0]["lines"] == [
        1,
        2,
        3,
        4,
        5,
        6,
    ]
    assert flight["launch"]["time"].startswith("2019-03-11T")
    assert flight["descent_start"] == {
        "time": "2019-03-11T17:52:19Z",
        "lat": 45.110283,
        "lon": 7.309138,
        "alt_m": 27358.0,
        "line": 72,
    }
    assert flight["landing"]["alt_m"] == 411.0
    assert flight["descent_time_s"] == 48 * 60
    assert flight["flags"][0]["code"] == "landing-at-last-fix"
    assert flight["usable"] is True and flight["exclusions"] == []


def test_a_bad_file_is_one_error_line_and_the_good_files_are_still_summarised(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.csv"
    bad.write_text("time,lat,lon,alt_m\n2024-05-01T12:00:00Z,46.2,north,100\n")
    assert run(["tracks", "summary", str(bad), flight_file(shared_data, "18-3-4")]) == 1
    captured = capsys.readouterr()
    assert captured.err == f"drs: error: {bad}:2: lon 'north' is not a number\n"
    assert captured.out.startswith("18-3-4  (")


def test_the_v4_file_needs_and_takes_a_date(shared_data: Path, capsys: pytest.CaptureFixture[str]) -> None:
    v4 = str(shared_data / "tracks/astra_meridiaz_V4_spain/V4_flight_1hz_DERIVED.csv")
    assert run(["tracks", "summary", v4]) == 1
    assert "give the flight date (--date YYYY-MM-DD)" in capsys.readouterr().err
    assert run(["tracks", "summary", "--date", "2021-06-01", v4]) == 0
    out = capsys.readouterr().out
    assert "peak          2021-06-01 09:10:18Z" in out
    assert "EXCLUDED: no landing observed" in out


def test_bench_reports_each_stage_and_refuses_zero_runs(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    files = [flight_file(shared_data, "18-3-4"), flight_file(shared_data, "19-2-9")]
    assert run(["tracks", "bench", "--repeat", "2", *files]) == 0
    out = capsys.readouterr().out
    assert out.startswith("2 files, 126 fixes, best of 2:")
    for stage in ("read", "clean", "ascent cube"):
        assert re.search(rf"^  {stage} +\d+\.\d ms$", out, re.MULTILINE)
    with pytest.raises(TrackError, match="--repeat must be at least 1, got 0"):
        run(["tracks", "bench", "--repeat", "0", *files])


def test_the_drs_entry_point_runs_tracks_summary_and_reports_bad_input_in_one_line(
    shared_data: Path, tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["tracks", "summary", "--json", flight_file(shared_data, "19-2-9")]) == 0
    assert json.loads(capsys.readouterr().out)[0]["flags"][0]["code"] == "floater"
    empty = tmp_path / "empty.gpx"
    empty.write_text("")
    assert main(["tracks", "summary", str(empty)]) == 1
    captured = capsys.readouterr()
    assert captured.out == ""
    assert captured.err.count("\n") == 1 and captured.err.startswith(
        f"drs: error: {empty}:1: not well-formed XML"
    )


def test_the_command_lines_default_effect_count_is_the_selections() -> None:
    """The parser states the default without importing the selection (numba, scipy): the two must agree."""
    from console.commands import calibrate as calibrate_cli
    from predictor.calibration import selection

    assert calibrate_cli.DEFAULT_MAX_EFFECTS == selection.DEFAULT_MAX_EFFECTS

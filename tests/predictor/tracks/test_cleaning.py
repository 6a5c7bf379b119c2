"""Cleaning rules: each rule on a small constructed track, and all of them on the 30 real flights."""

from __future__ import annotations

import re
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st

from predictor.environment.terrain import Terrain, tile_name
from predictor.tracks.cleaning import TERRAIN_LANDING_TOLERANCE_M, Flight, clean, distance_m
from predictor.tracks.reading import Fix, Track, read_track

FLIGHT_FILE = re.compile(r"^\d+-\d+-\d+(_\d)?\.csv$")
T0 = datetime(2024, 5, 1, 8, 0, 0, tzinfo=UTC)


def fix(
    seconds: float,
    alt: float,
    *,
    lat: float = 46.0,
    lon: float = 6.0,
    line: int = 0,
    speed: float | None = None,
) -> Fix:
    return Fix(time=T0 + timedelta(seconds=seconds), lat=lat, lon=lon, alt_m=alt, speed_ms=speed, line=line)


def track(fixes: list[Fix], name: str = "synthetic") -> Track:
    numbered = [Fix(**{**_fields(f), "line": i + 1}) for i, f in enumerate(fixes)]
    return Track(name=name, source=f"{name}.csv", format="test", fixes=tuple(numbered))


def _fields(f: Fix) -> dict[str, object]:
    return {k: getattr(f, k) for k in Fix.__slots__}


def simple_flight() -> list[Fix]:
    """Ground, a 5 m/s ascent to 30 km, a descent at 20 then 5 m/s, landing at 300 m, ground again."""
    fixes = [fix(i * 180.0, 400.0 + (i % 2) * 20) for i in range(5)]
    t, alt, lon = 5 * 180.0, 400.0, 6.0
    while alt < 30_000:
        alt = min(30_000.0, alt + 900.0)
        lon += 0.02
        fixes.append(fix(t, alt, lon=lon))
        t += 180.0
    for rate in [20.0] * 4 + [5.0] * 40:
        alt -= rate * 180.0
        lon += 0.01
        if alt <= 300.0:
            break
        fixes.append(fix(t, alt, lon=lon))
        t += 180.0
    fixes += [fix(t + i * 180.0, 300.0 + (i % 3) * 10, lon=lon) for i in range(6)]
    return fixes


def test_clean_constructed_flight_finds_launch_peak_descent_start_and_landing() -> None:
    flight = clean(track(simple_flight()))
    assert flight.usable, flight.exclusions
    assert flight.launch is not None and flight.launch.alt_m == 400.0 and flight.launch.line == 5
    assert flight.peak is not None and flight.peak.alt_m == 30_000.0
    assert flight.descent_start is not None and flight.descent_start.line == flight.peak.line + 1
    assert flight.landing is not None and flight.landing.alt_m == 300.0
    assert [r.rule for r in flight.removals] == ["before-launch", "after-landing"]
    assert flight.removals[0].lines == (1, 2, 3, 4)
    assert flight.ascent[0] is flight.launch and flight.ascent[-1] is flight.peak
    assert flight.descent[0] is flight.descent_start and flight.descent[-1] is flight.landing


def test_invalid_date_and_zero_position_rows_are_removed_and_reported() -> None:
    fixes = simple_flight()
    fixes.insert(40, Fix(time=datetime(1970, 1, 1, tzinfo=UTC), lat=0.0, lon=0.0, alt_m=0.0))
    fixes.insert(20, fix(fixes[19].time.timestamp() - T0.timestamp() + 60, 8000.0, lat=0.0, lon=0.0))
    flight = clean(track(fixes))
    rules = {r.rule: r.lines for r in flight.removals}
    assert rules["invalid-date"] == (42,)
    assert rules["zero-position"] == (21,)
    assert all(f.lat != 0 for f in flight.fixes)


def test_out_of_range_positions_and_altitudes_are_removed() -> None:
    fixes = simple_flight()
    fixes[20] = fix(fixes[20].time.timestamp() - T0.timestamp(), 80_000.0)
    fixes[21] = Fix(time=fixes[21].time, lat=95.0, lon=6.0, alt_m=fixes[21].alt_m)
    flight = clean(track(fixes))
    rules = {r.rule: r.lines for r in flight.removals}
    assert rules["altitude-out-of-range"] == (21,)
    assert rules["position-out-of-range"] == (22,)


def test_duplicate_times_keep_the_first_and_out_of_order_rows_are_resorted() -> None:
    fixes = simple_flight()
    fixes.insert(15, fixes[14])
    fixes[30], fixes[31] = fixes[31], fixes[30]
    flight = clean(track(fixes))
    assert {r.rule: r.lines for r in flight.removals}["duplicate-time"] == (16,)
    assert flight.notes == ("2 fixes were out of time order and were re-sorted by their GNSS time",)
    times = [f.time for f in flight.fixes]
    assert times == sorted(times)


def test_a_spike_impossible_to_both_neighbours_is_removed_but_its_neighbours_stay() -> None:
    fixes = simple_flight()
    spike = fixes[25]
    fixes[25] = Fix(time=spike.time, lat=spike.lat + 1.0, lon=spike.lon, alt_m=spike.alt_m)
    flight = clean(track(fixes))
    assert {r.rule: r.lines for r in flight.removals}["impossible-jump"] == (26,)
    assert fixes[24].time in {f.time for f in flight.fixes} and fixes[26].time in {
        f.time for f in flight.fixes
    }


def test_a_ground_test_days_earlier_is_another_session_and_the_flight_is_kept() -> None:
    ground_test = [fix(-2 * 86400.0 + i * 120.0, 420.0 + i) for i in range(6)]
    flight = clean(track(ground_test + simple_flight()))
    other = [r for r in flight.removals if r.rule == "other-session"]
    assert len(other) == 1 and other[0].lines == (1, 2, 3, 4, 5, 6)
    assert flight.launch is not None and flight.launch.time.date() == T0.date()


def test_rows_after_landing_are_dropped_including_the_drive_home() -> None:
    fixes = simple_flight()
    t = fixes[-1].time.timestamp() - T0.timestamp()
    fixes += [fix(t + 600.0 * (i + 1), 300.0 + 50 * i, lon=fixes[-1].lon + 0.1 * (i + 1)) for i in range(10)]
    flight = clean(track(fixes))
    after = next(r for r in flight.removals if r.rule == "after-landing")
    assert after.count == 5 + 10
    assert flight.landing is not None and distance_m(flight.landing, fixes[-1]) > 50_000
    assert "up to 7" in after.reason


def test_a_slow_fall_after_the_peak_is_a_floater_and_the_descent_starts_after_it() -> None:
    fixes = [f for f in simple_flight() if f.alt_m < 16_500 or f.time < T0 + timedelta(hours=1)]
    fixes = [f for f in fixes if f.time < T0 + timedelta(seconds=5 * 180 + 19 * 180)]
    t = fixes[-1].time.timestamp() - T0.timestamp()
    alt = fixes[-1].alt_m
    for _ in range(12):  # 36 min at -1 m/s
        t += 180.0
        alt -= 180.0
        fixes.append(fix(t, alt))
    float_end = alt
    for _ in range(40):
        t += 180.0
        alt -= 1500.0
        if alt < 300:
            break
        fixes.append(fix(t, alt))
    fixes += [fix(t + i * 180.0, 300.0) for i in range(4)]
    flight = clean(track(fixes))
    assert flight.has_flag("floater")
    assert flight.descent_start is not None and flight.descent_start.alt_m == float_end - 1500.0


def test_a_descent_only_track_starts_its_descent_at_its_first_fix() -> None:
    fixes = [fix(i * 120.0, 25_000.0 - 600.0 * i) for i in range(40)] + [
        fix(40 * 120.0 + i * 120, 700) for i in range(3)
    ]
    flight = clean(track(fixes))
    assert flight.launch is None and flight.ascent == ()
    assert flight.descent_start is flight.fixes[0] and flight.has_flag("descent-only")
    assert flight.usable


def test_a_track_without_a_flight_is_excluded_with_the_reason() -> None:
    flight = clean(track([fix(i * 120.0, 400.0 + i) for i in range(10)]))
    assert not flight.usable
    assert flight.exclusions[0].startswith("no flight: no part of the track spans 1000 m")


def test_a_track_ending_at_its_peak_has_no_descent() -> None:
    flight = clean(track([fix(i * 180.0, 400.0 + 900.0 * max(0, i - 3)) for i in range(20)]))
    assert flight.exclusions == ("no descent recorded: the track ends at its highest point",)


def test_a_track_ending_mid_descent_is_excluded_unless_the_receiver_says_it_stopped() -> None:
    fixes = [f for f in simple_flight() if f.alt_m > 5000 or f.time < T0 + timedelta(hours=1)]
    assert (
        clean(track(fixes)).exclusions[0].startswith("no landing observed: the track ends during the descent")
    )
    last = fixes[-1]
    fixes[-1] = Fix(time=last.time, lat=last.lat, lon=last.lon, alt_m=last.alt_m, speed_ms=0.1)
    stopped = clean(track(fixes))
    assert stopped.landing is not None and stopped.landing.alt_m == last.alt_m
    assert stopped.has_flag("landing-at-last-fix")


def _flat_dem(directory: Path, height_m: int) -> Terrain:
    """One SRTM3 tile (big-endian int16) at ``height_m`` over 46–47° N, 6–7° E, where simple_flight flies."""
    np.full((1201, 1201), height_m, dtype=">i2").tofile(directory / f"{tile_name(46, 6)}.hgt")
    return Terrain.from_dir(directory)


def _cut_at_touchdown() -> list[Fix]:
    """simple_flight as a logger that stops at touchdown writes it: up to the first fix on the ground."""
    fixes = simple_flight()
    peak = max(range(len(fixes)), key=lambda i: fixes[i].alt_m)
    first_ground = next(i for i in range(peak, len(fixes)) if fixes[i].alt_m <= 310.0)
    return fixes[: first_ground + 1]


def test_with_a_dem_a_track_ending_at_the_terrain_height_ends_in_a_flagged_landing(tmp_path: Path) -> None:
    fixes = _cut_at_touchdown()
    without = clean(track(fixes))
    assert without.exclusions[0].startswith("no landing observed")
    flight = clean(track(fixes), _flat_dem(tmp_path, 300 - 40))  # 40 m under the last fix: within 50 m
    assert flight.usable and flight.landing is not None
    assert flight.landing.time == fixes[-1].time and flight.landing.alt_m == fixes[-1].alt_m
    assert flight.has_flag("landing-at-terrain") and not flight.has_flag("landing-at-last-fix")
    flag = next(f for f in flight.flags if f.code == "landing-at-terrain")
    assert "+40 m from the terrain height 260 m (tolerance 50 m)" in flag.message


def test_with_a_dem_a_track_cut_off_above_the_tolerance_is_still_no_landing(tmp_path: Path) -> None:
    fixes = _cut_at_touchdown()
    terrain = _flat_dem(tmp_path, 300 - TERRAIN_LANDING_TOLERANCE_M - 10)
    assert clean(track(fixes), terrain).exclusions[0].startswith("no landing observed")
    in_the_air = [f for f in fixes if f.alt_m > 2000 or f.time < T0 + timedelta(hours=1)]
    assert clean(track(in_the_air), terrain).exclusions[0].startswith("no landing observed")


def test_where_no_dem_covers_the_last_fix_sea_level_is_not_taken_for_the_ground(tmp_path: Path) -> None:
    """A DEM of another place answers 0 m (sea level) here: a track ending at 0 m is still no landing."""
    fixes = [Fix(**{**_fields(f), "alt_m": f.alt_m - 300.0}) for f in _cut_at_touchdown()]
    np.full((1201, 1201), 0, dtype=">i2").tofile(tmp_path / f"{tile_name(10, 10)}.hgt")
    assert clean(track(fixes), Terrain.from_dir(tmp_path)).exclusions[0].startswith("no landing observed")


@settings(max_examples=120, deadline=None)
@given(
    st.lists(
        st.tuples(
            st.floats(-1e6, 1e6),
            st.floats(-100, 100),
            st.floats(-400, 400),
            st.floats(-2000, 70_000),
            st.none() | st.floats(0, 50),
        ),
        min_size=1,
        max_size=60,
    )
)
def test_cleaning_any_track_gives_a_flight_and_accounts_for_every_fix(rows: list[tuple]) -> None:
    fixes = [fix(t, alt, lat=lat, lon=lon, speed=speed) for t, lat, lon, alt, speed in rows]
    flight = clean(track(fixes))
    assert isinstance(flight, Flight)
    assert len(flight.fixes) + flight.n_dropped == len(fixes)


# ---- the 30 real flights ------------------------------------------------------------------------


def real_flights(shared_data: Path) -> dict[str, Flight]:
    folder = shared_data / "tracks" / "pyballoon_superbit"
    return {p.stem: clean(read_track(p)) for p in sorted(folder.iterdir()) if FLIGHT_FILE.match(p.name)}


@pytest.fixture(scope="module")
def flights(shared_data: Path) -> dict[str, Flight]:
    return real_flights(shared_data)


def test_all_thirty_real_flights_are_usable_and_every_row_is_accounted_for(
    flights: dict[str, Flight],
) -> None:
    assert len(flights) == 30
    for name, flight in flights.items():
        assert flight.usable, (name, flight.exclusions)
        assert len(flight.fixes) + flight.n_dropped == flight.n_read, name
        times = [f.time for f in flight.fixes]
        assert times == sorted(times), name
        assert flight.descent_start is not None and flight.peak is not None and flight.landing is not None
        assert flight.descent_start.time > flight.peak.time, name
        assert flight.landing.time >= flight.descent_start.time, name


def test_real_landings_are_the_first_steady_fix_after_a_fall(
    flights: dict[str, Flight], shared_data: Path
) -> None:
    for name, flight in flights.items():
        raw = read_track(shared_data / "tracks/pyballoon_superbit" / f"{name}.csv").fixes
        i = next(k for k, f in enumerate(raw) if f.line == flight.landing.line)
        assert raw[i - 1].alt_m - raw[i].alt_m > 50, name
        if i + 1 < len(raw):
            assert abs(raw[i + 1].alt_m - raw[i].alt_m) < 50, name


def test_18_8_13_loses_its_1970_row_and_nothing_else_inside_the_flight(flights: dict[str, Flight]) -> None:
    flight = flights["18-8-13"]
    invalid = [r for r in flight.removals if r.rule == "invalid-date"]
    assert len(invalid) == 1 and invalid[0].lines == (31,)
    assert {r.rule for r in flight.removals} == {"invalid-date", "before-launch", "after-landing"}
    assert all(f.time.year == 2018 for f in flight.fixes)


@pytest.mark.parametrize(
    ("name", "day", "dropped_day"),
    [("19-3-11", "2019-03-11", "2019-03-09"), ("19-4-21", "2019-04-21", "2019-04-20")],
)
def test_multi_day_files_keep_the_flight_day(
    flights: dict[str, Flight], name: str, day: str, dropped_day: str
) -> None:
    flight = flights[name]
    assert {f.time.date().isoformat() for f in flight.fixes} == {day}
    other = [r for r in flight.removals if r.rule == "other-session"]
    assert other and other[0].reason.startswith(dropped_day)
    assert flight.peak is not None and flight.peak.alt_m > 29_000


@pytest.mark.parametrize("name", ["18-8-3", "18-8-11", "18-8-6", "19-4-21", "19-4-22", "19-4-24"])
def test_landing_is_not_where_the_car_went(flights: dict[str, Flight], shared_data: Path, name: str) -> None:
    flight = flights[name]
    last_row = read_track(shared_data / "tracks/pyballoon_superbit" / f"{name}.csv").fixes[-1]
    assert flight.landing is not None
    assert distance_m(flight.landing, last_row) > 10_000
    assert flight.fixes[-1] is flight.landing
    assert any(r.rule in ("after-landing", "other-session") for r in flight.removals)


def test_19_2_9_is_flagged_as_a_floater_with_the_descent_after_the_float(flights: dict[str, Flight]) -> None:
    flight = flights["19-2-9"]
    assert flight.has_flag("floater")
    assert flight.peak is not None and flight.peak.alt_m == 16829
    assert flight.descent_start is not None and flight.descent_start.alt_m == 14030
    assert [n for n, f in flights.items() if f.has_flag("floater")] == ["19-2-9"]


def test_18_8_11_is_flagged_for_its_data_gap(flights: dict[str, Flight]) -> None:
    flight = flights["18-8-11"]
    assert flight.descent_start is not None and flight.descent_start.alt_m == 8765
    gaps = [f.message for f in flight.flags if f.code == "data-gap"]
    assert gaps[0].startswith("no fix for 27 min between 31661 m")
    assert sorted(n for n, f in flights.items() if f.has_flag("data-gap")) == [
        "18-6-16",
        "18-8-11",
        "18-8-13",
        "18-8-3",
    ]


def test_descent_starts_reproduce_the_papers_descent_only_start1(
    flights: dict[str, Flight], shared_data: Path
) -> None:
    """All 18 of the author's starts, including the 19-2-9 floater exception, to the fix."""
    lines = (shared_data / "tracks/pyballoon_superbit/descent_only_start1.txt").read_text().split("\n")
    paper = [line.split() for line in lines if line.strip()]
    assert len(paper) == 18
    starts = [f.descent_start for f in flights.values() if f.descent_start is not None]
    for day, hour, lat, lon, alt in paper:
        same_day = [s for s in starts if s.time.strftime("%Y%m%d") == day]
        match = min(same_day, key=lambda s: abs(s.time.hour + s.time.minute / 60 - float(hour)))
        assert abs(match.time.hour + match.time.minute / 60 + match.time.second / 3600 - float(hour)) < 0.06
        assert (match.lat, match.lon, match.alt_m) == pytest.approx(
            (float(lat), float(lon), float(alt)), abs=1e-6
        )


def test_the_v4_one_hertz_flight_cleans_without_gnss_noise_faking_a_landing(shared_data: Path) -> None:
    flight = clean(
        read_track(
            shared_data / "tracks/astra_meridiaz_V4_spain/V4_flight_1hz_DERIVED.csv",
            day=datetime(2021, 6, 1).date(),
        )
    )
    assert flight.peak is not None and flight.peak.alt_m == 15352
    assert flight.descent_start is not None and flight.descent_start.line == flight.peak.line + 1
    assert flight.landing is None
    assert flight.exclusions == (
        "no landing observed: the track ends during the descent at 867 m (10:06:31)",
    )
    assert len(flight.ascent) > 3000


def test_descent_starts_and_landings_agree_with_the_derived_summary_on_all_30(
    flights: dict[str, Flight], shared_data: Path
) -> None:
    """The summary's heuristic (landing = first fall under 50 m to the next fix) differs from ours in
    form; on these 30 files both give the same fixes, which pins our rules against a second reading."""
    summary = (shared_data / "tracks/pyballoon_superbit/flights_summary_derived.csv").read_text().splitlines()
    header = summary[0].split(",")
    for line in summary[1:]:
        row = dict(zip(header, line.split(","), strict=True))
        flight = flights[row["file"].removesuffix(".csv")]
        assert flight.descent_start is not None and flight.landing is not None
        assert f"{flight.descent_start.time:%Y-%m-%d %H:%M:%S}" == row["desc_start_utc"], row["file"]
        assert f"{flight.landing.time:%Y-%m-%d %H:%M:%S}" == row["land_utc"], row["file"]
        assert flight.landing.alt_m == float(row["land_alt_m"])

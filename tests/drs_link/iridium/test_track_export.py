"""Stored reports out as the canonical track CSV, read back by the calibration's own reader and cleaner."""

from __future__ import annotations

from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path

import pytest

from drs_link.errors import LinkError
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.iridium.track_export import export_track
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedDescent, SimulatedRockblock
from drs_link.store import Store
from predictor.tracks.cleaning import Flight, clean
from predictor.tracks.reading import read_track

from .flight_logs import flight_reports
from .helpers import IMEI, T0, to_delivery

NO_FIX_CYCLES = (5, 6)


@pytest.fixture
def reports(tmp_path: Path) -> Iterator[ReportStore]:
    store = Store.open(tmp_path / "drs.sqlite")
    yield ReportStore(store)
    store.close()


def record_descent(reports: ReportStore) -> SimulatedDescent:
    """A fall from 30 km reported every 2 min until 20 min after landing, two cycles without a fix."""
    descent = SimulatedDescent(T0, 45.4, 8.4)
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    with SimulatedRockblock(username="ops", password="pw") as gateway:
        moment, cycle = T0, 0
        while moment < descent.landing_time + timedelta(minutes=20):
            fix = None if cycle in NO_FIX_CYCLES else descent.fix(moment)
            reports.add(to_delivery(capsule.session(gateway, fix, moment + timedelta(seconds=40))))
            moment, cycle = moment + timedelta(minutes=2), cycle + 1
    reports.add(Delivery(IMEI, 999, b"not a report".hex(), "test", T0 + timedelta(minutes=3)))
    return descent


def test_stored_descent_round_trips_through_the_calibration_reader_and_cleaner(
    reports: ReportStore, tmp_path: Path
) -> None:
    descent = record_descent(reports)
    stored = reports.for_imei(IMEI)
    out = tmp_path / "drs1.csv"
    result = export_track(stored, out, "DRS1")
    expected = [r.report.fix for r in stored if r.report is not None and r.report.fix is not None]
    assert (result.fixes, result.without_fix, result.rejected) == (len(expected), len(NO_FIX_CYCLES), 1)

    track = read_track(out)
    assert track.format == "canonical-csv"
    assert [(f.time, f.lat, f.lon, f.alt_m) for f in track.fixes] == [
        (f.time, f.lat, f.lon, float(f.alt_m)) for f in expected
    ]
    assert all(f.pressure_pa is None for f in track.fixes)

    flight = clean(track)
    assert flight.usable, flight.exclusions
    assert flight.has_flag("descent-only")
    assert flight.descent_start is not None and flight.descent_start.time == T0
    assert flight.landing is not None
    assert timedelta(0) <= flight.landing.time - descent.landing_time <= timedelta(minutes=2)
    [after_landing] = [r for r in flight.removals if r.rule == "after-landing"]
    assert after_landing.count == len([f for f in expected if f.time > flight.landing.time])


def test_only_a_measured_pressure_is_exported(reports: ReportStore, tmp_path: Path) -> None:
    rows = (
        "20260701100007,45.400000,8.400000,30000,3.0,90,1.0,9,1267,-40.0,8.90,1",
        "20260701100207,45.401000,8.410000,27000,3.0,90,1.0,9,0,-40.0,8.90,2",
    )
    for momsn, row in enumerate(rows):
        reports.add(Delivery(IMEI, momsn, row.encode("ascii").hex(), "test", T0 + timedelta(minutes=momsn)))
    out = tmp_path / "track.csv"
    export_track(reports.for_imei(IMEI), out, "DRS1")
    assert [f.pressure_pa for f in read_track(out).fixes] == [1267.0, None]


def test_no_fix_at_all_is_an_error_and_writes_nothing(reports: ReportStore, tmp_path: Path) -> None:
    capsule = SimulatedCapsule(imei=IMEI, rb_source=11800)
    with SimulatedRockblock(username="ops", password="pw") as gateway:
        reports.add(to_delivery(capsule.session(gateway, None, T0)))
    out = tmp_path / "track.csv"
    with pytest.raises(LinkError, match=r"no position fix stored for DRS1 \(1 report\(s\): 1 without a fix"):
        export_track(reports.for_imei(IMEI), out, "DRS1")
    assert not out.exists()


def test_an_existing_file_is_kept_unless_forced(reports: ReportStore, tmp_path: Path) -> None:
    record_descent(reports)
    out = tmp_path / "track.csv"
    out.write_text("someone's track\n")
    with pytest.raises(LinkError, match="the file exists; choose another name or add --force"):
        export_track(reports.for_imei(IMEI), out, "DRS1")
    assert out.read_text() == "someone's track\n"
    export_track(reports.for_imei(IMEI), out, "DRS1", overwrite=True)
    assert read_track(out).fixes and list(tmp_path.glob(".*.part")) == []


def test_a_missing_directory_is_a_clear_error(reports: ReportStore, tmp_path: Path) -> None:
    record_descent(reports)
    with pytest.raises(LinkError, match="the directory .*nowhere does not exist"):
        export_track(reports.for_imei(IMEI), tmp_path / "nowhere" / "track.csv", "DRS1")


@pytest.mark.parametrize("flight", ["19-1-1.csv", "18-8-3.csv", "18-8-13.csv", "18-6-16.csv", "19-3-11.csv"])
def test_a_real_flight_received_and_exported_cleans_like_its_gateway_log(
    reports: ReportStore, tmp_path: Path, shared_data: Path, flight: str
) -> None:
    """Normal, flown home after landing, and one with a no-fix row: same launch, peak, descent, landing."""
    log = shared_data / "tracks" / "pyballoon_superbit" / flight
    for stored in flight_reports(log):
        reports.add(stored.delivery)
    out = tmp_path / flight
    export_track(reports.for_imei(IMEI), out, flight)
    original, exported = clean(read_track(log)), clean(read_track(out))

    def key_fixes(flight: Flight) -> list[tuple[datetime, float, float, float] | None]:
        points = (flight.launch, flight.peak, flight.descent_start, flight.landing)
        return [None if p is None else (p.time, p.lat, p.lon, p.alt_m) for p in points]

    assert exported.usable and original.usable
    assert key_fixes(exported) == key_fixes(original)
    assert [(f.time, f.alt_m) for f in exported.descent] == [(f.time, f.alt_m) for f in original.descent]


def test_out_dash_writes_the_csv_to_stdout_and_the_summary_to_stderr(
    reports: ReportStore, tmp_path: Path
) -> None:
    """#24 item 12: `drs mo export --out -` wrote a file named `-`."""
    import os
    import subprocess
    import sys

    record_descent(reports)
    config = tmp_path / "drs.toml"
    config.write_text(
        f'[data]\ndir = "{tmp_path}"\n[[capsule]]\nname = "DRS1"\nhost = "x"\nimei = "{IMEI}"\n'
    )
    repo = Path(__file__).resolve().parents[3]
    done = subprocess.run(
        [sys.executable, "-m", "console.commands.main", "--config", str(config), "mo", "export", "DRS1", "--out", "-"],
        cwd=tmp_path, capture_output=True, text=True, timeout=60, env={**os.environ, "PYTHONPATH": str(repo)},
    )  # fmt: skip
    assert done.returncode == 0, done.stderr
    assert not (tmp_path / "-").exists()
    assert done.stdout.startswith("time,lat,lon,alt_m") and "fixes of DRS1" in done.stderr
    (tmp_path / "piped.csv").write_text(done.stdout)
    assert len(read_track(tmp_path / "piped.csv").fixes) == done.stdout.count("\n") - 1

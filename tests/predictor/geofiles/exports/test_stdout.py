"""``-`` as an output file means standard output, and the human summary then moves to standard error."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from pathlib import Path

import gpxpy
import pytest
from lxml import etree

from console.commands.main import main
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.store import Store
from predictor.environment.demo_weather import demo_weather_files
from predictor.errors import UsageError
from predictor.geofiles import geojson
from predictor.geofiles.output import piped
from tests.drs_link.iridium.helpers import IMEI, T0, fix_at

WANAKA = ["predict", "--demo-weather", "--lat", "-44.7", "--lon", "179.64", "--alt", "28000",
          "--time", "2026-01-10T03:00Z"]  # fmt: skip


def test_predict_geojson_dash_prints_the_collection_and_moves_the_summary_to_stderr(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)
    assert main([*WANAKA, "--geojson", "-", "--gpx", str(tmp_path / "w.gpx")]) == 0
    out, err = capsys.readouterr()
    document = json.loads(out)
    assert document["type"] == "FeatureCollection"
    assert all(f["properties"]["is_demo"] for f in document["features"])
    assert "*** DEMO WEATHER" in err and "landing" in err
    assert not (tmp_path / "-").exists()
    names = [w.name for w in gpxpy.parse((tmp_path / "w.gpx").read_text(encoding="utf-8")).waypoints]
    assert names == ["DEMO PRED LAND", "DEMO RELEASE"]


def test_two_outputs_cannot_both_claim_standard_output() -> None:
    with pytest.raises(UsageError, match="--kml and --gpx all ask for standard output"):
        piped(kml="-", geojson="out.geojson", gpx="-", json=False)
    with pytest.raises(UsageError, match="--geojson and --json"):
        piped(kml=None, geojson="-", json=True)
    assert piped(kml=Path("-"), json=False) and not piped(kml="a.kml", json=True)


def test_predict_refuses_two_dashes_before_computing_anything(capsys: pytest.CaptureFixture[str]) -> None:
    assert main([*WANAKA, "--kml", "-", "--gpx", "-"]) == 2  # a usage error, as argparse's own
    assert "only one output can be '-'" in capsys.readouterr().err


def test_recovery_gpx_dash_prints_the_gpx_with_the_demo_predicted_landing_of_a_path_cut_at_180(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    config = tmp_path / "drs.toml"
    config.write_text(
        f'[operator]\nname = "alice"\n[data]\ndir = "{tmp_path / "data"}"\n'
        f'[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nimei = "{IMEI}"\nrockblock_serial = 11800\n'
    )
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    for i in range(3):
        moment = T0 + timedelta(minutes=2 * i)
        fix = fix_at(moment, lat=-44.7, lon=179.9, alt=9000 - 3000 * i)
        reports.add(Delivery(IMEI, i, format_mo(fix, 8.9, i).hex(), "t", moment))
    predicted = tmp_path / "prediction.geojson"
    path = geojson.line([(179.9, -44.7, 9000.0), (-179.9, -44.6, 600.0)])
    assert path["type"] == "MultiLineString"
    about = geojson.Provenance("DRS landing prediction (DEMO WEATHER, NOT A FORECAST)", "demo", is_demo=True)
    predicted.write_text(geojson.dumps(geojson.collection([geojson.feature(path, "path", about)], about)))
    argv = ["--config", str(config), "recovery", "DRS1", "--predicted", str(predicted), "--gpx", "-"]
    assert main(argv) == 0
    out, err = capsys.readouterr()
    gpx = gpxpy.parse(out)
    [landing] = [w for w in gpx.waypoints if w.name == "DEMO PRED LAND"]  # the prediction was demo
    assert (landing.latitude, landing.longitude) == (-44.6, -179.9)
    assert "DEMO WEATHER" in landing.description and "DEMO WEATHER" in gpx.tracks[-1].name
    assert err.startswith("DRS1 not landed: last fix 44.70000 S 179.90000 E")


def test_calibrate_json_dash_prints_only_the_results_document(
    shared_data: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    folder = shared_data / "tracks" / "pyballoon_superbit"
    tracks = [str(folder / f"{name}.csv") for name in ("18-5-19", "18-6-30", "19-2-2")]
    argv = ["calibrate", "--tracks", *tracks, "--winds", "ascent", "--payload", "superbit-test",
            "--effects", "descent_rate_scale", "--json", "-"]  # fmt: skip
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert json.loads(out)["flights"] == ["18-5-19", "18-6-30", "19-2-2"]
    assert err.startswith("3 flights used, 0 excluded")


def test_plan_kml_dash_prints_the_kml_and_moves_the_summary_to_stderr(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch, capsys: pytest.CaptureFixture[str]
) -> None:
    monkeypatch.chdir(tmp_path)  # were '-' taken as a file name, it would land here
    start = datetime(2026, 1, 10, 3, tzinfo=UTC)
    files = demo_weather_files(-44.7, 179.64, start, tmp_path / "grib", hours=6, half_width_deg=4.0)
    argv = ["plan", "--weather", *map(str, files), "--cache-dir", str(tmp_path / "cache"), "--lat", "-44.7",
            "--lon", "179.64", "--alt", "28000", "--from", "2026-01-10T03:00Z", "--hours", "0.5",
            "--every-minutes", "15", "--kml", "-"]  # fmt: skip
    assert main(argv) == 0
    out, err = capsys.readouterr()
    assert etree.fromstring(out.encode("utf-8")).tag == "{http://www.opengis.net/kml/2.2}kml"
    assert "DEMO WEATHER" in out and "*** DEMO WEATHER" in err
    assert not (tmp_path / "-").exists()

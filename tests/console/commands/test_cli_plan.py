"""`drs plan` end to end: GRIB2 written by eccodes, zone/target GeoJSON files, console.commands.main.main."""

from __future__ import annotations

import json
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from console.commands.main import main
from predictor.environment.gribwrite import gfs_file_name, write_gfs_grib2
from tests.predictor.predict_helpers import H_ISO, LEVELS_HPA, P0_HPA, T_ISO

CYCLE = datetime(2024, 5, 1, 0, tzinfo=UTC)


@pytest.fixture(scope="module")
def grib_files(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    root = tmp_path_factory.mktemp("gfs")
    lats, lons = np.arange(40.0, 52.01, 0.5), np.arange(0.0, 14.01, 0.5)
    shape = (LEVELS_HPA.size, lats.size, lons.size)
    gh = np.broadcast_to((-H_ISO * np.log(LEVELS_HPA / P0_HPA))[:, None, None], shape)
    files = []
    for step in (0, 3, 6):
        u = np.full(shape, 10.0 + step) + 0.2 * lons[None, None, :]
        v = np.full(shape, 1.0) + 0.1 * (lats[None, :, None] - 46.0)
        files.append(
            write_gfs_grib2(root / gfs_file_name(CYCLE, step), CYCLE, step, LEVELS_HPA, lats, lons,
                            u, v, np.full(shape, T_ISO), gh)
        )  # fmt: skip
    return files


def args(files: list[Path], tmp_path: Path, *extra: str) -> list[str]:
    return ["plan", "--weather", *map(str, files), "--cache-dir", str(tmp_path / "cache"),
            "--lat", "46.0", "--lon", "6.0", "--alt", "28000", "--from", "2024-05-01T01:00Z",
            "--hours", "1", "--every-minutes", "15", *extra]  # fmt: skip


def geojson_file(path: Path, geometry: dict, name: str) -> Path:
    path.write_text(
        json.dumps({"type": "FeatureCollection", "features": [
            {"type": "Feature", "properties": {"name": name}, "geometry": geometry}]})
    )  # fmt: skip
    return path


def test_plan_json_with_zones_targets_and_strip_files(
    grib_files: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    lake = geojson_file(
        tmp_path / "z.geojson",
        {"type": "Polygon", "coordinates": [[[9, 45], [9.5, 45], [9.5, 47], [9, 47], [9, 45]]]},
        "lake",
    )
    road = geojson_file(
        tmp_path / "t.geojson", {"type": "LineString", "coordinates": [[8, 44], [8, 48]]}, "road"
    )
    kml, gj = tmp_path / "strip.kml", tmp_path / "strip.geojson"
    code = main(
        args(grib_files, tmp_path, "--zones", str(lake), "--targets", str(road), "--json",
             "--kml", str(kml), "--geojson", str(gj), "--members", "20")
    )  # fmt: skip
    assert code == 0
    doc = json.loads(capsys.readouterr().out)
    assert doc["candidates_total"] == 5 and doc["zones"] == ["lake"] and doc["targets"] == ["road"]
    first = doc["candidates"][0]
    assert first["release"]["time"] == "2024-05-01T01:00:00Z"
    assert 0.0 <= first["zone_probability"] <= 1.0 and first["expected_target_km"] > 0.0
    assert first["uncertainty"]["kind"].startswith("ensemble (20 members)")
    assert kml.read_text().count("<Placemark") >= 7
    assert len(json.loads(gj.read_text())["features"]) >= 7


def test_plan_summary_reports_no_go_for_an_empty_window(
    grib_files: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    sea = geojson_file(
        tmp_path / "sea.geojson",
        {"type": "Polygon", "coordinates": [[[0, 40], [14, 40], [14, 52], [0, 52], [0, 40]]]},
        "sea",
    )
    assert main(args(grib_files, tmp_path, "--zones", str(sea))) == 0
    out = capsys.readouterr().out.splitlines()
    assert out[0] == "NO-GO: none of the 5 candidate release times meets the thresholds"
    assert out[2].strip() == "-----"
    assert all("NO-GO P(zone) 1.000 > 0.05 (mostly sea)" in line for line in out[3:8])


def test_plan_bad_input_is_one_line_with_its_exit_status(
    grib_files: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    bad = tmp_path / "bad.geojson"
    bad.write_text("{")
    assert main(args(grib_files, tmp_path, "--zones", str(bad))) == 1
    err = capsys.readouterr().err.strip()
    assert err.startswith("drs: error: zone file") and "not JSON" in err and "\n" not in err
    assert main(["plan", "--lat", "1"]) == 2
    assert capsys.readouterr().err.strip() == "drs: error: drs plan needs --weather, --lon, --alt, --from"
    assert main(args(grib_files, tmp_path, "--max-target-km", "5")) == 1
    assert "needs a targets file" in capsys.readouterr().err
    with pytest.raises(SystemExit) as usage:  # a command-line mistake: argparse's exit status 2 (#25 item 7)
        main([*args(grib_files, tmp_path)[:-4], "--hours", "1", "--every-minutes", "0"])
    assert usage.value.code == 2
    assert "argument --every-minutes: 0 is not a positive number of minutes" in capsys.readouterr().err


def test_plan_flies_the_mass_and_cda_given_and_refuses_them_beside_a_model(
    grib_files: list[Path], tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    def landings(*extra: str) -> list[str]:
        assert main(args(grib_files, tmp_path, "--json", *extra)) == 0
        return [c["landing"]["time"] for c in json.loads(capsys.readouterr().out)["candidates"]]

    nominal = landings()
    heavier = landings("--mass", "3.0")
    draggier = landings("--cda", "5.0")
    assert all(h < n < d for h, n, d in zip(heavier, nominal, draggier, strict=True)), "heavier falls faster"
    model = tmp_path / "m.json"
    model.write_text("{}")
    assert main(args(grib_files, tmp_path, "--model", str(model), "--mass", "3.0")) == 2
    assert "give --model or --payload/--mass/--cda, not both" in capsys.readouterr().err

"""JSON, KML, GeoJSON and GPX outputs of a prediction, parsed back and checked for what they must contain.

tests/exports reads every product's files with the schema and the readers users have; these pin
what a prediction's files say.
"""

from __future__ import annotations

import json
import xml.etree.ElementTree as ET
from pathlib import Path

import gpxpy
import pytest

from predictor import EnsemblePrediction, Payload, Prediction, PredictorError, predict, predict_ensemble
from predictor.descent import Release
from predictor.prediction import EnsembleSpread, FlightSetup
from predictor.prediction.export import to_geojson, to_json, write_geojson, write_gpx, write_json, write_kml
from tests.predictor.predict_helpers import RELEASE, isothermal_cube

KML_NS = {"k": "http://www.opengis.net/kml/2.2"}
PAYLOAD = Payload(mass_kg=1.029, cda_m2=1.13)


@pytest.fixture(scope="module")
def prediction() -> Prediction:
    return predict(isothermal_cube(u=8.0, v=3.0), Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD))


@pytest.fixture(scope="module")
def demo_ensemble() -> EnsemblePrediction:
    cube = isothermal_cube(u=8.0, is_demo=True)
    return predict_ensemble(
        cube, Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD), EnsembleSpread(members=20, seed=0)
    )


def test_json_parses_back_to_the_result_document(prediction: Prediction) -> None:
    doc = json.loads(to_json(prediction, track=True))
    assert doc == json.loads(json.dumps(prediction.to_dict(track=True)))
    assert len(doc["track"]) == len(prediction.track.lat)


def test_kml_has_path_release_landing_and_three_ellipses(prediction: Prediction, tmp_path: Path) -> None:
    root = ET.parse(write_kml(prediction, tmp_path / "p.kml")).getroot()
    placemarks = root.findall(".//k:Placemark", KML_NS)
    names = [p.findtext("k:name", namespaces=KML_NS) for p in placemarks]
    assert names[:3] == ["descent path", "release", "landing"]
    assert sum("σ" in n for n in names) == 3
    assert any("39.3 %" in n for n in names) and any("86.5 %" in n for n in names)
    coords = root.find(".//k:LineString/k:coordinates", KML_NS).text.split()
    first = [float(x) for x in coords[0].split(",")]
    assert first == pytest.approx([5.0, 46.0, 30000.0])
    assert len(coords) == len(prediction.track.lat)
    ring = root.find(".//k:Polygon//k:coordinates", KML_NS).text.split()
    assert ring[0] == ring[-1]


def test_geojson_features_and_their_geometry(prediction: Prediction, tmp_path: Path) -> None:
    doc = json.loads(write_geojson(prediction, tmp_path / "p.geojson").read_text())
    assert doc["type"] == "FeatureCollection"
    kinds = [f["properties"]["kind"] for f in doc["features"]]
    assert kinds[:3] == ["path", "release", "landing"] and kinds.count("ellipse") == 3
    landing = doc["features"][2]
    assert landing["geometry"]["coordinates"] == pytest.approx(
        [prediction.landing.lon, prediction.landing.lat], abs=5e-7
    )
    polygon = doc["features"][3]
    assert polygon["geometry"]["type"] == "Polygon"
    assert polygon["geometry"]["coordinates"][0][0] == polygon["geometry"]["coordinates"][0][-1]
    assert polygon["properties"]["probability"] == pytest.approx(0.393, abs=1e-3)
    assert doc["drs"]["is_demo"] is False and "properties" not in doc
    assert all(f["properties"]["source"] == prediction.weather_source for f in doc["features"])


def test_demo_ensemble_outputs_say_demo_and_carry_members(
    demo_ensemble: EnsemblePrediction, tmp_path: Path
) -> None:
    kml_root = ET.parse(write_kml(demo_ensemble, tmp_path / "e.kml")).getroot()
    assert "DEMO WEATHER" in kml_root.find(".//k:Document/k:name", KML_NS).text
    assert "DEMO WEATHER" in kml_root.find(".//k:Document/k:description", KML_NS).text
    assert kml_root.find(".//k:Folder/k:name", KML_NS).text == "20 ensemble landings"
    geo = to_geojson(demo_ensemble)
    assert geo["drs"]["is_demo"] is True and "DEMO" in geo["drs"]["title"]
    members = [f for f in geo["features"] if f["properties"]["kind"] == "ensemble landings"][0]
    assert len(members["geometry"]["coordinates"]) == 20
    assert sum(f["properties"]["kind"] == "ellipse" for f in geo["features"]) == 6
    doc = json.loads(write_json(demo_ensemble, tmp_path / "e.json").read_text())
    assert doc["is_demo"] is True and doc["warnings"][0].startswith("DEMO WEATHER")


def test_unwritable_output_is_a_clear_error(prediction: Prediction, tmp_path: Path) -> None:
    with pytest.raises(PredictorError, match="cannot write the KML file .*missing"):
        write_kml(prediction, tmp_path / "missing" / "p.kml")


def test_gpx_leads_with_the_predicted_landing_for_a_handheld(prediction: Prediction, tmp_path: Path) -> None:
    gpx = gpxpy.parse(write_gpx(prediction, tmp_path / "p.gpx").read_text(encoding="utf-8"))
    landing, release = gpx.waypoints
    assert (landing.name, landing.symbol) == ("DRS PRED LAND", "Flag, Blue")
    assert landing.latitude == pytest.approx(prediction.landing.lat, abs=5e-7)
    assert landing.longitude == pytest.approx(prediction.landing.lon, abs=5e-7)
    assert abs((landing.time - prediction.landing.time).total_seconds()) < 1.0
    assert "39 % ellipse" in landing.description
    assert release.name == "DRS RELEASE" and release.elevation == pytest.approx(30000.0)
    [path] = gpx.tracks
    assert len(path.segments[0].points) == len(prediction.track.lat)


def test_gpx_of_demo_weather_names_every_waypoint_demo(demo_ensemble: EnsemblePrediction) -> None:
    from predictor.prediction.export import to_gpx

    gpx = gpxpy.parse(to_gpx(demo_ensemble))
    assert [w.name for w in gpx.waypoints] == ["DEMO PRED LAND", "DEMO RELEASE"]
    assert all("DEMO WEATHER" in w.description for w in gpx.waypoints)


def test_dash_writes_the_file_to_standard_output(
    prediction: Prediction, capsys: pytest.CaptureFixture[str]
) -> None:
    write_geojson(prediction, "-")
    assert json.loads(capsys.readouterr().out)["type"] == "FeatureCollection"
    assert not Path("-").exists()

"""A live-only term (the pre-flight gate found it made the held-out pre-flight prediction worse) is flown
live and left out of every pre-flight prediction; a model file written before the gate still loads."""

from __future__ import annotations

import json
import re
from datetime import UTC, datetime
from pathlib import Path

import pytest

from console.commands.main import main
from predictor.descent import Release
from predictor.descent.model import DescentRateScale, DragDensityExponent
from predictor.descent.payload import Payload
from predictor.environment.demo_weather import demo_weather_files
from predictor.environment.terrain import Terrain
from predictor.environment.weather import load_weather
from predictor.prediction import FlightSetup
from predictor.prediction.landings import predict
from predictor.prediction.model_file import CalibratedModel, ModelFileError, load_model, save_model
from predictor.prediction.uncertainty import ErrorModel

WHEN = datetime(2026, 11, 22, 12, tzinfo=UTC)
RELEASE = ("--lat", "46.5", "--lon", "6.6", "--alt", "28000", "--time", "2026-11-22T12:00Z")
LIVE = (DescentRateScale(scale=0.96), DragDensityExponent(exponent=0.06))
"""The live law: λ (the median under every term) and the shape."""
PREFLIGHT = (DescentRateScale(scale=1.01),)
"""The pre-flight law once the gate made the exponent live-only: λ under the plain law alone."""
WHY = "pre-flight it makes the landing 4.49 → 4.59 km (+0.11, 95 % -0.13…+0.35)"
REASON = f"live-only: {WHY}"


def gated() -> CalibratedModel:
    return CalibratedModel(
        Payload(6.0, 1.36, name="superbit-test", source="fitted"), LIVE,
        ErrorModel(1.2, 5e-4, 0.0, 1.3, name="calibrated"),
        {"created_utc": "2026-12-02T11:00:00Z", "flights": ["18-5-19", "18-6-30"], "weather": "ascent winds",
         "preflight_gate": [{"term": "drag_density_exponent", "preflight": False, "reason": REASON}]},
        preflight=PREFLIGHT,
    )  # fmt: skip


def test_the_file_marks_each_term_and_loads_both_laws_back(tmp_path: Path) -> None:
    path = save_model(gated(), tmp_path / "m.json")
    raw = json.loads(path.read_text())
    assert raw["schema"] == 6, (
        "schema 4 added each term's flown (5 the live law, 6 the pre-flight spread and the wind gain)"
    )
    assert [(t["effect"], t["flown"]) for t in raw["terms"]] == [
        ("descent_rate_scale", "live-only"), ("descent_rate_scale", "pre-flight-only"),
        ("drag_density_exponent", "live-only"),
    ]  # fmt: skip
    loaded = load_model(path)
    assert loaded.terms == LIVE and loaded.preflight == PREFLIGHT
    assert loaded.live_only() == ("drag_density_exponent",)


def test_flight_setup_leaves_a_live_only_term_out_and_live_re_prediction_flies_it(tmp_path: Path) -> None:
    loaded = load_model(save_model(gated(), tmp_path / "m.json"))
    assert loaded.flight_setup(Terrain.sea_level()).effects == PREFLIGHT
    cube = load_weather(
        demo_weather_files(46.5, 6.6, WHEN, cache_dir=tmp_path / "wx"), cache_dir=tmp_path / "c"
    )
    assert loaded.live_predictor(cube).effects == LIVE


def test_drs_predict_flies_the_pre_flight_law(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = save_model(gated(), tmp_path / "m.json")
    files = demo_weather_files(46.5, 6.6, WHEN, cache_dir=tmp_path / "wx")
    argv = ["predict", "--weather", *map(str, files), "--cache-dir", str(tmp_path / "c"), *RELEASE, "--json"]
    assert main([*argv, "--model", str(path)]) == 0
    flown = json.loads(capsys.readouterr().out)
    cube = load_weather(files, cache_dir=tmp_path / "c")
    release = Release(WHEN, 46.5, 6.6, 28000.0)
    ellipse = gated().chosen_ellipse(None)
    preflight = predict(cube, release, FlightSetup(gated().payload, effects=PREFLIGHT, error_model=ellipse))
    live = predict(cube, release, FlightSetup(gated().payload, effects=LIVE, error_model=ellipse))
    assert flown["descent_s"] == pytest.approx(preflight.descent_s)
    assert flown["landing"]["lat"] == pytest.approx(preflight.landing.lat, abs=1e-9)
    assert abs(live.descent_s - preflight.descent_s) > 10.0, (
        "the two laws differ (by 28 s): the test can fail"
    )


def test_drs_model_show_says_which_terms_are_live_only_and_why(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["model", "show", str(save_model(gated(), tmp_path / "m.json"))]) == 0
    out = capsys.readouterr().out
    assert (
        f"drag_density_exponent (vertical): exponent 0.06, reference_density 1.225; LIVE-ONLY ({WHY})" in out
    )
    assert "descent_rate_scale (vertical): scale 1.01; pre-flight only" in out


def test_a_model_file_written_before_the_gate_loads_flies_every_term_and_says_so(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """A schema-3 file as `drs calibrate --save-model` wrote it before the gate (the committed
    docs/planning/superbit-2018-2019-model.json is one): no ``flown``, every term flies both ways."""
    document = gated().to_dict()
    document["schema"] = 3
    document["terms"] = [
        {"effect": t["effect"], "parameters": t["parameters"]}
        for t in document["terms"]
        if t["flown"] != "pre-flight-only"
    ]
    path = tmp_path / "old.json"
    path.write_text(json.dumps(document))
    old = load_model(path)
    assert old.terms == LIVE and old.preflight is None and old.live_only() == ()
    assert old.flight_setup(Terrain.sea_level()).effects == LIVE
    assert main(["model", "show", str(path)]) == 0
    assert "written before the pre-flight gate: not judged" in capsys.readouterr().out


@pytest.mark.parametrize(
    ("flown", "problem"),
    [(None, "terms[0].flown: must be one of both, live-only, pre-flight-only, got None"),
     ("sometimes", "terms[0].flown: must be one of both, live-only, pre-flight-only, got 'sometimes'")],
)  # fmt: skip
def test_a_schema_4_term_without_a_known_flown_is_refused(
    tmp_path: Path, flown: object, problem: str
) -> None:
    document = gated().to_dict()
    document["terms"][0]["flown"] = flown
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match=re.escape(problem)):
        load_model(path)


def test_two_pre_flight_rate_factors_are_refused(tmp_path: Path) -> None:
    document = gated().to_dict()
    document["terms"][0]["flown"] = "both"
    path = tmp_path / "bad.json"
    path.write_text(json.dumps(document))
    with pytest.raises(ModelFileError, match="the pre-flight law has more than one descent_rate_scale"):
        load_model(path)

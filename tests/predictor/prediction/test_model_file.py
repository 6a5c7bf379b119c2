"""The calibrated model file: what is saved is what predictions fly, and a bad file is refused by name."""

from __future__ import annotations

import json
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path

import pytest

from console.commands.main import main
from predictor.descent import Release
from predictor.descent.model import BinnedDescentRate, DescentRateScale, DragDensityExponent
from predictor.descent.payload import Payload
from predictor.descent.rate_prior import PreflightSpread
from predictor.environment.demo_weather import demo_weather_files
from predictor.environment.weather import load_weather
from predictor.prediction import FlightSetup
from predictor.prediction.landings import predict
from predictor.prediction.live import (
    Band,
    LiveCorrection,
    LiveErrorModel,
    LiveSettings,
    RateDiscrepancy,
    WindGain,
)
from predictor.prediction.model_file import (
    SCHEMA_VERSION,
    CalibratedModel,
    ModelFileError,
    load_model,
    save_model,
)
from predictor.prediction.uncertainty import ErrorModel

WHEN = datetime(2026, 11, 22, 12, tzinfo=UTC)
RELEASE = ("--lat", "46.5", "--lon", "6.6", "--alt", "28000", "--time", "2026-11-22T12:00Z")


def example() -> CalibratedModel:
    return CalibratedModel(
        Payload(6.0, 1.36, name="superbit-test", source="fitted"),
        (DragDensityExponent(exponent=0.06), DescentRateScale(scale=1.04),
         BinnedDescentRate(edges_m=(0.0, 5000.0, 40000.0), factors=(1.02, 0.98))),
        ErrorModel(1.2, 5e-4, 0.0, 1.3, name="calibrated"),
        {"created_utc": "2026-11-24T23:00:00Z", "flights": ["18-5-19", "18-6-30"], "weather": "ascent winds"},
        live=LiveSettings(
            LiveCorrection((Band(0.0, 5000.0, True, None), Band(5000.0, float("inf"), True, 2000.0))),
            LiveErrorModel((20.0, 2.0), (3.9, 1.6), (3.8, 0.8)),
            RateDiscrepancy((5.0, 20.0), (0.0, 0.04), (0.02, 0.05), (0.01, -0.02), (0.12, 0.15), (28, 27)),
        ),
        preflight_spread=PreflightSpread(0.14, 2),
    )  # fmt: skip


def test_a_saved_model_loads_back_the_same(tmp_path: Path) -> None:
    path = save_model(example(), tmp_path / "m.json")
    loaded = load_model(path)
    assert loaded.payload == example().payload and loaded.terms == example().terms
    assert loaded.ellipse == example().ellipse and loaded.provenance == example().provenance
    assert loaded.live == example().live, "bands (open ends included), λ discrepancy and live sigma"
    assert loaded.preflight_spread == example().preflight_spread
    assert loaded.label() == "m.json (calibrated 2026-11-24 on 2 flights)"
    assert [p.name for p in tmp_path.iterdir()] == ["m.json"], "no temporary file left behind"


def test_drs_predict_with_the_model_equals_the_same_terms_by_hand(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = save_model(example(), tmp_path / "m.json")
    files = demo_weather_files(46.5, 6.6, WHEN, cache_dir=tmp_path / "wx")
    argv = ["predict", "--weather", *map(str, files), "--cache-dir", str(tmp_path / "c"), *RELEASE, "--json"]
    assert main([*argv, "--model", str(path)]) == 0
    flown = json.loads(capsys.readouterr().out)
    by_hand = predict(
        load_weather(files, cache_dir=tmp_path / "c"),
        Release(WHEN, 46.5, 6.6, 28000.0),
        FlightSetup(example().payload, effects=example().terms, error_model=example().ellipse),
    )  # fmt: skip
    assert flown["landing"]["lat"] == pytest.approx(by_hand.landing.lat, abs=1e-9)
    assert flown["landing"]["lon"] == pytest.approx(by_hand.landing.lon, abs=1e-9)
    assert flown["descent_s"] == pytest.approx(by_hand.descent_s)
    assert flown["model"]["label"].startswith("m.json (calibrated 2026-11-24")
    assert main(argv) == 0
    plain = json.loads(capsys.readouterr().out)
    assert plain["descent_s"] != pytest.approx(flown["descent_s"]), "the model changes the prediction"


def test_model_and_payload_together_are_refused(tmp_path: Path, capsys: pytest.CaptureFixture[str]) -> None:
    path = save_model(example(), tmp_path / "m.json")
    assert main(["predict", "--demo-weather", *RELEASE, "--model", str(path), "--mass", "2"]) == 2
    assert "give --model or --payload/--mass/--cda, not both" in capsys.readouterr().err


def test_drs_model_show_names_the_payload_terms_ellipse_and_provenance(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    path = save_model(example(), tmp_path / "m.json")
    assert main(["model", "show", str(path)]) == 0
    out = capsys.readouterr().out
    for text in ("superbit-test: 6 kg, Cd·A 1.36 m²", "term      drag_density_exponent (vertical): exponent 0.06",
                 "ellipse   σ0 1.2 km", "flights   2: 18-5-19, 18-6-30", "weather   ascent winds",
                 "λ spread  pre-flight: σ of ln λ 0.14 about the pre-flight law's λ (its held-out descent times "
                 "over 2 flights; pre-flight descent time ±14 % 1σ)",
                 "live      0 km–5 km: own λ updated, wind off; 5 km–top: own λ updated, wind L = 2 km",
                 "live law  in the bands: the model's terms, with the flight's own λ where a band updates it; "
                 "outside them: the model's terms",
                 "live 1σ   20 km 3.90×3.80 km"):  # fmt: skip
        assert text in out


def test_a_model_with_an_unstable_term_says_so_wherever_it_is_named(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    from dataclasses import replace

    from predictor.descent.rate_prior import RatePrior

    model = replace(example(), provenance={**example().provenance, "unstable_terms": ["drag_density_exponent"],
                                           "selection_stability": {"drag_density_exponent": 0.6}},
                    rate_prior=RatePrior(1.04, 0.08, 30))  # fmt: skip
    path = save_model(model, tmp_path / "m.json")
    assert (
        "[FLAG: drag_density_exponent chosen in under 2/3 of the selection's folds]"
        in load_model(path).label()
    )
    files = demo_weather_files(46.5, 6.6, WHEN, cache_dir=tmp_path / "wx")
    assert main(["predict", "--weather", *map(str, files), "--cache-dir", str(tmp_path / "c"), *RELEASE,
                 "--model", str(path)]) == 0  # fmt: skip
    assert "FLAG: drag_density_exponent chosen in under 2/3" in capsys.readouterr().out
    assert main(["model", "show", str(path)]) == 0
    out = capsys.readouterr().out
    assert "λ prior   median 1.04, sd of ln λ 0.08 over 30 flights" in out
    assert "stability drag_density_exponent chosen in 60% of folds" in out


def _write(tmp_path: Path, document: object) -> Path:
    path = tmp_path / "bad.json"
    path.write_text(document if isinstance(document, str) else json.dumps(document))
    return path


def _good() -> dict:
    return example().to_dict()


def _with(change: dict) -> dict:
    document = _good()
    for dotted, value in change.items():
        target = document
        *parents, last = dotted.split(".")
        for key in parents:
            target = target[int(key)] if isinstance(target, list) else target[key]
        target[last] = value
    return document


@pytest.mark.parametrize(
    ("document", "message"),
    [
        ("{not json", r"bad\.json: is not valid JSON \(Expecting property name"),
        ({"kind": "something else"}, r"bad\.json: kind: not a calibrated model"),
        (
            _with({"schema": SCHEMA_VERSION + 1}),
            rf"schema: version {SCHEMA_VERSION + 1} is newer than this drs",
        ),
        (_with({"schema": "1"}), r"schema: must be a whole number"),
        (_with({"payload.mass_kg": -1.0}), r"payload\.mass_kg: must be a positive number of kg, got -1"),
        (_with({"payload.cda_m2": "big"}), r"payload\.cda_m2: must be a finite number, got 'big'"),
        (_with({"terms.0.effect": "gremlins"}), r"terms\[0\]\.effect: 'gremlins' is not a known effect"),
        (
            _with({"terms.1.parameters": {"scale": 1.0, "speed": 2}}),
            r"terms\[1\]\.parameters\.speed: is not a parameter",
        ),
        (
            _with({"terms.1.parameters": {"scale": float("nan")}}),
            r"terms\[1\]\.parameters\.scale: must be a finite",
        ),
        (
            _with({"terms.2.parameters.factors": [1.0]}),
            r"terms\[2\]: binned_descent_rate: need one value per bin",
        ),
        (
            _with({"ellipse.q": 0.0}),
            r"ellipse: error model 'calibrated': sigma0, h and k must be ≥ 0 and q > 0",
        ),
        (_with({"terms": {"a": 1}}), r"terms: must be a list"),
        (_with({"preflight_spread": [0.1]}), r"preflight_spread: must be an object with log_sigma"),
        (
            _with({"preflight_spread.log_sigma": 1.5}),
            r"preflight_spread: pre-flight spread log_sigma 1\.5 is outside 0\.0–1\.0",
        ),
        (_with({"preflight_spread.flights": 2.5}), r"preflight_spread\.flights: must be a whole number"),
        (_with({"live": []}), r"live: must be an object with bands"),
        (
            _with({"live.bands.0.use_rate": "yes"}),
            r"live\.bands\[0\]: must be an object with .* use_rate \(true/false\)",
        ),
        (_with({"live.bands.0.upper_m": -1.0}), r"live\.bands\[0\]: lower_m 0 must be below upper_m -1"),
        (
            _with({"live.bands.1.wind_decay_m": 0.0}),
            r"live\.bands\[1\]: wind_decay_m must be a positive length",
        ),
        (
            _with({"live.discrepancy.log_sigma": [0.02, -0.05]}),
            r"live\.discrepancy\.log_sigma: must not be negative, got -0\.05",
        ),
        (
            _with({"live.discrepancy.remaining_log_sigma": [0.12, 1.5]}),
            r"live\.discrepancy\.remaining_log_sigma: must be within 0–1",
        ),
        (
            _with({"live.discrepancy.remaining_flights": [28]}),
            r"live\.discrepancy: the remaining_\* columns must be as long as heights_km",
        ),
        (
            _with({"live.discrepancy.remaining_log_mean": [0.01, 3.0]}),
            r"live\.discrepancy\.remaining_log_mean: must be within ±ln 5",
        ),
        (
            _with({"live.error_model.sigma_parallel_km": [3.9]}),
            r"live\.error_model: heights_km, sigma_parallel_km, sigma_perpendicular_km must be as long",
        ),
        (
            _with({"live.law": "shape"}),
            r"live\.law: must be one of model, payload \(absent: model\), got 'shape'",
        ),
        (
            _with({"live.restart": 1}),
            r"live\.restart: must be one of model, payload \(absent: model\), got 1",
        ),
    ],
    ids=[
        "corrupt",
        "kind",
        "future-schema",
        "schema-type",
        "negative-mass",
        "cda-text",
        "unknown-effect",
        "unknown-parameter",
        "nan",
        "bins",
        "ellipse",
        "terms-type",
        "spread-type",
        "spread-range",
        "spread-flights",
        "live-type",
        "live-use-rate",
        "live-band-order",
        "live-decay",
        "live-discrepancy",
        "live-remaining-sigma",
        "live-remaining-length",
        "live-remaining-mean",
        "live-sigma",
        "live-law",
        "live-restart",
    ],  # fmt: skip
)
def test_a_bad_model_file_is_refused_naming_the_file_and_the_field(
    tmp_path: Path, document: object, message: str
) -> None:
    with pytest.raises(ModelFileError, match=message):
        load_model(_write(tmp_path, document))


def test_a_missing_model_file_is_one_line_from_the_cli(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    assert main(["predict", "--demo-weather", *RELEASE, "--model", str(tmp_path / "none.json")]) == 1
    err = capsys.readouterr().err
    assert err == f"drs: error: model file {tmp_path / 'none.json'} does not exist\n"


def _one_term(effect: str, parameters: dict) -> dict:
    document = _good()
    document["terms"] = [{"effect": effect, "parameters": parameters}]
    return document


@pytest.mark.parametrize(
    ("document", "message"),
    [
        (
            _one_term("drag_density_exponent", {"exponent": 5.0}),
            r"terms\[0\]\.parameters\.exponent: 5 is outside the calibration's bounds -0\.5…0\.5",
        ),
        (
            _one_term("descent_rate_scale", {"scale": 10.0}),
            r"terms\[0\]\.parameters\.scale: 10 is outside .* 0\.5…2",
        ),
        (_one_term("wind_scale", {"scale": -1.0}), r"terms\[0\]\.parameters\.scale: -1 is outside .* 0\.3…2"),
        (
            _one_term("deployment_delay", {"delay_s": -5.0}),
            r"terms\[0\]\.parameters\.delay_s: -5 is outside .* 0…240",
        ),
        (
            _one_term("deployment_delay", {"delay_s": 30.0, "speed_factor": 0.1}),
            r"terms\[0\]\.parameters\.speed_factor: 0\.1 is outside .* 1…10",
        ),
        (
            _one_term("two_regime_rate", {"height_m": 20000.0, "factor": 3.0}),
            r"terms\[0\]\.parameters\.factor: 3 is outside .* 0\.5…2",
        ),
        (
            _one_term("two_regime_rate", {"height_m": 1e6, "factor": 1.2}),
            r"terms\[0\]\.parameters\.height_m: 1e\+06 is outside .* -500…50000",
        ),
        (
            _one_term("binned_descent_rate", {"edges_m": [0.0, 5000.0], "factors": [4.0]}),
            r"terms\[0\]\.parameters\.factors: 4 is outside .* 0\.5…2",
        ),
        (
            _one_term("wind_band_scale", {"bottom_m": 9000.0, "top_m": 3000.0, "scale": 1.2}),
            r"terms\[0\]\.parameters: wind_band_scale: bottom_m must be below top_m",
        ),
        (
            _with({"payload.mass_kg": 1e6}),
            r"payload\.mass_kg: 1e\+06 is outside the payloads drs calibrates \(0\.05–50\)",
        ),
        (_with({"payload.cda_m2": 1e-4}), r"payload\.cda_m2: 0\.0001 is outside the payloads drs calibrates"),
    ],
    ids=[
        "exponent",
        "rate-scale",
        "negative-wind-scale",
        "negative-delay",
        "fast-fall-factor",
        "two-regime-factor",
        "two-regime-height",
        "binned-factor",
        "band-order",
        "mass",
        "cda",
    ],  # fmt: skip
)
def test_an_impossible_value_is_refused_in_one_line_naming_the_file_and_the_field(
    tmp_path: Path, document: dict, message: str, capsys: pytest.CaptureFixture[str]
) -> None:
    path = _write(tmp_path, document)
    with pytest.raises(ModelFileError, match=rf"^model file {tmp_path / 'bad.json'}: {message}"):
        load_model(path)
    assert main(["predict", "--demo-weather", *RELEASE, "--model", str(path)]) == 1
    err = capsys.readouterr().err
    assert err.count("\n") == 1 and err.startswith(f"drs: error: model file {path}: ")


def test_every_parameter_of_every_effect_has_the_calibrations_bounds() -> None:
    """A term added to the registry without bounds would let any value of it fly."""
    import dataclasses

    from predictor.descent.model import EFFECTS
    from predictor.prediction.model_file import PARAMETER_LIMITS as limits

    missing = [(name, f.name) for name, cls in EFFECTS.items() for f in dataclasses.fields(cls)
               if (name, f.name) not in limits]  # fmt: skip
    assert missing == []


def test_the_shape_is_the_terms_without_the_priors_median() -> None:
    from dataclasses import replace

    from predictor.descent.rate_prior import RatePrior

    shape = (DragDensityExponent(exponent=0.07),)
    with_prior = replace(
        example(), terms=(DescentRateScale(scale=0.96), *shape), rate_prior=RatePrior(0.96, 0.13, 30)
    )
    assert with_prior.shape_terms() == shape
    assert replace(with_prior, rate_prior=None).shape_terms() == with_prior.terms, (
        "no prior: λ is a term like any"
    )


def test_live_restarts_from_the_law_the_file_names_and_an_older_file_from_its_terms(tmp_path: Path) -> None:
    # Schema 5 named the live law (what the bands correct) and the restart (what flies outside them); a
    # file written before (neither) flew the model's terms live everywhere, and still does. ``payload``:
    # the payload's drag law, no calibrated term (the plain restart from the nominal payload, which the
    # flight's own λ corrects), with the evaluation's λ prior since the calibration's is on the terms.
    document = example().to_dict()
    assert document["schema"] == SCHEMA_VERSION == 6
    assert (document["live"]["law"], document["live"]["restart"]) == ("model", "model")
    del document["live"]["law"], document["live"]["restart"]
    document["schema"] = 4
    older = tmp_path / "old.json"
    older.write_text(json.dumps(document), encoding="utf-8")
    cube = load_weather(
        demo_weather_files(46.5, 6.6, WHEN, cache_dir=tmp_path / "wx"), cache_dir=tmp_path / "c"
    )
    assert load_model(older).live == example().live
    old = load_model(older).live_predictor(cube)
    assert old.effects == old.restart_effects == example().terms
    document["live"]["law"] = "payload"
    document["live"]["restart"] = "payload"
    document["live"]["prior"] = {"median": 1.0, "log_sigma": 0.1, "flights": 9}
    newer = tmp_path / "new.json"
    newer.write_text(json.dumps(document), encoding="utf-8")
    live = load_model(newer).live_predictor(cube)
    assert live.effects == live.restart_effects == () and live.payload == example().payload
    assert live.prior is not None and live.prior.flights == 9
    assert any(note.startswith("live law: the payload's drag law") for note in live.notes)


def test_the_wind_gain_is_saved_flown_and_shown_and_an_older_file_carries_all_of_the_wind(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    # Schema 6 carries the share of the measured wind error the evaluation's flights wanted carried
    # down (``live.wind_gain``); a file written before has none and flies all of it, as it did.
    assert example().live is not None and example().live.correction.wind_gain is None
    assert "wind_gain" not in example().to_dict()["live"]
    gain = WindGain((2.0, 5.0, 10.0), (0.0, 0.25, 1.0))
    live = replace(example().live, correction=replace(example().live.correction, wind_gain=gain))
    path = save_model(replace(example(), live=live), tmp_path / "m.json")
    loaded = load_model(path)
    assert loaded.live is not None and loaded.live.correction.wind_gain == gain
    cube = load_weather(
        demo_weather_files(46.5, 6.6, WHEN, cache_dir=tmp_path / "wx"), cache_dir=tmp_path / "c"
    )
    assert loaded.live_predictor(cube).correction.wind_gain == gain
    assert main(["model", "show", str(path)]) == 0
    assert (
        "live wind share of the measured error carried, by report height: 2 km 0.00, 5 km 0.25, 10 km 1.00"
        in (capsys.readouterr().out)
    )
    document = json.loads(path.read_text(encoding="utf-8"))
    for bad, message in (
        ({"heights_km": [2.0, 5.0], "gains": [0.5, 1.2]}, r"live\.wind_gain\.gains: must be within 0–1"),
        (
            {"heights_km": [2.0], "gains": [0.5, 0.5]},
            r"live\.wind_gain: heights_km and gains must be as long",
        ),
        ([0.5], r"live\.wind_gain: must be an object with heights_km and gains"),
    ):
        document["live"]["wind_gain"] = bad
        with pytest.raises(ModelFileError, match=message):
            load_model(_write(tmp_path, document))

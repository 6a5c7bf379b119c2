"""A capsule's `model` key: its predictions fly the calibrated model and say so; a bad file stops the start."""

from __future__ import annotations

from pathlib import Path

import pytest

from console.predictions import PredictionService, ReleaseOrigin, capsule_models
from drs_link.config import parse_config
from drs_link.errors import ConfigError
from predictor import Terrain
from predictor.descent.model import DragDensityExponent
from predictor.descent.payload import Payload
from predictor.environment.demo_weather import demo_weather_files
from predictor.errors import PredictorError
from predictor.prediction import CalibratedModel, save_model
from tests.console.conftest import SITE, T0, offline_config


def test_a_capsule_with_a_model_key_predicts_with_it_and_names_it(tmp_path: Path) -> None:
    path = save_model(
        CalibratedModel(Payload(2.0, 0.5, name="heavier"), (DragDensityExponent(exponent=0.1),), None,
                        {"created_utc": "2026-11-24T00:00:00Z", "flights": ["a", "b", "c"]}),
        tmp_path / "drs1.model.json",
    )  # fmt: skip
    config = parse_config({**_document(tmp_path), "capsule": [
        {"name": "DRS1", "host": "127.0.0.1", "model": str(path)}, {"name": "DRS2", "host": "127.0.0.1"}]})  # fmt: skip
    assert config.capsules[0].model == path and config.capsules[1].model is None
    files = demo_weather_files(SITE[0], SITE[1], T0, cache_dir=tmp_path / "wx", hours=6)
    service = PredictionService(lambda: files, Terrain.sea_level, lambda: T0,
                                capsule_models([(c.name, c.model) for c in config.capsules]))  # fmt: skip
    origin = ReleaseOrigin(SITE[0], SITE[1], 31500.0, "test")
    [calibrated] = service.predict("DRS1", origin)
    [plain] = service.predict("DRS2", origin)
    assert calibrated.data.model == "drs1.model.json (calibrated 2026-11-24 on 3 flights)"
    assert plain.data.model == "drs profile"
    assert calibrated.data.descent_s != pytest.approx(plain.data.descent_s, rel=0.01)


def test_a_bad_model_file_names_the_capsule_key(tmp_path: Path) -> None:
    broken = tmp_path / "broken.json"
    broken.write_text("{")
    with pytest.raises(
        PredictorError, match=r"capsule\[1\]\.model \(DRS2\): model file .*broken\.json: is not valid JSON"
    ):
        capsule_models([("DRS1", None), ("DRS2", broken)])


def _document(tmp_path: Path) -> dict:
    return {"operator": {"name": "EL"}, "data": {"dir": str(tmp_path / "data")}}


def test_the_old_payload_key_is_refused_by_name(tmp_path: Path) -> None:
    with pytest.raises(ConfigError, match="payload"):
        parse_config({**_document(tmp_path), "capsule": [{"name": "DRS1", "host": "h", "payload": "drs"}]})
    assert offline_config(tmp_path).capsules[0].model is None

"""The live ellipse widens with the distance between the ascent (where its winds were measured) and the
descent still to come, and says what its 1σ and 2σ mean (issue #30 item 4). Real flights and the
committed model file: deterministic, so no false failures."""

from __future__ import annotations

import dataclasses
import json
import math
from pathlib import Path

import numpy as np
import pytest

from predictor.calibration.live_evaluation import LevelGround
from predictor.environment import WeatherCube
from predictor.prediction import LIVE_PROBABILITIES, LivePrediction, load_model
from predictor.prediction.landings import Track
from predictor.prediction.live import (
    ELLIPSE_MEANING,
    TYPICAL_DISTANCE_NOTE,
    LiveErrorModel,
    ascent_distance_km_h,
)
from predictor.prediction.model_file import ModelFileError
from predictor.tracks import ascent_weather_cube, clean, read_track
from tests.conftest import REPO_ROOT

MODEL = REPO_ROOT / "docs" / "planning" / "superbit-2018-2019-model.json"


def committed_error_model() -> LiveErrorModel:
    live = load_model(MODEL).live
    assert live is not None
    return live.error_model


def test_the_committed_live_ellipse_grows_with_the_distance_from_the_ascent() -> None:
    errors = committed_error_model()
    assert errors.growth_exponent > 0.0
    for km, typical in zip(errors.heights_km, errors.typical_km_h, strict=True):
        near, usual, far = (errors.at(km, x * typical).sigmas_km(0.0, 0.0) for x in (0.5, 1.0, 2.0))
        assert near[0] < usual[0] < far[0] and near[1] < usual[1] < far[1], km
        # Weather that does not say where it was measured flies the evaluation flights' typical X.
        assert errors.at(km).sigmas_km(0.0, 0.0) == usual


def fly_to(cube: WeatherCube, track: Path, height_m: float) -> LivePrediction:
    """The committed model's live prediction from the first fix of the descent below ``height_m``
    above the landing."""
    flight = clean(read_track(track))
    assert flight.landing is not None
    live = load_model(MODEL).live_predictor(cube, LevelGround(flight.landing.alt_m))
    for fix in flight.descent[:-1]:
        prediction = live.update(fix)
        if fix.alt_m - flight.landing.alt_m <= height_m:
            return prediction
    pytest.fail(f"{track.name} never came below {height_m} m")


def test_a_live_prediction_on_ascent_winds_widens_by_its_own_distance_and_says_what_it_means(
    shared_data: Path,
) -> None:
    track = shared_data / "tracks" / "pyballoon_superbit" / "19-7-28.csv"
    cube = ascent_weather_cube(clean(read_track(track)))
    assert cube.measured_along is not None
    live = fly_to(cube, track, 10000.0)
    assert live.ascent_distance_km_h is not None and live.ascent_distance_km_h > 0.0
    height_km = (live.report.alt_m - live.prediction.landing.alt_m) / 1000.0
    ellipse = live.prediction.ellipse
    expected = committed_error_model().at(height_km, live.ascent_distance_km_h).sigmas_km(0.0, 0.0)
    assert (ellipse.sigma_parallel_km, ellipse.sigma_perpendicular_km) == pytest.approx(expected)
    assert TYPICAL_DISTANCE_NOTE not in live.notes
    out = json.loads(json.dumps(live.to_dict()))
    assert out["ellipse_meaning"] == ELLIPSE_MEANING
    probabilities = [c["probability"] for c in out["ellipse"]["contours"]]
    for p in LIVE_PROBABILITIES:
        assert round(p, 6) in probabilities
    one_sigma = next(c for c in out["ellipse"]["contours"] if c["probability"] == 0.6827)
    assert one_sigma["n_sigma"] == pytest.approx(math.sqrt(-2.0 * math.log(1.0 - 0.6827)), abs=1e-6)
    # The remaining time's σ adds the law's error below to λ's own.
    assert live.rate is not None and live.time_log_sigma is not None and live.time_log_sigma > 0.0
    assert live.remaining_sigma_s is not None
    assert live.remaining_sigma_s > live.prediction.descent_s * live.rate.log_sigma


def test_weather_that_does_not_say_where_it_was_measured_flies_the_typical_distance_and_says_so(
    shared_data: Path,
) -> None:
    track = shared_data / "tracks" / "pyballoon_superbit" / "19-7-28.csv"
    cube = dataclasses.replace(ascent_weather_cube(clean(read_track(track))), measured_along=None)
    live = fly_to(cube, track, 10000.0)
    assert live.ascent_distance_km_h is None
    assert TYPICAL_DISTANCE_NOTE in live.notes
    height_km = (live.report.alt_m - live.prediction.landing.alt_m) / 1000.0
    ellipse = live.prediction.ellipse
    expected = committed_error_model().at(height_km).sigmas_km(0.0, 0.0)
    assert (ellipse.sigma_parallel_km, ellipse.sigma_perpendicular_km) == pytest.approx(expected)


def test_a_model_file_written_before_the_distance_flies_its_table_alone(tmp_path: Path) -> None:
    raw = json.loads(MODEL.read_text(encoding="utf-8"))
    for key in ("growth_exponent", "typical_km_h", "time_log_sigma"):
        del raw["live"]["error_model"][key]
    older = tmp_path / "older.json"
    older.write_text(json.dumps(raw), encoding="utf-8")
    live = load_model(older).live
    assert live is not None
    errors = live.error_model
    assert (errors.growth_exponent, errors.typical_km_h, errors.time_log_sigma) == (0.0, (), ())
    assert errors.at(10.0, 1000.0).sigmas_km(0.0, 0.0) == errors.at(10.0).sigmas_km(0.0, 0.0)
    assert errors.time_sigma_at(10.0) is None


def test_a_negative_distance_column_is_refused(tmp_path: Path) -> None:
    raw = json.loads(MODEL.read_text(encoding="utf-8"))
    raw["live"]["error_model"]["typical_km_h"][0] = -1.0
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(raw), encoding="utf-8")
    with pytest.raises(ModelFileError, match="typical_km_h"):
        load_model(bad)


def test_a_growth_without_the_distance_it_grows_from_is_refused(tmp_path: Path) -> None:
    """An edited file that keeps ``growth_exponent`` but lost ``typical_km_h`` is not flown as if the
    growth were not there."""
    raw = json.loads(MODEL.read_text(encoding="utf-8"))
    del raw["live"]["error_model"]["typical_km_h"]
    bad = tmp_path / "bad.json"
    bad.write_text(json.dumps(raw), encoding="utf-8")
    with pytest.raises(ModelFileError, match="growth_exponent.*typical_km_h"):
        load_model(bad)


def test_the_distance_from_the_ascent_is_the_same_across_the_antimeridian() -> None:
    """A flight whose ascent crossed ±180° (a long-duration flight circling the southern ocean): the
    measured layers' longitudes interpolate across the line, not the long way round through 0°."""

    def distance(lon0: float) -> float:
        def wrapped(lon: np.ndarray) -> np.ndarray:
            return (lon + 180.0) % 360.0 - 180.0

        track = Track(
            t_s=np.array([0.0, 1200.0, 2400.0]), lat=np.array([-45.0, -45.1, -45.2]),
            lon=wrapped(lon0 + np.array([0.3, 0.5, 0.7])), alt_m=np.array([30000.0, 12000.0, 0.0]),
        )  # fmt: skip
        layers = np.array(
            [[0.0, -44.9, lon0 - 0.2], [15000.0, -45.0, lon0 + 0.1], [31000.0, -45.1, lon0 + 0.2]]
        )
        layers[:, 2] = wrapped(layers[:, 2])
        return ascent_distance_km_h(track, layers)

    away_from_the_line = distance(10.0)
    assert 1.0 < away_from_the_line < 100.0
    assert distance(179.95) == pytest.approx(away_from_the_line, rel=1e-6)

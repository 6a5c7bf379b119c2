"""A prediction flown with a calibrated model carries its rate prior's spread (``prior_spread``).

The check on the numbers is closed form: with every term a factor on the rate (λ, a density exponent),
the fall time is ∫ dz / (λ·v(z)), so at λ·e^(±σ) it is exactly the median's × e^(∓σ), whatever the
weather; the runs are the project's kernel, the expectation is that integral's scaling.
"""

from __future__ import annotations

import dataclasses
import json
import math
from datetime import UTC, datetime
from pathlib import Path

import pytest

from console.commands.main import main
from predictor.descent.model import DescentRateScale, DragDensityExponent
from predictor.descent.payload import Payload
from predictor.descent.rate_prior import PreflightSpread, RatePrior
from predictor.environment.demo_weather import demo_weather_files
from predictor.prediction import CalibratedModel, save_model

WHEN = datetime(2026, 11, 22, 12, tzinfo=UTC)
RELEASE = ("--lat", "46.5", "--lon", "6.6", "--alt", "28000", "--time", "2026-11-22T12:00Z")


def _model(log_sigma: float | None) -> CalibratedModel:
    """The shape (a density exponent) × the prior's median λ 0.96, as ``drs calibrate`` saves it."""
    return CalibratedModel(
        Payload(6.0, 1.36, name="superbit-test", source="fitted"),
        (DescentRateScale(scale=0.96), DragDensityExponent(exponent=0.07)),
        None,
        {"created_utc": "2026-11-27T03:00:00Z", "flights": ["a", "b", "c"]},
        rate_prior=None if log_sigma is None else RatePrior(0.96, log_sigma, 30),
    )


def _predict(tmp_path: Path, capsys: pytest.CaptureFixture[str], model: CalibratedModel, *extra: str) -> str:
    name = f"m-{model.rate_prior.log_sigma if model.rate_prior else 'none'}.json"
    path = save_model(model, tmp_path / name)
    files = demo_weather_files(46.5, 6.6, WHEN, cache_dir=tmp_path / "wx")
    argv = ["predict", "--weather", *map(str, files), "--cache-dir", str(tmp_path / "c"), *RELEASE]
    assert main([*argv, "--model", str(path), *extra]) == 0
    return capsys.readouterr().out


def test_a_wider_rate_prior_gives_a_wider_descent_time_interval_about_the_prediction(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    narrow, wide = (json.loads(_predict(tmp_path, capsys, _model(s), "--json")) for s in (0.05, 0.15))
    for flown, sigma in ((narrow, 0.05), (wide, 0.15)):
        spread = flown["rate_prior_spread"]
        times = spread["descent_s"]
        assert times["median"] == pytest.approx(flown["descent_s"], abs=1e-3), "the median is the prediction"
        # Closed form: every term scales the rate, so the time scales by e^(∓σ) (to the step's rounding).
        assert times["slow"] == pytest.approx(flown["descent_s"] * math.exp(sigma), rel=2e-3)
        assert times["fast"] == pytest.approx(flown["descent_s"] * math.exp(-sigma), rel=2e-3)
        assert spread["rate_factor_slow"] == pytest.approx(0.96 * math.exp(-sigma))
        assert spread["descent_sigma_s"] == pytest.approx((times["slow"] - times["fast"]) / 2.0)
        assert spread["landing_shift_km"]["slow"] > 0.0 and spread["landing_shift_km"]["fast"] > 0.0
    assert wide["descent_s"] == narrow["descent_s"], "the spread does not move the prediction"
    wider, narrower = wide["rate_prior_spread"], narrow["rate_prior_spread"]
    assert wider["descent_sigma_s"] > 2.5 * narrower["descent_sigma_s"]
    assert wider["landing_shift_km"]["slow"] > narrower["landing_shift_km"]["slow"]


def test_the_text_names_the_interval_and_a_model_without_a_prior_claims_none(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    text = _predict(tmp_path, capsys, _model(0.1))
    line = next(x for x in text.splitlines() if x.startswith("λ ±1σ"))
    assert "σ ln λ 0.1)" in line and "at λ 1.06–0.869" in line, line
    without = _model(None)
    assert "λ ±1σ" not in _predict(tmp_path, capsys, without)
    assert "rate_prior_spread" not in json.loads(_predict(tmp_path, capsys, without, "--json"))


def test_the_interval_flies_the_spread_measured_about_the_pre_flight_law_not_the_priors(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """The gate kept the median λ (0.96) and the shape out: before release the plain law flies at λ = 1,
    and the flights' own λ miss it by 0.15 in ln λ (their scatter and the median's offset), not by the
    prior's 0.05 about its median. The interval is flown about λ = 1 with 0.15."""
    model = dataclasses.replace(
        _model(0.05), preflight=(DescentRateScale(scale=1.0),), preflight_spread=PreflightSpread(0.15, 30)
    )
    flown = json.loads(_predict(tmp_path, capsys, model, "--json"))
    spread = flown["rate_prior_spread"]
    assert spread["log_sigma"] == 0.15
    assert spread["rate_factor_slow"] == pytest.approx(math.exp(-0.15))
    assert spread["rate_factor_fast"] == pytest.approx(math.exp(0.15))
    assert spread["descent_s"]["slow"] == pytest.approx(flown["descent_s"] * math.exp(0.15), rel=2e-3)

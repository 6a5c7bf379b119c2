"""The pre-flight uncertainty a saved model states is measured on the law that flies before release.

Why: the pre-flight gate may keep every term and the median λ out of the pre-flight law (on every real
training set so far it did), and then a prediction before release shows the plain law. An ellipse and a
λ spread fitted on shape × median λ would describe another prediction than the one drawn. Five
synthetic flights of the plain law, each with its own λ (0.86–1.12) and its own wind error: nothing to
select, and the median λ does not beat λ = 1 beyond its interval, so the plain law flies pre-flight and
the model's ellipse and descent-time spread must be those of the plain law's own held-out landings
and descent times.
"""

from __future__ import annotations

import argparse
import dataclasses
from collections.abc import Callable
from pathlib import Path

import numpy as np
import pytest

from predictor.calibration.ellipse_fit import fit_parameters
from predictor.calibration.report import result_json
from predictor.calibration.residuals import FlightCase, residuals, run, score
from predictor.calibration.run import Inputs, analyse, calibrated_model
from predictor.calibration.selection import t_future
from predictor.descent.model import DescentRateScale
from predictor.descent.payload import PROFILES
from predictor.prediction import load_model, save_model

PAYLOAD = PROFILES["superbit-test"]
OWN_RATES = (0.86, 1.12, 0.93, 1.07, 0.97)


def test_with_nothing_passing_the_gate_the_saved_ellipse_and_spread_are_the_plain_laws(
    synthetic_cases: Callable[..., list[FlightCase]], tmp_path: Path
) -> None:
    cases = [
        dataclasses.replace(
            synthetic_cases((DescentRateScale(scale=rate),), n=1, seed=7 * k, wind_error_ms=4.0)[0],
            name=f"synthetic-{k}",
        )
        for k, rate in enumerate(OWN_RATES)
    ]
    inputs = Inputs(cases, [], PAYLOAD, "synthetic jets")
    args = argparse.Namespace(effects=["descent_rate_scale"], step=200.0, max_effects=3, seed=0)
    cal, ellipse = analyse(inputs, args)
    assert cal.preflight_terms() == (DescentRateScale(scale=1.0),), "the gate kept the median λ out"
    assert cal.rate_prior.median != pytest.approx(1.0, abs=0.01), "so shape × median λ is another law"

    plain = [residuals(c, run(c, PAYLOAD, (), 1, 200.0)) for c in cases]
    along, cross, drift = (np.array([getattr(r, k) for r in plain])
                           for k in ("landing_along_km", "landing_cross_km", "predicted_drift_km"))  # fmt: skip
    t = np.array([t_future(c) for c in cases])
    expected = fit_parameters(along, cross, drift, t)[0]
    # The λ each flight needed to land on time, about the flown λ = 1: predicted / measured descent time.
    needed = np.array([1.0 + float(score(c, run(c, PAYLOAD, (), 1, 200.0)).descent_time_error_s[0]) / c.descent_time_s
                       for c in cases])  # fmt: skip

    data = result_json(cal, ellipse, [], PAYLOAD.to_dict(), inputs.weather)
    path = save_model(calibrated_model(cal, ellipse, inputs, data, "drs calibrate …"), tmp_path / "m.json")
    model = load_model(path)
    assert model.ellipse is not None and model.preflight_spread is not None
    stated = (model.ellipse.sigma0_km, model.ellipse.h, model.ellipse.k_km2_per_h2, model.ellipse.q)
    assert stated == pytest.approx(tuple(expected), rel=1e-9)
    one_sigma = float(np.quantile(np.abs(np.log(needed)), 0.6827))
    assert model.preflight_spread.log_sigma == pytest.approx(one_sigma, rel=1e-3)
    assert model.preflight_spread.flights == len(cases)

    # What the model carried before: fitted on the held-out landings of the plain law × the others' median
    # λ, a law no prediction before release flies here; it is measurably another ellipse.
    old = np.array(
        [[r.landing_along_km, r.landing_cross_km, r.predicted_drift_km] for r in cal.after_residuals]
    )
    before = fit_parameters(old[:, 0], old[:, 1], old[:, 2], t)[0]
    assert not np.allclose(before, expected, rtol=1e-3)

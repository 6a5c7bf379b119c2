"""The landing-ellipse model fitted by the bivariate-normal likelihood, with held-out coverage."""

from __future__ import annotations

import numpy as np
import pytest

from predictor.calibration.ellipse_fit import PAPER_OBJECTIVE, _nll, fit_ellipse, fit_parameters
from predictor.errors import PredictorError

TRUE = (1.5, 1e-3, 0.02, 1.3)


def simulated(n: int, seed: int, lead_h: bool = True) -> tuple[np.ndarray, ...]:
    rng = np.random.default_rng(seed)
    d = rng.uniform(5.0, 80.0, n)
    t = rng.uniform(0.0, 12.0, n) if lead_h else np.zeros(n)
    sigma0, h, k, q = TRUE
    parallel = np.sqrt(sigma0**2 + h * d**2 + k * t**2)
    return rng.normal(0.0, parallel), rng.normal(0.0, parallel / q), d, t


def test_the_likelihood_gradient_is_exact() -> None:
    along, cross, d, t = simulated(20, 1)
    x = np.array([2.0, 5e-4, 0.01, 1.2])
    value, grad = _nll(x, along, cross, d, t)
    for i in range(4):
        step = np.zeros(4)
        step[i] = 1e-7 * max(abs(x[i]), 1e-3)
        numeric = (_nll(x + step, along, cross, d, t)[0] - _nll(x - step, along, cross, d, t)[0]) / (
            2 * step[i]
        )
        assert grad[i] == pytest.approx(numeric, rel=1e-4, abs=1e-6)


def test_the_fit_recovers_known_parameters_and_its_ellipses_hold_the_expected_share() -> None:
    fit = fit_ellipse(*simulated(240, 2))
    assert fit.sigma0_km == pytest.approx(TRUE[0], abs=3 * fit.stderr["sigma0_km"])
    assert fit.h == pytest.approx(TRUE[1], abs=3 * fit.stderr["h"])
    assert fit.k_km2_per_h2 == pytest.approx(TRUE[2], abs=3 * fit.stderr["k_km2_per_h2"])
    assert fit.q == pytest.approx(TRUE[3], abs=3 * fit.stderr["q"])
    assert fit.k_identifiable
    assert fit.coverage_1sigma == pytest.approx(0.393, abs=0.08)
    assert fit.coverage_2sigma == pytest.approx(0.865, abs=0.06)
    assert set(fit.paper) == {"launch", "hindsight", PAPER_OBJECTIVE}
    # The paper's criterion pulls σ towards the typical |error|: its ellipses hold too few landings.
    assert fit.paper[PAPER_OBJECTIVE]["coverage_2sigma"] < fit.coverage_2sigma - 0.05


def test_without_lead_times_k_is_not_identifiable_and_held_at_zero() -> None:
    along, cross, d, t = simulated(40, 3, lead_h=False)
    params, k_free = fit_parameters(along, cross, d, t)
    assert not k_free and params[2] == 0.0
    fit = fit_ellipse(along, cross, d, t)
    assert fit.to_dict()["k_identifiable"] is False and fit.k_km2_per_h2 == 0.0


def test_a_too_small_sample_is_refused() -> None:
    with pytest.raises(PredictorError, match="at least 4 flights, got 3"):
        fit_ellipse(np.ones(3), np.ones(3), np.ones(3), np.zeros(3))

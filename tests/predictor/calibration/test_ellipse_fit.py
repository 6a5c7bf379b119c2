"""The landing-ellipse model fitted by the bivariate-normal likelihood, with held-out coverage."""

from __future__ import annotations

import numpy as np
import pytest

from predictor.calibration.ellipse_fit import PAPER_OBJECTIVE, EllipseFit, _nll, fit_ellipse, fit_parameters
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


SEEDS = range(2, 10)
"""Eight independent samples of 240 flights: the claims below are checked on all 1,920 simulated
landings together, so no claim rests on one draw."""


@pytest.fixture(scope="module")
def fits() -> list[EllipseFit]:
    return [fit_ellipse(*simulated(240, seed)) for seed in SEEDS]


def test_the_fit_recovers_known_parameters(fits: list[EllipseFit]) -> None:
    """Each estimate lies within 4 bootstrap standard errors of the truth.

    False-failure rate: for a normal estimator P(|z| > 4) = 6.3e-5; over 8 samples × 4 parameters
    that is about 0.2 % (the bootstrap's own ±5 % error on the standard error is included in that
    margin: at |z| > 3.8 the rate would still be under 0.5 %).
    """
    for fit in fits:
        for name, truth in zip(("sigma0_km", "h", "k_km2_per_h2", "q"), TRUE, strict=True):
            z = (getattr(fit, name) - truth) / fit.stderr[name]
            assert abs(z) < 4.0, (
                f"{name}: {getattr(fit, name):.4g} vs true {truth} ({z:+.1f} standard errors)"
            )
        assert fit.k_identifiable
        assert set(fit.paper) == {"launch", "hindsight", PAPER_OBJECTIVE}


def test_held_out_ellipses_hold_the_bivariate_normal_share(fits: list[EllipseFit]) -> None:
    """Pooled held-out coverage over 1,920 landings: 39.3 % inside 1σ and 86.5 % inside 2σ.

    The binomial standard deviation of the pooled share is 1.1 points (1σ) and 0.78 points (2σ); the
    tolerances are 4.5 of them (false-failure rate < 1e-5 each), after allowing for the small known
    shortfall of held-out coverage when the parameters are themselves estimated.
    """
    one = np.mean([fit.coverage_1sigma for fit in fits])
    two = np.mean([fit.coverage_2sigma for fit in fits])
    assert one == pytest.approx(0.393, abs=0.05)
    assert two == pytest.approx(0.865, abs=0.035)


def test_the_papers_criterion_gives_ellipses_that_hold_too_few_landings(fits: list[EllipseFit]) -> None:
    """The paper's criterion pulls σ towards the typical |error| (≈ 0.8 σ): fewer landings inside.

    A normal with σ scaled by 0.8 puts 72 % inside its 2σ ellipse instead of 86.5 %. Measured over these
    samples the paired per-sample gap is 6 ± 2 points; the pooled gap's standard deviation over 8
    samples is about 0.7 points, so requiring more than 3 points is > 4 standard deviations from the
    measured mean (false-failure rate < 1e-4).
    """
    ours = np.mean([fit.coverage_2sigma for fit in fits])
    paper = np.mean([fit.paper[PAPER_OBJECTIVE]["coverage_2sigma"] for fit in fits])
    assert paper < ours - 0.03


def test_without_lead_times_k_is_not_identifiable_and_held_at_zero() -> None:
    along, cross, d, t = simulated(40, 3, lead_h=False)
    params, k_free = fit_parameters(along, cross, d, t)
    assert not k_free and params[2] == 0.0
    fit = fit_ellipse(along, cross, d, t)
    assert fit.to_dict()["k_identifiable"] is False and fit.k_km2_per_h2 == 0.0


def test_a_too_small_sample_is_refused() -> None:
    with pytest.raises(PredictorError, match="at least 4 flights, got 3"):
        fit_ellipse(np.ones(3), np.ones(3), np.ones(3), np.zeros(3))

"""The error ellipse: the paper's known answers, true 2-D coverages, and the ensemble fit."""

from __future__ import annotations

import math

import numpy as np
import pytest

from predictor import HINDSIGHT, LAUNCH, ErrorModel, PredictorError
from predictor.prediction.uncertainty import (
    GEOD,
    coverage,
    empirical_ellipse,
    n_sigma_for,
    parametric_ellipse,
)


def test_capsule_1_known_answer_from_the_paper() -> None:
    parallel, perpendicular = LAUNCH.sigmas_km(32.4, 9.2)
    assert 1.9 <= parallel <= 2.0
    assert perpendicular == pytest.approx(1.7, abs=0.05)


def test_capsule_2_known_answer_from_the_paper() -> None:
    parallel, perpendicular = LAUNCH.sigmas_km(18.6, 6.1)
    assert 1.8 <= parallel <= 1.9
    assert perpendicular == pytest.approx(1.6, abs=0.05)


def test_hindsight_parameters_are_the_papers() -> None:
    assert (HINDSIGHT.sigma0_km, HINDSIGHT.h, HINDSIGHT.k_km2_per_h2, HINDSIGHT.q) == (
        1.63,
        6.4e-4,
        3.3e-3,
        1.20,
    )
    parallel, perpendicular = HINDSIGHT.sigmas_km(0.0, 0.0)
    assert (parallel, perpendicular) == pytest.approx((1.63, 1.63 / 1.2))


def test_user_model_and_its_validation() -> None:
    model = ErrorModel(sigma0_km=1.0, h=0.0, k_km2_per_h2=0.0, q=2.0)
    assert model.sigmas_km(100.0, 100.0) == (1.0, 0.5)
    with pytest.raises(PredictorError, match="q > 0"):
        ErrorModel(sigma0_km=1.0, h=0.0, k_km2_per_h2=0.0, q=0.0)
    with pytest.raises(PredictorError, match="must be ≥ 0"):
        ErrorModel(sigma0_km=-1.0, h=0.0, k_km2_per_h2=0.0, q=1.0)


def test_contours_carry_true_two_dimensional_coverage() -> None:
    assert [round(coverage(n), 3) for n in (1, 2, 3)] == [0.393, 0.865, 0.989]
    ellipse = parametric_ellipse(LAUNCH, 32.4, 9.2, 45.0, 46.0, 7.0, probabilities=(0.5, 0.95, 0.99))
    probs = [round(c.probability, 3) for c in ellipse.contours]
    assert probs == [0.393, 0.865, 0.989, 0.5, 0.95, 0.99]
    for c in ellipse.contours:
        assert coverage(c.n_sigma) == pytest.approx(c.probability)
        assert c.semi_major_km == pytest.approx(c.n_sigma * ellipse.sigma_parallel_km)
        assert c.semi_minor_km == pytest.approx(c.n_sigma * ellipse.sigma_perpendicular_km)


def test_n_sigma_for_probability_and_its_bounds() -> None:
    assert n_sigma_for(0.95) == pytest.approx(math.sqrt(-2 * math.log(0.05)))
    for bad in (0.0, 1.0, 1.5, -0.1):
        with pytest.raises(PredictorError, match="strictly between 0 and 1"):
            n_sigma_for(bad)


def test_ellipse_outline_lies_at_n_sigma_along_and_across_the_bearing() -> None:
    ellipse = parametric_ellipse(LAUNCH, 32.4, 9.2, 60.0, -33.0, 151.0)
    contour = ellipse.contours[1]
    ring = ellipse.outline(contour, points=4)
    assert ring[0] == ring[-1]
    az, _, dist = GEOD.inv(151.0, -33.0, ring[0][0], ring[0][1])
    assert az % 360 == pytest.approx(60.0, abs=1e-6)
    assert dist / 1000 == pytest.approx(contour.semi_major_km, rel=1e-9)
    az, _, dist = GEOD.inv(151.0, -33.0, ring[1][0], ring[1][1])
    assert az % 360 == pytest.approx(150.0, abs=1e-6)
    assert dist / 1000 == pytest.approx(contour.semi_minor_km, rel=1e-9)


def test_q_below_one_puts_the_major_axis_across_the_bearing() -> None:
    model = ErrorModel(sigma0_km=1.333, h=3.07e-4, k_km2_per_h2=2.29e-3, q=0.983)
    ellipse = parametric_ellipse(model, 20.0, 5.0, 10.0, 0.0, 0.0)
    assert ellipse.major_axis_bearing_deg == pytest.approx(100.0)
    assert ellipse.contours[0].semi_major_km == pytest.approx(ellipse.sigma_perpendicular_km)


def test_empirical_ellipse_recovers_a_known_gaussian_rotated_to_the_bearing() -> None:
    rng = np.random.default_rng(1)
    bearing = 30.0
    along, across = rng.normal(0, 4.0, 20000), rng.normal(0, 1.5, 20000)
    b = math.radians(bearing)
    east = along * math.sin(b) + across * math.cos(b)
    north = along * math.cos(b) - across * math.sin(b)
    lat0, lon0 = 46.0, 179.9
    az = np.degrees(np.arctan2(east, north))
    lons, lats, _ = GEOD.fwd(
        np.full(east.size, lon0), np.full(east.size, lat0), az, np.hypot(east, north) * 1000
    )
    ellipse = empirical_ellipse(lats, lons, bearing)
    assert ellipse.sigma_parallel_km == pytest.approx(4.0, rel=0.03)
    assert ellipse.sigma_perpendicular_km == pytest.approx(1.5, rel=0.03)
    assert ellipse.major_axis_bearing_deg == pytest.approx(30.0, abs=1.0)
    assert abs(((ellipse.center_lon - lon0) + 180) % 360 - 180) < 0.01
    observed = [c.observed_fraction for c in ellipse.contours]
    assert observed == pytest.approx([0.393, 0.865, 0.989], abs=0.01)


def test_empirical_ellipse_needs_three_members() -> None:
    with pytest.raises(PredictorError, match="at least 3 members"):
        empirical_ellipse(np.array([1.0, 2.0]), np.array([1.0, 2.0]), 0.0)

"""The effects library: every candidate builds a real model term; fits find the grid objective's minimum."""

from __future__ import annotations

import numpy as np
import pytest

from predictor.calibration.effects import LIBRARY, Candidate, fit_binned, library
from predictor.calibration.residuals import BinBudget
from predictor.descent.model import EFFECTS, FAMILIES, WindBandScale
from predictor.errors import PredictorError


@pytest.mark.parametrize("candidate", LIBRARY, ids=[c.name for c in LIBRARY])
def test_every_candidate_is_a_model_term_with_its_neutral_value_inside_grid_and_bounds(
    candidate: Candidate,
) -> None:
    assert candidate.name in EFFECTS and candidate.family in FAMILIES
    assert candidate.family == EFFECTS[candidate.name].family
    lo, hi = candidate.bounds
    assert lo <= min(candidate.grid) and max(candidate.grid) <= hi
    assert min(candidate.grid) <= candidate.neutral <= max(candidate.grid)
    term = candidate.term(0, candidate.neutral)
    assert isinstance(term, EFFECTS[candidate.name])


def test_the_library_covers_the_three_families_and_every_named_effect() -> None:
    names = {c.name for c in LIBRARY}
    assert names == {
        "descent_rate_scale", "drag_density_exponent", "deployment_delay", "wind_scale", "wind_rotation",
        "wind_band_scale", "wind_lag", "weather_time_offset", "two_regime_rate",
    }  # fmt: skip
    assert {c.family for c in LIBRARY} == {"vertical", "horizontal", "timing"}


def test_a_fit_finds_a_minimum_between_grid_values() -> None:
    candidate = library(["descent_rate_scale"])[0]
    grid = np.asarray(candidate.grid)
    variant, value, best = candidate.fit((grid - 1.234) ** 2 + 0.5)
    assert variant == 0 and value == pytest.approx(1.234, abs=1e-3) and best == pytest.approx(0.5, abs=1e-4)


def test_a_fit_picks_the_best_variant_and_ignores_failed_runs() -> None:
    band = library(["wind_band_scale"])[0]
    objective = np.full(len(band.points()), 5.0)
    objective[0] = np.nan
    best_variant = 3
    for k, (v, x) in enumerate(band.points()):
        if v == best_variant:
            objective[k] = (x - 1.5) ** 2
    variant, value, _ = band.fit(objective)
    assert variant == best_variant and value == pytest.approx(1.5, abs=0.01)
    assert band.parameters(variant, value) == {
        "bottom_m": 9000.0,
        "top_m": 15000.0,
        "scale": pytest.approx(1.5, abs=0.01),
    }


def test_a_refined_height_is_found_between_the_coarse_heights_along_a_diagonal_valley() -> None:
    """The two-regime canopy's height and factor trade off (a higher break, a larger factor): an
    objective with its minimum at 19.4 km × 1.23 along such a valley. The coarse grid alone gives a
    height on the 3 km grid; the fine pass gives the minimum (to the spline's error, ≪ the coarse step)."""
    two = library(["two_regime_rate"])[0]

    def valley(height_m: float, factor: float) -> float:
        along = (height_m - 19_400.0) / 1000.0
        across = factor - (1.23 + 0.12 * along)
        return 0.05 * along**2 + 40.0 * across**2 + 0.2

    coarse = np.array([valley(two.variants[v]["height_m"], x) for v, x in two.points()])
    variant, value, _ = two.fit(coarse)
    assert two.variants[variant]["height_m"] in (18_000.0, 21_000.0)
    fine = two.fine(variant, value)
    coarse_height = two.variants[variant]["height_m"]
    heights = [v["height_m"] for v in fine.variants]
    assert heights == pytest.approx(list(np.arange(coarse_height - 3000.0, coarse_height + 3001.0, 1000.0)))
    table = np.array([valley(fine.variants[v]["height_m"], x) for v, x in fine.points()])
    height, factor, best = fine.fit_refined(table)
    assert height == pytest.approx(19_400.0, abs=50.0) and factor == pytest.approx(1.23, abs=0.005)
    assert best == pytest.approx(0.2, abs=0.01)
    assert two.parameters(variant, factor, height) == {"height_m": height, "factor": factor}
    term = two.term(np.array([variant, variant]), np.array([1.2, 1.3]), np.array([19_000.0, 19_500.0]))
    assert list(term.height_m) == [19_000.0, 19_500.0] and list(term.factor) == [1.2, 1.3]


def test_an_effect_the_data_cannot_see_is_reported_at_its_neutral_value() -> None:
    offset = library(["weather_time_offset"])[0]
    assert offset.fit(np.full(len(offset.grid), 2.0))[1] == 0.0


def test_terms_take_one_parameter_value_per_trajectory() -> None:
    band = library(["wind_band_scale"])[0]
    term = band.term(np.array([0, 2]), np.array([0.5, 1.5]))
    assert isinstance(term, WindBandScale)
    assert list(term.bottom_m) == [0.0, 6000.0] and list(term.top_m) == [6000.0, 12000.0]
    assert list(term.scale) == [0.5, 1.5]


def test_an_unknown_effect_is_refused_with_the_library_named() -> None:
    with pytest.raises(PredictorError, match="unknown effect.*wind_shear.*descent_rate_scale"):
        library(["wind_shear"])


def test_the_binned_correction_matches_measured_bin_times_and_leaves_unmeasured_bins_alone() -> None:
    budget = BinBudget(
        measured_s=np.array([125.0, 25.0, 0.0]),
        predicted_s=np.array([100.0, 20.0, 0.0]),
        measured_east_m=np.array([1250.0, 0.0, 0.0]),
        measured_north_m=np.array([-250.0, 0.0, 0.0]),
        predicted_east_ms=np.array([8.0, 1.0, 0.0]),
        predicted_north_ms=np.array([0.0, 0.0, 0.0]),
    )
    corr = fit_binned([budget, budget], edges_m=(0.0, 3000.0, 6000.0, 9000.0))
    assert corr.rate_factor == pytest.approx((0.8, 1.0, 1.0))
    assert corr.east_ms == pytest.approx((2.0, 0.0, 0.0))
    assert corr.north_ms == pytest.approx((-2.0, 0.0, 0.0))
    assert corr.measured_s == pytest.approx((250.0, 50.0, 0.0))
    assert [t.name for t in corr.terms()] == ["binned_descent_rate", "binned_wind"]

"""The margin: a held-out improvement counts only when it is larger than the flight-to-flight noise."""

from __future__ import annotations

from collections.abc import Callable

import numpy as np
import pytest

from predictor.calibration.effects import Candidate, library
from predictor.calibration.residuals import FlightCase
from predictor.calibration.selection import HORIZONTAL, VERTICAL, calibrate, paired_test
from predictor.descent.model import WindScale
from predictor.descent.payload import PROFILES
from predictor.errors import PredictorError


def test_an_improvement_on_every_flight_passes() -> None:
    before = np.array([3.0, 2.5, 4.0, 1.8, 2.2, 3.3])
    test = paired_test(before, before - 0.5, alpha=0.05, seed=0, floor=HORIZONTAL.floor)
    assert test.passed and test.wins == 6 and test.mean_improvement == pytest.approx(0.5)


def test_a_mean_improvement_carried_by_one_lucky_flight_does_not_pass() -> None:
    before = np.full(10, 3.0)
    after = before.copy()
    after[0] = 0.0  # one flight 3 km better, the other nine unchanged
    after[1:] += np.linspace(-0.05, 0.05, 9)
    test = paired_test(before, after, alpha=0.05, seed=0, floor=HORIZONTAL.floor)
    assert test.mean_improvement > HORIZONTAL.floor and not test.passed
    assert test.margin > test.mean_improvement


def test_noise_around_zero_does_not_pass_and_the_margin_is_reported() -> None:
    rng = np.random.default_rng(4)
    before = rng.uniform(1.0, 5.0, 30)
    test = paired_test(before, before + rng.normal(0.0, 0.3, 30), alpha=0.05, seed=1, floor=HORIZONTAL.floor)
    assert not test.passed and test.margin > 0.05
    assert test.to_dict()["flights"] == 30


def test_a_consistent_but_tiny_improvement_is_below_the_practical_floor() -> None:
    before = np.array([3.0, 2.5, 4.0, 1.8])
    test = paired_test(before, before - 0.01, alpha=0.05, seed=0, floor=HORIZONTAL.floor)
    assert test.lower_bound > 0.0 and not test.passed


def test_a_failed_run_on_any_flight_cannot_pass() -> None:
    before = np.array([3.0, 2.5, 4.0, 1.8])
    assert not paired_test(
        before, np.array([1.0, 1.0, np.nan, 1.0]), alpha=0.05, seed=0, floor=HORIZONTAL.floor
    ).passed


def test_leave_one_out_needs_three_flights(plain_cases: list[FlightCase]) -> None:
    with pytest.raises(PredictorError, match="at least 3 usable flights, got 2"):
        calibrate(plain_cases[:2], PROFILES["superbit-test"], library(["wind_scale"]))


def test_every_fold_is_fitted_without_its_own_flight(
    synthetic_cases: Callable[..., list[FlightCase]], plain_cases: list[FlightCase]
) -> None:
    """Only flight 0 has a 1.5× wind: the fold that holds it out must not see it, every other fold must."""
    cases = [*synthetic_cases((WindScale(scale=1.5),), n=1), *plain_cases[1:4]]
    payload = PROFILES["superbit-test"]
    assert calibrate(cases, payload, library(["wind_scale"]), max_effects=0).rounds == ()
    result = calibrate(cases, payload, library(["wind_scale"])).rounds[0][0]
    assert result.folds[0].value == pytest.approx(1.0, abs=0.01)
    assert all(f.value > 1.02 for f in result.folds[1:])
    assert 1.02 < result.full.value < 1.5


def test_each_family_has_its_record_and_floor() -> None:
    """Vertical effects on the shape record (time at altitude, each flight's λ profiled out), horizontal ones
    on the replayed horizontal one."""
    assert (VERTICAL.metric, VERTICAL.unit, VERTICAL.replay) == ("shape_time_rms_s", "s", False)
    assert (HORIZONTAL.metric, HORIZONTAL.unit, HORIZONTAL.replay) == ("horizontal_rms_km", "km", True)
    before = np.array([130.0, 95.0, 240.0, 180.0])
    assert paired_test(
        before, before - 12.0, alpha=0.05, seed=0, floor=VERTICAL.floor, record=VERTICAL
    ).passed
    assert not paired_test(before, before - 8.0, alpha=0.05, seed=0, floor=VERTICAL.floor).passed


def test_an_unknown_family_is_refused(plain_cases: list[FlightCase]) -> None:
    odd = Candidate("wind_scale", "sideways", "scale", (0.9, 1.0, 1.1), 1.0)
    with pytest.raises(PredictorError, match="unknown effect family sideways"):
        calibrate(plain_cases, PROFILES["superbit-test"], (odd,))


def _heldout(shape_s: np.ndarray):  # noqa: ANN202
    from predictor.calibration.selection import HeldOut

    n = shape_s.size
    zeros = np.zeros(n)
    return HeldOut(zeros, shape_s, shape_s, np.ones(n), zeros, zeros, zeros, zeros, zeros, zeros, zeros)


def _result(name: str, before: np.ndarray, improvement: np.ndarray):  # noqa: ANN202
    from predictor.calibration.selection import CandidateResult, Fit, _tests

    candidate = next(c for c in library() if c.name == name)
    heldout = _heldout(before - improvement)
    tests = _tests((VERTICAL,), _heldout(before), heldout, 0.05 / 2, 0)
    return CandidateResult(1, Fit(candidate, 0, 0.0), (), heldout, tests)


def test_a_term_that_passes_on_the_knife_edge_of_the_floor_is_chosen_in_half_the_folds() -> None:
    """Improvements 19 s on five flights and 1 s on five: the mean is the 10 s floor exactly, so it is
    selected; without one of the 19 s flights it falls to 9 s and fails, without a 1 s one it rises to
    11 s: chosen in 5 of 10 folds, under two thirds, flagged. A term that helps every flight by 20 s
    beside it is chosen in every fold where it ranks first."""
    from predictor.calibration.selection import STABLE_SHARE, decision_stability

    before = np.full(10, 60.0)
    edge = _result("drag_density_exponent", before, np.array([19.0] * 5 + [1.0] * 5))
    assert edge.passed
    assert decision_stability(((edge,),), (_heldout(before), edge.heldout), 0.05, 0) == {
        "drag_density_exponent": 0.5
    }
    assert 0.5 < STABLE_SHARE
    solid = _result("two_regime_rate", before, np.full(10, 20.0))
    shares = decision_stability(((edge, solid),), (_heldout(before), solid.heldout), 0.05, 0)
    assert shares == {"two_regime_rate": 1.0}

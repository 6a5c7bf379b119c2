"""A calibrated model's law refitted without each flight: what `drs live evaluate` flies on that flight."""

from __future__ import annotations

import pytest

from predictor.calibration.residuals import FlightCase
from predictor.calibration.selection import refit_without_each
from predictor.descent.model import BinnedDescentRate, DragDensityExponent, WindOffset
from predictor.descent.payload import PROFILES
from predictor.errors import PredictorError
from tests.predictor.calibration.conftest import make_cases

PAYLOAD = PROFILES["superbit-test"]
EXPONENTS = (0.05, 0.12, 0.2, 0.3)


@pytest.fixture(scope="module")
def cases() -> list[FlightCase]:
    """Four flights, each falling with its own density exponent, so that every fold's fit differs."""
    return [make_cases((DragDensityExponent(exponent=x),), n=1, seed=k)[0] for k, x in enumerate(EXPONENTS)]


def test_each_fold_is_the_fit_on_the_other_flights_alone(cases: list[FlightCase]) -> None:
    full, folds = refit_without_each(cases, PAYLOAD, (DragDensityExponent(exponent=0.1),))
    exponents = [terms[0].exponent for terms in folds]
    for i, terms in enumerate(folds):
        alone, _ = refit_without_each(
            cases[:i] + cases[i + 1 :], PAYLOAD, (DragDensityExponent(exponent=0.1),)
        )
        # A fold's losses are the other flights' only; the one thing all the flights set is where the
        # fine grid lies (around the all-flights optimum, ``selection._fit``), which moves the spline's
        # optimum a little: 2e-4 here, against 0.02–0.05 from one fold to the next.
        assert terms[0].exponent == pytest.approx(alone[0].exponent, abs=1e-3), f"fold {i} saw its own flight"
    # Leaving out the steepest flight gives the flattest law, and the reverse.
    assert exponents.index(min(exponents)) == EXPONENTS.index(max(EXPONENTS))
    assert exponents.index(max(exponents)) == EXPONENTS.index(min(EXPONENTS))
    assert min(exponents) < full[0].exponent < max(exponents)


def test_the_binned_parts_a_model_keeps_are_refitted_per_fold_too(cases: list[FlightCase]) -> None:
    model = (DragDensityExponent(exponent=0.1), BinnedDescentRate(edges_m=(0.0, 40000.0), factors=(1.0,)))
    full, folds = refit_without_each(cases, PAYLOAD, model)
    assert [t.name for t in full] == ["drag_density_exponent", "binned_descent_rate"]
    assert all([t.name for t in terms] == [t.name for t in full] for terms in folds)
    assert len({terms[1].factors for terms in folds}) == len(cases), (
        "each fold's bins come from its own flights"
    )


def test_a_term_the_calibration_cannot_fit_is_refused(cases: list[FlightCase]) -> None:
    with pytest.raises(PredictorError, match="cannot refit wind_offset: not a library effect"):
        refit_without_each(cases, PAYLOAD, (WindOffset(east_ms=1.0, north_ms=0.0),))

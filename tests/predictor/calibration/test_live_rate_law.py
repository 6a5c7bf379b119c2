"""The λ table a live evaluation measures (``rate_law``): prior and departure by height, and the
conservative default pooled from several payloads (``conservative_discrepancy``)."""

from __future__ import annotations

import math

import pytest

from predictor.calibration.live_evaluation import _Sample, _Survey, conservative_discrepancy, rate_law
from predictor.prediction.live import RateDiscrepancy


def survey_just_below_the_top() -> _Survey:
    # Four flights. At 26 km (just below their tops) none has a record λ yet, only the remaining
    # descent's; the record first says something at 22.9 km (over 3 km below), 12–15 % faster than the rest.
    samples = []
    for i, remaining in enumerate((-0.10, 0.0, 0.05, 0.15)):
        name = f"f{i}"
        samples.append(_Sample(name, 26000.0, None, remaining))
        samples.append(_Sample(name, 23500.0, None, remaining))
        samples.append(_Sample(name, 22900.0, remaining + 0.12 + 0.01 * i, remaining))
    return _Survey({f"f{i}": 0.0 for i in range(4)}, samples)


def test_a_height_the_record_does_not_reach_yet_keeps_its_prior_and_borrows_the_nearest_departure() -> None:
    _, table = rate_law(survey_just_below_the_top())
    assert 26.0 in table.heights_km and 23.5 in table.heights_km
    high, low = table.heights_km.index(26.0), table.heights_km.index(23.5)
    # The remaining λ is measured at 26 km from every flight, with or without a record there.
    assert table.remaining_flights[high] == 4
    assert table.remaining_log_mean[high] == pytest.approx(0.025, abs=1e-5)
    # The departure is the record's first measurement below (median of 0.12–0.15), carried up.
    assert table.log_bias[low] == pytest.approx(0.135, abs=1e-5)
    assert table.log_bias[high] == table.log_bias[low] and table.log_sigma[high] == table.log_sigma[low]


def test_the_prior_of_the_rest_is_the_law_as_wide_as_the_flights_were_from_it() -> None:
    _, table = rate_law(survey_just_below_the_top())
    prior = table.remaining_prior(26.0)
    assert prior is not None and prior.median == 1.0
    sigma = table.remaining_log_sigma[table.heights_km.index(26.0)]
    assert prior.log_sigma == pytest.approx(math.hypot(0.025, sigma), rel=1e-4)


def test_the_default_of_several_payloads_is_the_widest_of_them_at_every_height() -> None:
    narrow = RateDiscrepancy((5.0, 20.0), (0.02, -0.03), (0.05, 0.06), (0.0, 0.1), (0.1, 0.1), (30, 30))
    wide = RateDiscrepancy((5.0, 20.0), (0.2, 0.0), (0.05, 0.2), (0.3, 0.0), (0.1, 0.1), (5, 5))
    pooled = conservative_discrepancy([narrow, wide])
    assert pooled.log_bias == (0.0, 0.0) and pooled.remaining_log_mean == (0.0, 0.0)
    assert pooled.log_sigma == (round(math.hypot(0.2, 0.05), 3), 0.2)
    assert pooled.remaining_log_sigma == (round(math.hypot(0.3, 0.1), 3), round(math.hypot(0.1, 0.1), 3))
    assert pooled.remaining_flights == (5, 5)

"""The standard profile's ascent: a constant rate, carried by the wind of the cube."""

from __future__ import annotations

from datetime import timedelta

import numpy as np
import pytest

from predictor.errors import OutOfCoverageError, PredictorError
from predictor.prediction.uncertainty import GEOD
from predictor.tawhiri.ascent import ascend
from tests.predictor.predict_helpers import RELEASE, isothermal_cube


def test_a_uniform_wind_carries_the_ascent_rate_times_the_time() -> None:
    ascent = ascend(isothermal_cube(u=10.0, v=-4.0), RELEASE, 45.0, 2.0, 100.0, 5.0, 30100.0)
    burst = ascent.burst
    assert burst.time == RELEASE + timedelta(seconds=6000)
    assert burst.alt_m == 30100.0
    assert np.all(np.diff(ascent.alt_m) > 0) and np.allclose(np.diff(ascent.t_s), 60.0)
    azimuth, _, distance = GEOD.inv(2.0, 45.0, burst.lon, burst.lat)
    assert distance == pytest.approx(np.hypot(10.0, 4.0) * 6000.0, rel=5e-3)
    assert azimuth == pytest.approx(np.degrees(np.arctan2(10.0, -4.0)), abs=0.3)


def test_an_ascent_that_leaves_the_weather_says_where() -> None:
    with pytest.raises(OutOfCoverageError, match="the ascent leaves the weather region"):
        ascend(isothermal_cube(u=60.0), RELEASE, 45.0, 11.5, 0.0, 2.0, 30000.0)


@pytest.mark.parametrize(
    ("rate", "burst", "says"), [(0.0, 30000.0, "ascent rate"), (5.0, 50.0, "burst altitude")]
)
def test_a_rate_or_burst_that_cannot_rise_is_refused(rate: float, burst: float, says: str) -> None:
    with pytest.raises(PredictorError, match=says):
        ascend(isothermal_cube(), RELEASE, 45.0, 2.0, 100.0, rate, burst)

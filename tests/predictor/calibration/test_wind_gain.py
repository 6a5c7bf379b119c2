"""The wind gain: how much of the measured wind error its training flights' landings wanted carried down."""

from __future__ import annotations

import math

import numpy as np
import pytest

from predictor.calibration.wind_gain import GainSample, fit_gain, gain_sample, gained, local_km
from predictor.prediction.uncertainty import GEOD


def flights(carried: float, seed: int, n: int = 20, noise_km: float = 1.0) -> list[GainSample]:
    """``n`` flights whose wind correction displaces the landing by D (a few km, any direction) and
    whose landing without it misses by ``carried`` × D plus an independent miss of ``noise_km`` rms."""
    rng = np.random.default_rng(seed)
    d = rng.normal(0.0, 2.0, (n, 2))
    m = carried * d + rng.normal(0.0, noise_km, (n, 2))
    return [
        GainSample((float(a), float(b)), (float(c), float(e))) for (a, b), (c, e) in zip(m, d, strict=True)
    ]


def test_a_measured_error_that_does_not_carry_to_the_ground_gets_no_gain() -> None:
    # The hard worlds' case: the error measured above says nothing of the fall below (the landing miss
    # is independent of the displacement the correction adds). Over seeds the shrunk gain is 0 on most
    # draws and small on the rest, where the least-squares slope alone wanders by ±0.2.
    fits = [fit_gain(flights(0.0, seed)) for seed in range(20)]
    assert np.mean([f.gain == 0.0 for f in fits]) >= 0.7
    assert max(f.gain for f in fits) < 0.35
    assert max(abs(f.raw) for f in fits) > max(f.gain for f in fits), "shrinking moved it toward 0"


def test_a_measured_error_that_carries_gets_all_of_it() -> None:
    # The real flights' case: the miss without the correction is the displacement it adds.
    for seed in range(10):
        fit = fit_gain(flights(1.0, seed))
        assert fit.raw == pytest.approx(1.0, abs=0.2)
        assert fit.gain >= 0.85
        assert fit.sigma < 0.15 and fit.flights == 20


def test_half_an_error_carried_gives_about_half_and_the_gain_stays_within_0_and_1() -> None:
    assert fit_gain(flights(0.5, 3, n=200, noise_km=0.5)).gain == pytest.approx(0.5, abs=0.05)
    assert fit_gain(flights(2.0, 4, noise_km=0.1)).gain == 1.0, "never more than all of the error"
    against = fit_gain(flights(-1.0, 5, noise_km=0.1)).gain
    assert against == 0.0 and math.copysign(1.0, against) == 1.0, (
        "never against the measured error (nor -0.0)"
    )


def test_too_few_flights_with_a_displacement_give_no_gain() -> None:
    one = [GainSample((3.0, 1.0), (3.0, 1.0)), GainSample((2.0, -1.0), (0.0, 0.0))]
    fit = fit_gain(one)
    assert (fit.gain, fit.flights) == (0.0, 1) and math.isinf(fit.sigma)
    assert fit_gain([]).gain == 0.0


def test_the_gained_landing_is_that_share_of_the_way_and_the_sample_is_in_km() -> None:
    without, with_wind = (46.0, 6.0), (46.03, 6.04)
    assert gained(*without, *with_wind, 0.0) == pytest.approx(without)
    assert gained(*without, *with_wind, 1.0) == pytest.approx(with_wind)
    half = gained(*without, *with_wind, 0.5)
    whole = GEOD.inv(without[1], without[0], with_wind[1], with_wind[0])[2]
    assert GEOD.inv(without[1], without[0], half[1], half[0])[2] == pytest.approx(0.5 * whole, rel=1e-6)
    assert np.hypot(*local_km(*without, *with_wind)) == pytest.approx(whole / 1000.0)
    s = gain_sample(without, with_wind, with_wind)
    assert s.miss_km == pytest.approx(s.displacement_km), "a truth where the whole correction lands"
    assert fit_gain([s, gain_sample(without, (46.0, 6.05), (46.0, 6.05))]).raw == pytest.approx(1.0)

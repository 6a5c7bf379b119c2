"""predict_ensemble(): member spread against its closed form, GEFS-style members, errors."""

from __future__ import annotations

from datetime import timedelta

import numpy as np
import pytest

from predictor import (
    Model,
    OutOfCoverageError,
    Payload,
    PredictorError,
    predict,
    predict_ensemble,
    predict_landings,
)
from predictor.descent import Release
from predictor.descent.model import DescentRateScale
from predictor.prediction import EnsembleSpread, FlightSetup
from predictor.prediction.uncertainty import GEOD
from tests.predictor.predict_helpers import RELEASE, isothermal_cube

PAYLOAD = Payload(mass_kg=1.029, cda_m2=1.13)


def test_member_spread_matches_the_perturbations_closed_form() -> None:
    # Constant wind u, fall time T: a wind error σw moves a member σw·T each way; a rate factor
    # e^ε (ε ~ N(0, σr)) changes the fall time to T·e^−ε, so the along-wind spread is ≈ u·T·σr.
    u, sigma_w, sigma_r = 10.0, 1.0, 0.05
    cube = isothermal_cube(u=u)
    ens = predict_ensemble(
        cube,
        Release(RELEASE, 46.0, 5.0, 30000.0),
        FlightSetup(PAYLOAD),
        EnsembleSpread(members=2000, seed=3, rate_sigma=sigma_r, wind_sigma_ms=sigma_w),
    )  # fmt: skip
    fall_km = ens.central.descent_s / 1000.0
    expected_along = np.hypot(sigma_w * fall_km, u * fall_km * sigma_r)
    assert ens.empirical.sigma_parallel_km == pytest.approx(expected_along, rel=0.06)
    assert ens.empirical.sigma_perpendicular_km == pytest.approx(sigma_w * fall_km, rel=0.06)
    assert ens.empirical.bearing_deg == pytest.approx(90.0, abs=0.2)
    assert np.std(ens.member_descent_s) / ens.central.descent_s == pytest.approx(sigma_r, rel=0.08)
    observed = [c.observed_fraction for c in ens.empirical.contours]
    assert observed == pytest.approx([0.393, 0.865, 0.989], abs=0.04)


def test_ensemble_mean_lands_near_the_central_prediction_and_beside_the_parametric_ellipse() -> None:
    ens = predict_ensemble(
        isothermal_cube(u=10.0),
        Release(RELEASE, 46.0, 5.0, 30000.0),
        FlightSetup(PAYLOAD),
        EnsembleSpread(members=500, seed=1),
    )
    _, _, gap = GEOD.inv(
        ens.central.landing.lon, ens.central.landing.lat, ens.empirical.center_lon, ens.empirical.center_lat
    )
    assert gap < 0.2 * ens.empirical.sigma_major_km * 1000.0 + 200.0
    assert ens.central.ellipse.kind.startswith("parametric")
    assert ens.empirical.kind.startswith("empirical")
    doc = ens.to_dict()
    assert doc["ensemble"]["members"] == 500
    assert len(doc["ensemble"]["landings"]) == 500
    assert doc["ellipse"]["sigma_parallel_km"] == ens.central.ellipse.sigma_parallel_km
    assert doc["ensemble"]["empirical_ellipse"]["contours"][0]["observed_fraction"] > 0.3


def test_same_seed_same_members_and_another_seed_differs() -> None:
    cube = isothermal_cube(u=10.0)
    a = predict_ensemble(
        cube, Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD), EnsembleSpread(members=50, seed=7)
    )
    b = predict_ensemble(
        cube, Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD), EnsembleSpread(members=50, seed=7)
    )
    c = predict_ensemble(
        cube, Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD), EnsembleSpread(members=50, seed=8)
    )
    assert np.array_equal(a.member_lon, b.member_lon)
    assert not np.array_equal(a.member_lon, c.member_lon)


def test_one_member_per_weather_cube_reproduces_each_cubes_own_prediction() -> None:
    cubes = [isothermal_cube(u=u, v=v) for u, v in ((5.0, 0.0), (8.0, 2.0), (11.0, -3.0), (6.0, 1.0))]
    ens = predict_ensemble(cubes, Release(RELEASE, 46.0, 4.0, 30000.0), FlightSetup(PAYLOAD))
    assert ens.members == 4
    for cube, lat, lon in zip(cubes, ens.member_lat, ens.member_lon, strict=True):
        single = predict(cube, Release(RELEASE, 46.0, 4.0, 30000.0), FlightSetup(PAYLOAD))
        assert (lat, lon) == pytest.approx((single.landing.lat, single.landing.lon), abs=1e-12)
    assert ens.perturbations["kind"] == "one member per weather cube"


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"members": 2}, "at least 3 members"),
        ({"rate_sigma": -0.1}, "spreads must be finite"),
        ({"wind_sigma_ms": float("nan")}, "spreads must be finite"),
    ],
)
def test_bad_ensemble_requests_are_refused(kwargs: dict, message: str) -> None:
    with pytest.raises(PredictorError, match=message):
        predict_ensemble(
            isothermal_cube(),
            Release(RELEASE, 46.0, 5.0, 30000.0),
            FlightSetup(PAYLOAD),
            EnsembleSpread(**kwargs),
        )


def test_two_weather_cubes_are_too_few_for_an_ensemble() -> None:
    with pytest.raises(PredictorError, match="at least 3 of them"):
        predict_ensemble(
            [isothermal_cube(), isothermal_cube()], Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD)
        )


def test_vectorised_sweep_gives_the_same_landings_as_single_predictions() -> None:
    # 8 release times × 25 descent-rate factors in one call (enough trajectories per thread block for
    # the stepper to share column interpolations between them), against single predictions.
    cube = isothermal_cube(u=lambda t, z, y, x: 8.0 + 0.5 * t + 0.2 * (x - 5.0), v=3.0)
    times = [RELEASE + timedelta(minutes=m) for m in range(0, 80, 10)] * 25
    rates = np.repeat(np.linspace(0.8, 1.2, 25), 8)
    model = Model.for_payload(PAYLOAD, DescentRateScale(scale=rates))
    sweep = predict_landings(cube, times, 46.0, 5.0, 30000.0, model=model)
    for i in range(0, 200, 13):
        single = predict(
            cube,
            Release(times[i], 46.0, 5.0, 30000.0),
            FlightSetup(PAYLOAD, effects=(DescentRateScale(scale=rates[i]),)),
        )
        assert sweep.lat[i] == pytest.approx(single.landing.lat, abs=1e-12)
        assert sweep.lon[i] == pytest.approx(single.landing.lon, abs=1e-12)
        assert sweep.descent_s[i] == pytest.approx(single.descent_s, abs=1e-6)
        assert sweep.drift_km[i] == pytest.approx(single.drift_km, rel=1e-9)
        landing = np.datetime64(single.landing.time.replace(tzinfo=None), "us")
        assert abs(sweep.time[i] - landing) <= np.timedelta64(1, "ms")


def test_vectorised_sweep_refuses_bad_inputs() -> None:
    model = Model.for_payload(PAYLOAD)
    with pytest.raises(PredictorError, match="every latitude"):
        predict_landings(isothermal_cube(), [RELEASE], np.array([46.0, 95.0]), 5.0, 30000.0, model=model)
    with pytest.raises(PredictorError, match="timezone-aware"):
        predict_landings(isothermal_cube(), [RELEASE.replace(tzinfo=None)], 46.0, 5.0, 30000.0, model=model)


def test_members_leaving_the_region_name_where_they_left() -> None:
    # The calm central descent stays inside; members with 20 m/s wind errors leave the 1° box.
    cube = isothermal_cube(lats=np.arange(45.0, 47.01, 1.0), lons=np.arange(5.0, 7.01, 1.0))
    with pytest.raises(
        OutOfCoverageError, match=r"descent leaves the weather region \(lat 45…47, lon 5…7 °E\) at"
    ):
        predict_ensemble(
            cube,
            Release(RELEASE, 46.0, 6.0, 30000.0),
            FlightSetup(PAYLOAD),
            EnsembleSpread(members=50, wind_sigma_ms=20.0),
        )

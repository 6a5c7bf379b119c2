"""The stepper against closed-form descents and around the places pyBalloon broke."""

from __future__ import annotations

import math
from datetime import timedelta

import numpy as np
import pytest
from hypothesis import given, settings, strategies as st
from scipy.integrate import quad

from predictor import OutOfCoverageError, Payload, WeatherCube, predict
from predictor.descent import Release
from predictor.prediction import FlightSetup
from predictor.prediction.uncertainty import GEOD
from tests.predictor.predict_helpers import (
    G0,
    H_ISO,
    R_GRAVITY,
    RELEASE,
    RHO0,
    closed_form_fall_time,
    isothermal_cube,
)

PAYLOAD = Payload(mass_kg=1.029, cda_m2=1.13)
WGS84_A = 6378137.0
WGS84_E2 = 6.69437999014e-3


def fall_speed(z: float, mass: float = PAYLOAD.mass_kg, cda: float = PAYLOAD.cda_m2) -> float:
    g = G0 * (R_GRAVITY / (R_GRAVITY + z)) ** 2
    return math.sqrt(2 * mass * g / (RHO0 * math.exp(-z / H_ISO) * cda))


def test_isothermal_fall_time_matches_the_closed_form() -> None:
    cube = isothermal_cube()
    res = predict(cube, Release(RELEASE, 46.0, 6.0, 30000.0), FlightSetup(PAYLOAD))
    expected = closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, 30000.0)
    assert res.descent_s == pytest.approx(expected, rel=1e-5)
    assert res.landing.alt_m == pytest.approx(0.0, abs=1e-6)
    assert res.drift_km == pytest.approx(0.0, abs=1e-6)


def test_fall_time_from_an_altitude_off_the_step_grid() -> None:
    res = predict(isothermal_cube(), Release(RELEASE, 46.0, 6.0, 27345.6), FlightSetup(PAYLOAD, step_m=100.0))
    assert res.descent_s == pytest.approx(
        closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, 27345.6), rel=1e-5
    )


def test_constant_wind_drift_is_wind_times_fall_time_on_the_ground() -> None:
    u = 12.0
    lat = 46.0
    res = predict(isothermal_cube(u=u), Release(RELEASE, lat, 3.0, 30000.0), FlightSetup(PAYLOAD))
    s = math.sin(math.radians(lat))
    normal = WGS84_A / math.sqrt(1 - WGS84_E2 * s * s)
    # Eastward metres at altitude z shrink to N/(N+z) on the ground: quadrature independent of the stepper.
    ground_m, _ = quad(lambda z: u * normal / (normal + z) / fall_speed(z), 0.0, 30000.0, limit=200)
    along_parallel_deg = math.degrees(ground_m / (normal * math.cos(math.radians(lat))))
    assert res.landing.lon - 3.0 == pytest.approx(along_parallel_deg, rel=2e-4)
    assert res.landing.lat == pytest.approx(lat, abs=2e-4)
    assert res.drift_km == pytest.approx(u * res.descent_s / 1000.0, rel=5e-3)
    assert res.bearing_deg == pytest.approx(90.0, abs=0.2)


def test_northward_wind_moves_along_the_meridian_radius() -> None:
    v = 8.0
    res = predict(isothermal_cube(v=v), Release(RELEASE, 44.0, 6.0, 30000.0), FlightSetup(PAYLOAD))
    s2 = math.sin(math.radians(44.0)) ** 2
    meridian = WGS84_A * (1 - WGS84_E2) / (1 - WGS84_E2 * s2) ** 1.5
    ground_m, _ = quad(lambda z: v * meridian / (meridian + z) / fall_speed(z), 0.0, 30000.0, limit=200)
    _, _, distance = GEOD.inv(6.0, 44.0, res.landing.lon, res.landing.lat)
    assert distance == pytest.approx(ground_m, rel=2e-3)
    assert res.landing.lat > 44.0


def sheared_wind(t_h: np.ndarray, z: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    return 10.0 + 25.0 * np.exp(-(((z - 11000.0) / 3500.0) ** 2)) + 0.8 * (lon - 6.0) + 0.3 * t_h


def turning_wind(t_h: np.ndarray, z: np.ndarray, lat: np.ndarray, lon: np.ndarray) -> np.ndarray:
    return 6.0 * np.sin(z / 5000.0) - 0.5 * (lat - 46.0)


def test_step_of_100_m_lands_within_150_m_of_a_1_m_step() -> None:
    cube = isothermal_cube(u=sheared_wind, v=turning_wind)
    coarse = predict(cube, Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD, step_m=100.0))
    fine = predict(cube, Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD, step_m=1.0))
    _, _, gap = GEOD.inv(coarse.landing.lon, coarse.landing.lat, fine.landing.lon, fine.landing.lat)
    assert fine.drift_km > 30.0
    assert gap < 150.0
    assert coarse.descent_s == pytest.approx(fine.descent_s, abs=1.0)


def test_crossing_greenwich_gives_the_same_landing_in_either_longitude_convention() -> None:
    signed = isothermal_cube(lons=np.arange(-10.0, 10.5, 0.5), u=15.0)
    global_lons = np.arange(0.0, 360.5, 0.5)
    global_cube = isothermal_cube(lons=global_lons, u=15.0)
    a = predict(signed, Release(RELEASE, 51.5, -0.2, 30000.0), FlightSetup(PAYLOAD))
    b = predict(global_cube, Release(RELEASE, 51.5, 359.8, 30000.0), FlightSetup(PAYLOAD))
    assert a.landing.lon > 0.0
    assert a.landing.lon == pytest.approx(b.landing.lon, abs=1e-9)
    assert a.landing.lat == pytest.approx(b.landing.lat, abs=1e-9)
    assert a.release.lon == pytest.approx(-0.2)
    assert b.release.lon == pytest.approx(-0.2)


def test_crossing_the_antimeridian_reports_longitudes_in_plus_minus_180() -> None:
    cube = isothermal_cube(lats=np.arange(-50.0, -37.0, 1.0), lons=np.arange(170.0, 191.0, 1.0), u=20.0)
    res = predict(cube, Release(RELEASE, -44.0, 179.8, 30000.0), FlightSetup(PAYLOAD))
    assert -180.0 <= res.landing.lon < -179.0
    assert np.all((res.track.lon >= -180.0) & (res.track.lon < 180.0))


def test_southern_hemisphere_descent_drifts_with_the_wind() -> None:
    cube = isothermal_cube(lats=np.arange(-50.0, -37.0, 1.0), lons=np.arange(165.0, 175.0, 1.0), v=10.0)
    res = predict(cube, Release(RELEASE, -44.7, 169.1, 30000.0), FlightSetup(PAYLOAD))
    assert res.landing.lat > -44.7
    assert res.bearing_deg == pytest.approx(0.0, abs=0.2)
    assert res.drift_km == pytest.approx(10.0 * res.descent_s / 1000.0, rel=5e-3)


def test_west_longitudes_drift_west_with_an_easterly_wind() -> None:
    cube = isothermal_cube(lats=np.arange(30.0, 40.0, 1.0), lons=np.arange(-110.0, -100.0, 1.0), u=-9.0)
    res = predict(cube, Release(RELEASE, 34.0, -104.5, 30000.0), FlightSetup(PAYLOAD))
    assert res.landing.lon < -104.5
    assert res.bearing_deg == pytest.approx(270.0, abs=0.2)


def test_path_leaving_the_region_is_an_error_naming_where() -> None:
    cube = isothermal_cube(lons=np.arange(0.0, 7.0, 1.0), u=30.0)
    with pytest.raises(OutOfCoverageError, match=r"leaves the weather region .* at 46\.\d+, 6\.\d+"):
        predict(cube, Release(RELEASE, 46.0, 5.5, 30000.0), FlightSetup(PAYLOAD))


def test_release_outside_the_region_is_an_error() -> None:
    with pytest.raises(OutOfCoverageError, match="release point .* is outside the weather region"):
        predict(isothermal_cube(), Release(RELEASE, 20.0, 6.0, 30000.0), FlightSetup(PAYLOAD))


def test_release_outside_the_time_span_is_an_error_naming_both_times() -> None:
    cube = isothermal_cube(hours=(0.0, 3.0))
    late = RELEASE + timedelta(hours=9)
    with pytest.raises(
        OutOfCoverageError,
        match=r"2024-05-01T15:00:00Z .* covers 2024-05-01T06:00:00Z to 2024-05-01T09:00:00Z",
    ):
        predict(cube, Release(late, 46.0, 6.0, 30000.0), FlightSetup(PAYLOAD))


def test_descent_running_past_the_last_valid_time_is_held_briefly_and_warned() -> None:
    cube = isothermal_cube(hours=(-3.0, 0.0))
    res = predict(cube, Release(RELEASE, 46.0, 6.0, 30000.0), FlightSetup(PAYLOAD))
    assert any("held at its nearest valid time" in w for w in res.warnings)


def test_descent_running_far_past_the_last_valid_time_is_an_error() -> None:
    cube = isothermal_cube(hours=(-6.0, -1.0))
    with pytest.raises(OutOfCoverageError, match="descent needs weather at"):
        predict(cube, Release(RELEASE, 46.0, 6.0, 30000.0), FlightSetup(PAYLOAD))


def test_release_above_the_top_level_is_an_error() -> None:
    cube = isothermal_cube(levels_hpa=np.array([1000, 850, 500, 250, 100, 50, 20], float))
    top = -H_ISO * math.log(20 / 1013.25)
    with pytest.raises(OutOfCoverageError, match="above the weather's top level \\(20 hPa\\)"):
        predict(cube, Release(RELEASE, 46.0, 6.0, top + 800.0), FlightSetup(PAYLOAD))


def test_release_just_above_the_top_level_is_within_tolerance() -> None:
    cube = isothermal_cube(levels_hpa=np.array([1000, 850, 500, 250, 100, 50, 20], float))
    top = -H_ISO * math.log(20 / 1013.25)
    res = predict(cube, Release(RELEASE, 46.0, 6.0, top + 300.0), FlightSetup(PAYLOAD))
    assert res.descent_s == pytest.approx(
        closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, top + 300.0), rel=1e-4
    )


GLOBAL_CUBES: dict[tuple[float, float], WeatherCube] = {}


@settings(max_examples=25, deadline=None)
@given(
    lat=st.floats(-80.0, 80.0),
    lon=st.floats(-180.0, 179.99),
    u=st.floats(-30.0, 30.0),
    v=st.floats(-30.0, 30.0),
)
def test_anywhere_on_earth_a_constant_wind_drifts_wind_times_fall_time(
    lat: float, lon: float, u: float, v: float
) -> None:
    # One global 2.5° cube per wind (its 0…360 longitudes carry the wrap column): no place is special.
    key = (round(u, 1), round(v, 1))
    if key not in GLOBAL_CUBES:
        GLOBAL_CUBES.clear()
        GLOBAL_CUBES[key] = isothermal_cube(
            lats=np.arange(-90.0, 90.1, 2.5), lons=np.arange(0.0, 360.1, 2.5), u=key[0], v=key[1]
        )
    res = predict(GLOBAL_CUBES[key], Release(RELEASE, lat, lon, 30000.0), FlightSetup(PAYLOAD))
    speed = math.hypot(*key)
    assert -180.0 <= res.landing.lon < 180.0
    assert res.descent_s == pytest.approx(
        closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, 30000.0), rel=1e-5
    )
    assert res.drift_km == pytest.approx(speed * res.descent_s / 1000.0, rel=0.01, abs=0.05)

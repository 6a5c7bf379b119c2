"""The payload profiles fall as their sources say they did."""

from __future__ import annotations

import numpy as np

from predictor import payload_profile, predict
from predictor.descent import Release
from predictor.environment.cube import WeatherCube
from predictor.prediction import FlightSetup
from predictor.tracks.standard_atmosphere import R_DRY_AIR, pressure_temperature
from tests.predictor.predict_helpers import LEVELS_HPA, RELEASE


def standard_atmosphere_cube() -> WeatherCube:
    """Still air with the 1976 standard atmosphere's pressure levels, temperature and density."""
    fine_z = np.linspace(-500.0, 40_000.0, 40_501)
    fine_p, _ = pressure_temperature(fine_z)
    z_levels = np.interp(np.log(LEVELS_HPA * 100.0), np.log(fine_p[::-1]), fine_z[::-1])
    pressure, temperature = pressure_temperature(z_levels)
    lats, lons, hours = np.arange(40.0, 53.0), np.arange(0.0, 13.0), np.array([-6.0, 18.0])
    shape = (hours.size, LEVELS_HPA.size, lats.size, lons.size)

    def field(column: np.ndarray) -> np.ndarray:
        return np.broadcast_to(column[None, :, None, None], shape).astype(float)

    base = np.datetime64(RELEASE.replace(tzinfo=None), "s")
    return WeatherCube(
        times=base + (hours * 3600).astype("timedelta64[s]"), lead_h=hours + 6.0, levels_hpa=LEVELS_HPA,
        lats=lats, lons=lons, z_m=field(z_levels), u=np.zeros(shape), v=np.zeros(shape),
        temperature_k=field(temperature), density=field(pressure / (R_DRY_AIR * temperature)),
        source="1976 standard atmosphere, still air",
    )  # fmt: skip


def test_the_drs_capsule_falls_from_30_km_in_about_37_minutes_as_measured_in_2019() -> None:
    """Sirks et al. 2020 (JINST 15 P05014): two DRS drops, ~37 min from ~30 km."""
    result = predict(
        standard_atmosphere_cube(), Release(RELEASE, 46.0, 6.0, 30_000.0), FlightSetup(payload_profile("drs"))
    )
    assert 36.0 <= result.descent_s / 60.0 <= 38.0, result.descent_s / 60.0


def test_both_rocketman_canopies_fly_at_the_same_fraction_of_their_nominal_drag_area() -> None:
    """0.97 × nominal area (pyBalloon's Cd) against the fitted Cd·A: 4 ft DRS and 7 ft test payload agree."""

    def nominal_cda(diameter_ft: float) -> float:
        return 0.97 * np.pi * (diameter_ft * 0.3048 / 2.0) ** 2

    drs = payload_profile("drs").cda_m2 / nominal_cda(4.0)
    test_payload = payload_profile("superbit-test").cda_m2 / nominal_cda(7.0)
    assert abs(drs - test_payload) < 0.03, (drs, test_payload)

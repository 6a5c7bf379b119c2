"""Residuals: a prediction compared with a measured descent at every fix, and per altitude bin."""

from __future__ import annotations

from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime
from pathlib import Path

import numpy as np
import pytest

from predictor.calibration.effects import BIN_EDGES_M, fit_binned
from predictor.calibration.residuals import FlightCase, bin_budget, flight_case, residuals, run, score
from predictor.descent.model import DescentRateScale, WindOffset, WindRotation
from predictor.descent.payload import PROFILES
from predictor.environment.terrain import Terrain, tile_name
from predictor.errors import PredictorError
from predictor.tracks.cleaning import clean
from predictor.tracks.reading import Fix, Track

PAYLOAD = PROFILES["superbit-test"]
Cases = Callable[..., list[FlightCase]]


def test_the_true_model_reproduces_a_synthetic_descent_to_metres(plain_cases: list[FlightCase]) -> None:
    for case in plain_cases:
        s = score(case, run(case, PAYLOAD, (), 1, 100.0))
        assert s.track_rms_km[0] < 0.03
        assert s.landing_error_km[0] < 0.03
        assert abs(s.time_rms_s[0]) < 20.0 and s.altitude_rms_km[0] < 0.03
        # The landing fix is the first one on the ground, up to one interval (180 s) after the touchdown;
        # the touchdown estimated from the last airborne fixes is within seconds of the truth.
        assert abs(s.descent_time_error_s[0]) < 20.0


def test_the_touchdown_is_estimated_from_the_last_airborne_fixes_not_the_late_landing_fix(
    plain_cases: list[FlightCase],
) -> None:
    """Uncorrected, every descent time would be long by about half an interval (90 s at 3 min)."""
    late = [case.fix_t[-1] - case.descent_time_s for case in plain_cases]
    assert all(0.0 < x <= 180.0 for x in late)
    assert np.mean(late) > 30.0


def test_a_slower_true_descent_shows_as_a_speed_ratio_of_the_factor_at_every_altitude(
    synthetic_cases: Cases,
) -> None:
    case = synthetic_cases((DescentRateScale(scale=0.8),), n=1)[0]
    res = residuals(case, run(case, PAYLOAD, (), 1, 100.0))
    ratios = res.speed_ratio[np.isfinite(res.speed_ratio)]
    assert len(ratios) >= 5 and np.all(np.abs(ratios - 0.8) < 0.03)
    assert np.isnan(res.speed_ratio[-1])  # the interval with the touchdown says nothing about speed
    assert res.descent_time_error_s < -300.0  # the plain model lands minutes early
    assert np.all(np.diff(res.interval_density) > 0)  # density rises as the capsule falls
    assert res.fix_alt_m.shape == res.along_km.shape == res.cross_km.shape == res.fix_wind_ms.shape


def test_a_veered_true_wind_leaves_the_capsule_right_of_the_predicted_track(synthetic_cases: Cases) -> None:
    case = synthetic_cases((WindRotation(angle_deg=20.0),), n=1)[0]
    res = residuals(case, run(case, PAYLOAD, (), 1, 100.0))
    assert res.landing_cross_km > 1.0
    assert res.cross_km[-1] == pytest.approx(res.landing_cross_km, abs=0.05)
    assert abs(res.landing_along_km) < res.landing_cross_km


def test_bin_budgets_recover_a_descent_factor_and_an_added_wind(synthetic_cases: Cases) -> None:
    edges = np.asarray(BIN_EDGES_M)
    slow = synthetic_cases((DescentRateScale(scale=0.8),), n=2)
    budgets = [bin_budget(c, run(c, PAYLOAD, (), 1, 100.0), 0, edges) for c in slow]
    factors = np.array(fit_binned(budgets).rate_factor)
    measured = np.sum([b.measured_s for b in budgets], axis=0)
    assert np.all(np.abs(factors[measured > 300] - 0.8) < 0.03)
    assert np.all(factors[measured == 0] == 1.0)
    pushed = synthetic_cases((WindOffset(east_ms=3.0, north_ms=-2.0),), n=2)
    wind = fit_binned([bin_budget(c, run(c, PAYLOAD, (), 1, 100.0), 0, edges) for c in pushed])
    seconds = np.array(wind.measured_s)
    east, north = np.array(wind.east_ms), np.array(wind.north_ms)
    # Positions between 3-minute fixes are linear in time, which blurs the jet's bins (±0.8 m/s);
    # over the whole descent the added wind comes back within 0.2 m/s.
    well_measured = seconds > 600
    assert np.all(np.abs(east[well_measured] - 3.0) < 0.8) and np.all(
        np.abs(north[well_measured] + 2.0) < 0.8
    )
    assert np.average(east, weights=seconds) == pytest.approx(3.0, abs=0.2)
    assert np.average(north, weights=seconds) == pytest.approx(-2.0, abs=0.2)


def test_many_parameter_sets_fly_in_one_batch_and_a_failed_run_scores_nan(
    plain_cases: list[FlightCase],
) -> None:
    case = plain_cases[0]
    runs = run(case, PAYLOAD, (DescentRateScale(scale=np.array([1.0, 0.0, 1.1])),), 3, 200.0)
    s = score(case, runs)
    assert list(runs.ok) == [True, False, True]
    assert np.isfinite(s.track_rms_km[[0, 2]]).all() and np.isnan(s.track_rms_km[1])
    assert s.landing_t[2] < s.landing_t[0]  # 10 % faster lands sooner


def test_a_flight_that_cleaning_excluded_cannot_be_calibrated_on(plain_cases: list[FlightCase]) -> None:
    t0 = datetime(2024, 5, 1, 8, tzinfo=UTC)
    fixes = tuple(
        Fix(time=t0.replace(minute=m), lat=46.0, lon=6.0 + 0.01 * m, alt_m=500.0 + 600.0 * m)
        for m in range(10)
    )
    flight = clean(Track(name="climb-only", source="test", format="synthetic", fixes=fixes))
    with pytest.raises(PredictorError, match="climb-only cannot be calibrated on"):
        flight_case(flight, plain_cases[0].cube)


def test_with_a_dem_the_prediction_lands_on_the_terrain(
    plain_cases: list[FlightCase], tmp_path: Path
) -> None:
    """A real SRTM3 tile set (big-endian int16) 300 m high around the landing: the path stops there."""
    case = plain_cases[1]
    flat = score(case, run(case, PAYLOAD, (), 1, 100.0))
    land_lat, land_lon = case.geographic(flat.landing_x, flat.landing_y)
    south, west = int(np.floor(land_lat[0])), int(np.floor(land_lon[0]))
    for dy in (-1, 0, 1):
        for dx in (-1, 0, 1):
            tile = tmp_path / f"{tile_name(south + dy, west + dx)}.hgt"
            np.full((1201, 1201), 300, dtype=">i2").tofile(tile)
    hilly = replace(case, terrain=Terrain.from_dir(tmp_path))
    on_dem = score(hilly, run(hilly, PAYLOAD, (), 1, 100.0))
    assert on_dem.landing_z[0] == pytest.approx(0.3, abs=1e-3)
    assert on_dem.landing_t[0] < flat.landing_t[0] - 30.0  # 300 m less to fall at ~4–5 m/s


@pytest.mark.parametrize("cadence_s", [180.0, 1.0], ids=["3min", "1Hz"])
def test_a_replayed_run_follows_the_measured_descent_so_a_rate_error_leaves_no_wind_error(
    synthetic_cases: Cases, cadence_s: float
) -> None:
    """The truth falls 20 % slower: the drag-law run is kilometres off in both altitude and position
    (it crosses the jet at the wrong times); the replayed run is on the measured profile and in the
    right place, since the wind it flies is the truth's."""
    case = synthetic_cases((DescentRateScale(scale=0.8),), n=1, cadence_s=cadence_s, noise_m=2.0)[0]
    plain = score(case, run(case, PAYLOAD, (), 1, 200.0))
    replayed = score(case, run(case, PAYLOAD, (DescentRateScale(scale=1.3),), 1, 200.0, replay=True))
    assert plain.altitude_rms_km[0] > 1.0 and plain.horizontal_rms_km[0] > 1.0
    assert replayed.altitude_rms_km[0] < 0.05 and replayed.horizontal_rms_km[0] < 0.1
    assert abs(replayed.descent_time_error_s[0]) < 5.0  # the vertical effect given to it is dropped


def test_the_vertical_record_read_against_pressure_is_blind_to_a_gnss_altitude_bias(
    plain_cases: list[FlightCase],
) -> None:
    """The synthetic loggers record the weather's pressure: read against it, the true model's time
    error stays as small as against the true altitude; a receiver that reads 300 m high moves the
    altitude-read record by about a minute, not the pressure-read one."""
    case = plain_cases[0]
    assert np.isfinite(case.fix_pressure_z).all()
    assert np.abs(case.fix_pressure_z - case.fix_z).max() < 0.02
    high = replace(case, fix_z=case.fix_z + 0.3)
    true, biased = (score(c, run(c, PAYLOAD, (), 1, 100.0)) for c in (case, high))
    assert true.time_rms_s[0] < 20.0 and true.pressure_time_rms_s[0] < 20.0
    assert biased.time_rms_s[0] > 40.0
    assert biased.pressure_time_rms_s[0] == pytest.approx(true.pressure_time_rms_s[0])


def test_without_a_logged_pressure_the_pressure_record_is_empty(plain_cases: list[FlightCase]) -> None:
    case = replace(plain_cases[0], fix_pressure_z=np.full(plain_cases[0].fix_z.shape, np.nan))
    assert np.isnan(score(case, run(case, PAYLOAD, (), 1, 100.0)).pressure_time_rms_s[0])

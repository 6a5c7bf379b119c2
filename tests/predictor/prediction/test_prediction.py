"""predict(): terrain crossing, drift before release, lead time, warnings, the result document."""

from __future__ import annotations

import json
import math
import shutil
from datetime import datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
import xarray as xr

from predictor import PROFILES, Payload, PredictorError, Terrain, payload_profile, predict
from predictor.descent import Release
from predictor.prediction import FlightSetup
from tests.predictor.predict_helpers import RELEASE, closed_form_fall_time, isothermal_cube

PAYLOAD = Payload(mass_kg=1.029, cda_m2=1.13)


def write_dem(path: Path, lats: np.ndarray, lons: np.ndarray, heights: np.ndarray) -> Path:
    ds = xr.Dataset(
        {"elevation": (("lat", "lon"), heights)},
        coords={
            "lat": ("lat", lats, {"units": "degrees_north"}),
            "lon": ("lon", lons, {"units": "degrees_east"}),
        },
    )
    ds.to_netcdf(path)
    return path


@pytest.fixture
def plateau(tmp_path: Path) -> Terrain:
    lats, lons = np.arange(40.0, 53.0, 0.5), np.arange(0.0, 13.0, 0.5)
    return Terrain.from_netcdf(
        write_dem(tmp_path / "plateau.nc", lats, lons, np.full((lats.size, lons.size), 1000.0))
    )


def test_landing_on_a_plateau_stops_at_its_height_with_the_closed_form_time(plateau: Terrain) -> None:
    res = predict(
        isothermal_cube(), Release(RELEASE, 46.0, 6.0, 30000.0), FlightSetup(PAYLOAD, terrain=plateau)
    )
    assert res.landing.alt_m == pytest.approx(1000.0, abs=1e-6)
    expected = closed_form_fall_time(PAYLOAD.mass_kg, PAYLOAD.cda_m2, 30000.0, 1000.0)
    assert res.descent_s == pytest.approx(expected, rel=1e-5)
    assert res.track.alt_m[-1] == pytest.approx(1000.0)
    assert np.all(res.track.alt_m[:-1] > 1000.0)
    assert res.terrain_source == "coarse DEM plateau.nc"
    assert "landing altitude from coarse DEM plateau.nc" in res.warnings


def test_crossing_a_sloping_ground_is_interpolated_inside_the_last_step(tmp_path: Path) -> None:
    # Ground rising 200 m per 0.1° of longitude eastwards; the capsule drifts east into the slope.
    lats, lons = np.arange(40.0, 53.0, 0.1), np.arange(0.0, 13.0, 0.1)
    heights = np.clip((lons - 5.3) * 2000.0, 0.0, None)[None, :].repeat(lats.size, axis=0)
    terrain = Terrain.from_netcdf(write_dem(tmp_path / "slope.nc", lats, lons, heights))
    res = predict(
        isothermal_cube(u=10.0), Release(RELEASE, 46.0, 5.0, 30000.0), FlightSetup(PAYLOAD, terrain=terrain)
    )
    ground_there = float(terrain.elevation(res.landing.lat, res.landing.lon))
    assert res.landing.alt_m == pytest.approx(ground_there, abs=2.0)
    assert res.landing.alt_m > 100.0
    assert res.path_km == pytest.approx(res.drift_km, rel=1e-3)


def test_landing_at_sea_is_at_zero_metres_and_says_so() -> None:
    res = predict(
        isothermal_cube(u=5.0),
        Release(RELEASE, 46.0, 6.0, 30000.0),
        FlightSetup(PAYLOAD, terrain=Terrain.sea_level()),
    )
    assert res.landing.alt_m == pytest.approx(0.0, abs=1e-9)
    assert any("sea level" in w for w in res.warnings)


def test_landing_on_the_real_srtm_tile_uses_its_heights(shared_data: Path, tmp_path: Path) -> None:
    shutil.copy(shared_data / "dem/srtm3_N47E009_hgt-elevation/137.hgt", tmp_path / "N47E009.hgt")
    terrain = Terrain.from_dir(tmp_path)
    cube = isothermal_cube(u=4.0)
    res = predict(cube, Release(RELEASE, 47.3, 9.2, 30000.0), FlightSetup(PAYLOAD, terrain=terrain))
    sea = predict(cube, Release(RELEASE, 47.3, 9.2, 30000.0), FlightSetup(PAYLOAD))
    assert res.terrain_source == "SRTM3 N47E009"
    assert 300.0 < res.landing.alt_m < 3000.0
    assert res.landing.alt_m == pytest.approx(
        float(terrain.elevation(res.landing.lat, res.landing.lon)), abs=25.0
    )
    assert res.descent_s < sea.descent_s


def test_release_below_the_ground_is_an_error(plateau: Terrain) -> None:
    with pytest.raises(PredictorError, match="release altitude 900 m is at or below the ground"):
        predict(isothermal_cube(), Release(RELEASE, 46.0, 6.0, 900.0), FlightSetup(PAYLOAD, terrain=plateau))


def test_drift_before_release_moves_the_release_point_with_the_float_wind() -> None:
    cube = isothermal_cube(u=10.0)
    res = predict(cube, Release(RELEASE, 46.0, 4.0, 30000.0, drift_minutes=30.0), FlightSetup(PAYLOAD))
    now = predict(
        cube,
        Release(RELEASE + timedelta(minutes=30), res.release.lat, res.release.lon, 30000.0),
        FlightSetup(PAYLOAD),
    )
    assert res.decision is not None and res.decision.lon == pytest.approx(4.0)
    assert res.release.time == RELEASE + timedelta(minutes=30)
    normal_km = 6378.137 / math.sqrt(1 - 6.69437999014e-3 * math.sin(math.radians(46.0)) ** 2)
    moved_at_float_km = (
        math.radians(res.release.lon - 4.0) * (normal_km + 30.0) * math.cos(math.radians(46.0))
    )
    assert moved_at_float_km == pytest.approx(10.0 * 30 * 60 / 1000.0, rel=1e-9)
    assert res.landing.lon == pytest.approx(now.landing.lon, abs=1e-9)


def test_a_drift_not_a_multiple_of_the_step_still_ends() -> None:
    res = predict(
        isothermal_cube(u=10.0), Release(RELEASE, 46.0, 4.0, 30000.0, drift_minutes=7.3), FlightSetup(PAYLOAD)
    )
    assert (res.release.time - RELEASE).total_seconds() == pytest.approx(438.0, abs=1e-3)


def test_t_future_is_the_time_mean_of_the_lead_along_the_path() -> None:
    cube = isothermal_cube(hours=(-3.0, 3.0), lead_h=(9.0, 15.0))
    res = predict(cube, Release(RELEASE, 46.0, 6.0, 30000.0), FlightSetup(PAYLOAD))
    # Lead grows 1 h per hour of valid time: its mean over the descent is the lead at mid-descent.
    assert res.t_future_mean_h == pytest.approx(12.0 + res.descent_s / 2 / 3600, abs=1e-3)


def test_demo_weather_is_marked_in_warnings_and_document() -> None:
    res = predict(isothermal_cube(is_demo=True), Release(RELEASE, 46.0, 6.0, 30000.0), FlightSetup(PAYLOAD))
    assert res.warnings[0].startswith("DEMO WEATHER")
    doc = res.to_dict()
    assert doc["is_demo"] is True and doc["weather"]["is_demo"] is True


def test_result_document_has_the_issue_keys_and_utc_times() -> None:
    res = predict(
        isothermal_cube(u=7.0),
        Release(RELEASE, 46.0, 6.0, 28000.0),
        FlightSetup(PAYLOAD, probabilities=(0.5, 0.95)),
    )
    doc = json.loads(json.dumps(res.to_dict(track=True)))
    for key in (
        "release",
        "landing",
        "descent_s",
        "drift_km",
        "path_km",
        "t_future_mean_h",
        "ellipse",
        "warnings",
        "track",
    ):
        assert key in doc
    assert set(doc["release"]) == {"time", "lat", "lon", "alt_m"} == set(doc["landing"])
    assert doc["release"]["time"] == "2024-05-01T06:00:00Z"
    assert doc["landing"]["time"].endswith("Z")
    assert datetime.fromisoformat(doc["landing"]["time"]) > RELEASE
    ellipse = doc["ellipse"]
    for key in ("sigma_parallel_km", "sigma_perpendicular_km", "bearing_deg", "contours"):
        assert key in ellipse
    assert [c["n_sigma"] for c in ellipse["contours"]][:3] == [1.0, 2.0, 3.0]
    assert {"n_sigma", "probability", "semi_major_km", "semi_minor_km"} <= set(ellipse["contours"][0])
    assert [c["probability"] for c in ellipse["contours"]][3:] == [0.5, 0.95]
    assert doc["track"][0] == {"t_s": 0.0, "lat": 46.0, "lon": 6.0, "alt_m": 28000.0}
    assert doc["track"][-1]["alt_m"] == pytest.approx(0.0)
    assert "track" not in res.to_dict()


@pytest.mark.parametrize(
    ("kwargs", "message"),
    [
        ({"time": datetime(2024, 5, 1, 6)}, "timezone-aware"),
        ({"lat": 91.0}, "latitude must be between"),
        ({"lon": float("nan")}, "longitude must be a finite"),
        ({"alt_m": -5.0}, "release altitude must be a positive"),
        ({"step_m": 0.0}, "altitude step must be between"),
        ({"drift_minutes": -1.0}, "drift time must be between"),
    ],
)
def test_bad_questions_are_refused_with_a_specific_message(kwargs: dict, message: str) -> None:
    args = {"time": RELEASE, "lat": 46.0, "lon": 6.0, "alt_m": 30000.0, "drift_minutes": 0.0, **kwargs}
    step_m = args.pop("step_m", 100.0)
    with pytest.raises(PredictorError, match=message):
        predict(isothermal_cube(), Release(**args), FlightSetup(PAYLOAD, step_m=step_m))


def test_payload_profiles_and_overrides() -> None:
    drs = payload_profile("drs")
    assert drs.mass_kg == 1.029 and drs.cda_m2 == 0.43
    assert PROFILES["superbit-test"].mass_kg == pytest.approx(1.6, abs=0.05)
    heavier = drs.overridden(mass_kg=2.0)
    assert heavier.mass_kg == 2.0 and heavier.cda_m2 == drs.cda_m2 and "mass overridden" in heavier.source
    with pytest.raises(PredictorError, match="unknown payload profile 'nope'"):
        payload_profile("nope")
    with pytest.raises(PredictorError, match="mass must be a positive"):
        Payload(mass_kg=0.0, cda_m2=1.0)
    with pytest.raises(PredictorError, match="Cd·A must be a positive"):
        Payload(mass_kg=1.0, cda_m2=float("inf"))


def test_heavier_payload_falls_faster_by_the_square_root_of_mass() -> None:
    light = predict(isothermal_cube(), Release(RELEASE, 46.0, 6.0, 30000.0), FlightSetup(Payload(1.0, 1.0)))
    heavy = predict(isothermal_cube(), Release(RELEASE, 46.0, 6.0, 30000.0), FlightSetup(Payload(4.0, 1.0)))
    assert light.descent_s / heavy.descent_s == pytest.approx(2.0, rel=1e-9)

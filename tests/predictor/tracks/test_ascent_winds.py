"""Ascent winds: known winds flown by a synthetic balloon come back out; real flights give valid cubes."""

from __future__ import annotations

import math
import re
from collections.abc import Callable
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path

import numpy as np
import pytest
from pyproj import Geod

from predictor.descent.payload import PROFILES
from predictor.environment.cube import WeatherCube
from predictor.errors import WeatherError
from predictor.prediction.landings import predict
from predictor.tracks.ascent_winds import ascent_weather_cube, ascent_wind_profile
from predictor.tracks.cleaning import Flight, clean
from predictor.tracks.reading import Fix, Track, read_track
from predictor.tracks.standard_atmosphere import R_DRY_AIR, pressure_temperature

GEOD = Geod(ellps="WGS84")
T0 = datetime(2024, 5, 1, 8, 0, 0, tzinfo=UTC)
Wind = Callable[[float], tuple[float, float]]
FLIGHT_FILE = re.compile(r"^\d+-\d+-\d+(_\d)?\.csv$")


def fly(
    wind: Wind,
    *,
    cadence_s: int,
    noise_m: float = 0.0,
    pressure_factor: float | None = None,
    lat: float = 46.2,
    lon: float = 6.1,
    seed: int = 1,
) -> Flight:
    """A balloon that moves exactly with ``wind`` (1 s steps on the ellipsoid) while climbing 5 m/s from
    400 m to 30 km, then a 2-fix fall and a landing; sampled every ``cadence_s`` with GNSS noise."""
    rng = np.random.default_rng(seed)
    truth: list[tuple[float, float, float, float]] = [(0.0, lat, lon, 400.0)]
    t, alt = 0.0, 400.0
    while alt < 30_000.0:
        u, v = wind(alt + 2.5)
        lon, lat, _ = GEOD.fwd(lon, lat, math.degrees(math.atan2(u, v)), math.hypot(u, v))
        t, alt = t + 1.0, alt + 5.0
        truth.append((t, lat, lon, alt))
    sampled = [s for s in truth if int(s[0]) % cadence_s == 0]
    fixes = [
        Fix(time=T0 - timedelta(seconds=600 - 120 * i), lat=lat0, lon=lon0, alt_m=400.0)
        for i, (lat0, lon0) in enumerate([(truth[0][1], truth[0][2])] * 4)
    ]
    for seconds, la, lo, z in sampled:
        east, north, up = rng.normal(0.0, noise_m, 3) if noise_m else (0.0, 0.0, 0.0)
        lo2, la2, _ = GEOD.fwd(lo, la, math.degrees(math.atan2(east, north)), math.hypot(east, north))
        fixes.append(Fix(time=T0 + timedelta(seconds=seconds), lat=la2, lon=lo2, alt_m=z + up))
    end = T0 + timedelta(seconds=t)
    for k, z in enumerate([20_000.0, 10_000.0, 3_000.0, 300.0, 305.0, 302.0], start=1):
        fixes.append(Fix(time=end + timedelta(seconds=180 * k), lat=lat, lon=lon, alt_m=z))
    if pressure_factor is not None:
        fixes = [
            Fix(
                time=f.time,
                lat=f.lat,
                lon=f.lon,
                alt_m=f.alt_m,
                pressure_pa=float(pressure_temperature(f.alt_m)[0]) * pressure_factor,
            )
            for f in fixes
        ]
    numbered = tuple(
        Fix(time=f.time, lat=f.lat, lon=f.lon, alt_m=f.alt_m, pressure_pa=f.pressure_pa, line=i + 1)
        for i, f in enumerate(fixes)
    )
    return clean(Track(name="synthetic", source="synthetic", format="test", fixes=numbered))


def constant(alt: float) -> tuple[float, float]:
    return 12.0, -7.0


def shear(alt: float) -> tuple[float, float]:
    """A jet-like profile: u grows 1 m/s per km, v turns with altitude."""
    return 5.0 + 1.0e-3 * alt, 10.0 * math.sin(alt / 5000.0)


def test_constant_wind_is_recovered_within_5_cm_per_s_from_3_minute_fixes() -> None:
    profile = ascent_wind_profile(fly(constant, cadence_s=180))
    assert np.max(np.abs(profile.u - 12.0)) < 0.05
    assert np.max(np.abs(profile.v + 7.0)) < 0.05


def test_constant_wind_is_recovered_within_20_cm_per_s_from_noisy_1hz_fixes() -> None:
    """3 m GNSS noise per fix: layer winds are displacement over time, so noise does not add up."""
    profile = ascent_wind_profile(fly(constant, cadence_s=1, noise_m=3.0))
    assert np.max(np.abs(profile.u - 12.0)) < 0.2
    assert np.max(np.abs(profile.v + 7.0)) < 0.2


def test_a_launch_between_two_fixes_does_not_dilute_the_lowest_layer_with_ground_time() -> None:
    """The last ground fix is 4 min before the launch: only the climb's time counts for that pair."""
    flight = fly(constant, cadence_s=180)
    launch = flight.ascent[0]
    assert launch.time == T0 and flight.ascent[1].alt_m == 1300.0
    late = (replace(launch, time=T0 - timedelta(seconds=240)), *flight.ascent[1:])
    profile = ascent_wind_profile(Flight(**{**flight.__dict__, "ascent": late}))
    assert profile.alt_m[0] < 1000
    assert profile.u[0] == pytest.approx(12.0, abs=0.1) and profile.v[0] == pytest.approx(-7.0, abs=0.1)


def test_wind_shear_is_recovered_layer_by_layer_from_1hz_fixes() -> None:
    profile = ascent_wind_profile(fly(shear, cadence_s=1, noise_m=3.0), layer_m=500.0)
    inner = (profile.alt_m > 1000) & (profile.alt_m < 29_500)
    expected = np.array([shear(z) for z in profile.alt_m[inner]])
    assert np.max(np.abs(profile.u[inner] - expected[:, 0])) < 0.25
    assert np.max(np.abs(profile.v[inner] - expected[:, 1])) < 0.25


def test_wind_shear_from_3_minute_fixes_is_the_layer_mean_within_half_a_fix_spacing() -> None:
    """900 m between fixes: each pair measures its layer's mean, so the error is at most the shear over
    ±450 m (0.45 m/s for u here, 0.9 m/s for v's steepest turn)."""
    profile = ascent_wind_profile(fly(shear, cadence_s=180), layer_m=500.0)
    inner = (profile.alt_m > 1500) & (profile.alt_m < 29_000)
    expected = np.array([shear(z) for z in profile.alt_m[inner]])
    assert np.max(np.abs(profile.u[inner] - expected[:, 0])) < 0.46
    assert np.max(np.abs(profile.v[inner] - expected[:, 1])) < 0.91
    assert np.mean(np.abs(profile.u[inner] - expected[:, 0])) < 0.25


def test_the_cube_has_the_weathercube_conventions_and_the_measured_wind() -> None:
    flight = fly(shear, cadence_s=60, pressure_factor=1.05)
    cube = ascent_weather_cube(flight)
    assert isinstance(cube, WeatherCube)
    assert np.all(np.diff(cube.levels_hpa) < 0)
    assert np.all(np.diff(cube.z_m[0, :, 0, 0]) > 0)
    assert np.all(np.diff(cube.lats) > 0) and np.all(np.diff(cube.lons) > 0)
    assert np.all(np.diff(cube.times) > np.timedelta64(0, "s"))
    assert np.all(cube.lead_h == 0)
    assert "ascent-measured wind of flight synthetic" in cube.source and not cube.is_demo
    assert flight.peak is not None
    assert cube.z_m[0, 0, 0, 0] <= -500 and cube.z_m[0, -1, 0, 0] >= flight.peak.alt_m + 2000
    assert flight.launch is not None and flight.landing is not None
    for f in (flight.launch, flight.peak, flight.landing):
        assert cube.covers(f.lat, f.lon)
    assert cube.times[0] <= np.datetime64(flight.launch.time.replace(tzinfo=None), "s")
    assert cube.times[-1] >= np.datetime64(flight.landing.time.replace(tzinfo=None), "s")
    for field in (cube.u, cube.v, cube.density, cube.z_m):
        assert np.all(field == field[:1, :, :1, :1])
    level = int(np.argmin(np.abs(cube.z_m[0, :, 0, 0] - 12_250)))
    assert cube.u[0, level, 0, 0] == pytest.approx(shear(12_250)[0], abs=0.1)


def test_cube_pressure_is_the_measured_pressure_and_density_uses_standard_temperature() -> None:
    cube = ascent_weather_cube(fly(constant, cadence_s=60, pressure_factor=1.05))
    z = cube.z_m[0, :, 0, 0]
    p_std, t_std = pressure_temperature(z)
    np.testing.assert_allclose(cube.levels_hpa * 100.0, 1.05 * p_std, rtol=0.005)
    np.testing.assert_allclose(cube.temperature_k[0, :, 0, 0], t_std)
    np.testing.assert_allclose(cube.density[0, :, 0, 0], cube.levels_hpa * 100.0 / (R_DRY_AIR * t_std))
    assert "pressure is measured on board from 400 to 29" in cube.warnings[2]


def test_without_measured_pressure_the_standard_atmosphere_is_used_and_said() -> None:
    cube = ascent_weather_cube(fly(constant, cadence_s=60))
    np.testing.assert_allclose(cube.levels_hpa * 100.0, pressure_temperature(cube.z_m[0, :, 0, 0])[0])
    assert "fewer than 3 trustworthy measured pressures in the ascent" in cube.warnings[2]


def test_a_measured_pressure_that_does_not_fall_with_altitude_is_not_used() -> None:
    flight = fly(constant, cadence_s=60, pressure_factor=1.0)
    stuck = tuple(
        Fix(time=f.time, lat=f.lat, lon=f.lon, alt_m=f.alt_m, pressure_pa=50_000.0, line=f.line)
        for f in flight.ascent
    )
    cube = ascent_weather_cube(Flight(**{**flight.__dict__, "ascent": stuck}))
    assert "fewer than 3 trustworthy measured pressures" in cube.warnings[2]
    assert np.all(np.diff(cube.levels_hpa) < 0)


def test_a_pressure_sensor_reading_high_aloft_is_trusted_only_up_to_where_it_is_physical() -> None:
    """+600 Pa (what 1.7x the standard pressure at 32 km amounts to): negligible low down, but near 26 km
    the pressure falls too slowly for any real air temperature."""
    flight = fly(constant, cadence_s=60, pressure_factor=1.0)
    offset = tuple(replace(f, pressure_pa=f.pressure_pa + 600.0) for f in flight.ascent)
    cube = ascent_weather_cube(Flight(**{**flight.__dict__, "ascent": offset}))
    top = float(re.search(r"measured on board from \d+ to (\d+) m", cube.warnings[2]).group(1))
    assert 20_000 < top < 27_000
    z = cube.z_m[0, :, 0, 0]
    above = z > top + 1000
    ratio = cube.levels_hpa[above] * 100.0 / pressure_temperature(z[above])[0]
    np.testing.assert_allclose(ratio, ratio[0], rtol=1e-6)


def test_measured_pressure_can_be_switched_off() -> None:
    cube = ascent_weather_cube(fly(constant, cadence_s=60, pressure_factor=1.3), use_measured_pressure=False)
    np.testing.assert_allclose(cube.levels_hpa * 100.0, pressure_temperature(cube.z_m[0, :, 0, 0])[0])
    assert "measured pressure not used, as asked" in cube.warnings[2]


def test_a_flight_across_the_antimeridian_gets_continuous_longitudes() -> None:
    flight = fly(lambda alt: (30.0, 0.0), cadence_s=180, lat=-45.0, lon=179.0)
    assert flight.peak is not None and flight.peak.lon < 0
    cube = ascent_weather_cube(flight)
    assert cube.lons[0] < 180 < cube.lons[-1]
    assert cube.covers(flight.peak.lat, flight.peak.lon)


def test_an_ascent_too_short_to_measure_is_a_weather_error() -> None:
    flight = fly(constant, cadence_s=180)
    short = Flight(**{**flight.__dict__, "ascent": flight.ascent[:2]})
    with pytest.raises(WeatherError, match="its ascent has 2 fixes; ascent winds need at least 3"):
        ascent_wind_profile(short)
    with pytest.raises(WeatherError, match="layer thickness must be positive"):
        ascent_wind_profile(flight, layer_m=0.0)


def test_every_real_flight_gives_a_cube_with_measured_pressure_and_plausible_winds(shared_data: Path) -> None:
    folder = shared_data / "tracks" / "pyballoon_superbit"
    for path in sorted(p for p in folder.iterdir() if FLIGHT_FILE.match(p.name)):
        flight = clean(read_track(path))
        cube = ascent_weather_cube(flight)
        speed = np.hypot(cube.u, cube.v)
        assert np.max(speed) < 90, path.name
        assert "pressure is measured on board from" in cube.warnings[2], path.name
        assert flight.landing is not None and cube.covers(flight.landing.lat, flight.landing.lon)
        assert flight.peak is not None
        assert cube.levels_hpa[0] > 900 and cube.z_m[0, -1, 0, 0] >= flight.peak.alt_m + 2000, path.name


def test_the_1hz_v4_ascent_gives_a_standard_atmosphere_cube_with_fine_layers(shared_data: Path) -> None:
    path = shared_data / "tracks/astra_meridiaz_V4_spain/V4_flight_1hz_DERIVED.csv"
    flight = clean(read_track(path, day=datetime(2021, 6, 1).date()))
    cube = ascent_weather_cube(flight, layer_m=250.0)
    profile = ascent_wind_profile(flight, layer_m=250.0)
    assert len(profile.alt_m) > 55 and np.all(profile.seconds >= 30)
    assert np.max(np.hypot(profile.u, profile.v)) < 60
    assert "fewer than 3 trustworthy measured pressures" in cube.warnings[2]
    assert cube.covers(flight.fixes[-1].lat, flight.fixes[-1].lon)


def test_the_predictor_flies_real_descents_through_ascent_cubes_to_near_the_real_landings(
    shared_data: Path,
) -> None:
    """The contract with predictor.prediction.landings.predict: with no forecast at all, the median landing
    error over these 10 flights is a few km against 10-86 km of drift (a wrong sign or unit would
    put it near the drift itself). The path is cut at the measured landing altitude (no DEM here)."""
    folder = shared_data / "tracks" / "pyballoon_superbit"
    names = [
        "18-3-4",
        "18-5-19",
        "18-6-30",
        "18-8-3",
        "19-1-1",
        "19-2-2",
        "19-3-11",
        "19-4-22",
        "19-7-28",
        "19-8-1",
    ]
    errors, drifts = [], []
    for name in names:
        flight = clean(read_track(folder / f"{name}.csv"))
        start, landing = flight.descent_start, flight.landing
        assert start is not None and landing is not None and flight.drift_km is not None
        path = predict(ascent_weather_cube(flight), start.time, start.lat, start.lon, start.alt_m,
                       payload=PROFILES["superbit-test"]).track  # fmt: skip
        k = min(int(np.searchsorted(-path.alt_m, -landing.alt_m)), len(path.alt_m) - 1)
        errors.append(GEOD.inv(path.lon[k], path.lat[k], landing.lon, landing.lat)[2] / 1000.0)
        drifts.append(flight.drift_km)
    assert np.median(errors) < 5.0
    assert np.median(np.array(errors) / np.array(drifts)) < 0.2

"""The independent generator itself: its files read as real ones, and its truth is the physics it claims."""

from __future__ import annotations

import math
from dataclasses import replace
from pathlib import Path

import numpy as np
import pytest

from predictor.environment import load_weather
from predictor.tracks import clean, read_track
from tests.independent_world import (
    CANOPY_DIAMETER_M,
    CDA_M2,
    GROUND_M,
    HARD,
    MASS_KG,
    NOISE_ONLY,
    RATE_DRIFT,
    REYNOLDS_DRAG,
    REYNOLDS_REF,
    TWO_REGIME,
    ForecastError,
    density,
    fly,
    geometric_altitude,
    geopotential_height,
    gravity,
    height_of_pressure,
    make_world,
    temperature_pressure,
    viscosity,
    wind,
)


@pytest.fixture(scope="module")
def world_dir(tmp_path_factory: pytest.TempPathFactory) -> Path:
    return tmp_path_factory.mktemp("independent")


def test_the_atmosphere_inverts_and_is_hydrostatic() -> None:
    """dp/dH = −ρ·g0 in geopotential height, and the height of a pressure is its inverse."""
    for h in (500.0, 9000.0, 15_000.0, 25_000.0, 33_000.0):
        t, p = temperature_pressure(h)
        assert height_of_pressure(p) == pytest.approx(h, abs=1e-6)
        dp = (temperature_pressure(h + 0.5)[1] - temperature_pressure(h - 0.5)[1]) / 1.0
        assert dp == pytest.approx(-p / (287.053 * t) * 9.80665, rel=1e-6)
    assert geometric_altitude(geopotential_height(28_000.0, 45.0), 45.0) == pytest.approx(28_000.0, abs=1e-6)


def test_a_true_descent_is_the_integral_of_the_drag_law(world_dir: Path) -> None:
    """The RK4 path's descent time equals the quadrature of dz / v(z) (no wind in the vertical)."""
    path, burst_s, land_s = fly(0.0, 45.5, 5.0, 28_000.0, 1.0, NOISE_ONLY)
    z = np.linspace(GROUND_M, 28_000.0, 200_001)
    speed = np.array(
        [math.sqrt(2 * MASS_KG * gravity(h, 45.5) / (density(h, 45.5) * CDA_M2)) for h in z[::100]]
    )
    quadrature = float(np.trapezoid(1.0 / np.interp(z, z[::100], speed), z))
    # The latitude changes a little during the fall (gravity and density follow it): well under a second.
    assert land_s - burst_s == pytest.approx(quadrature, abs=1.0)
    faster = fly(0.0, 45.5, 5.0, 28_000.0, 1.0, TWO_REGIME)
    assert faster[2] - faster[1] < land_s - burst_s - 60.0
    assert path[-1, 3] == GROUND_M


def test_its_tracks_clean_like_real_files_and_its_grib_is_the_field_sampled(world_dir: Path) -> None:
    world = make_world(world_dir / "noise", NOISE_ONLY, flights=2, seed=4)
    for truth in world.flights:
        flight = clean(read_track(truth.path))
        assert flight.usable, flight.exclusions
        assert flight.landing is not None
        assert abs(flight.landing.lat - truth.landing_lat) < 0.002
        assert abs(flight.landing.lon - truth.landing_lon) < 0.003
    cube = load_weather(world.weather, cache_dir=world_dir / "cache")
    # A grid point, level and hour: the decoder gives the field back (float32 packing, the altitude
    # converted by the project's own formula from geopotential height).
    li = int(np.argmin(np.abs(cube.levels_hpa - 250.0)))
    yi, xi = int(np.argmin(np.abs(cube.lats - 45.5))), int(np.argmin(np.abs(cube.lons - 5.0)))
    z = float(cube.z_m[3, li, yi, xi])
    hour = float((cube.times[3] - np.datetime64("2025-03-10T00:00:00")) / np.timedelta64(1, "h"))
    u, v = wind(z, hour, float(cube.lats[yi]), float(cube.lons[xi]))
    assert float(cube.u[3, li, yi, xi]) == pytest.approx(u, abs=0.05)
    assert float(cube.v[3, li, yi, xi]) == pytest.approx(v, abs=0.05)
    assert z == pytest.approx(geometric_altitude(height_of_pressure(25_000.0), 45.5), abs=15.0)


def test_the_forecast_error_has_its_stated_spread_and_correlation_scales() -> None:
    """3 m/s rms per component; correlation exp(−½) ≈ 0.61 one scale away in height, distance, time
    (averaged over 30 drawn fields of 48 modes, so the check is of the construction, not of one draw)."""
    spec = ForecastError()
    rng = np.random.default_rng(1)
    values, pairs = [], {"height": [], "distance": [], "time": []}
    for seed in range(30):
        error = ForecastError(seed=seed).field()
        for _ in range(60):
            z, lat, lon, t = (
                rng.uniform(0, 30_000),
                rng.uniform(44, 47),
                rng.uniform(3, 9),
                rng.uniform(0, 86_400),
            )
            u = error.at(z, lat, lon, t)[0]
            values.append(u)
            lat_step = math.degrees(spec.horizontal_m / 6_378_137.0)
            pairs["height"].append((u, error.at(z + spec.vertical_m, lat, lon, t)[0]))
            pairs["distance"].append((u, error.at(z, lat + lat_step, lon, t)[0]))
            pairs["time"].append((u, error.at(z, lat, lon, t + spec.hours * 3600.0)[0]))
    assert float(np.std(values)) == pytest.approx(spec.rms_ms, rel=0.15)
    for name, xy in pairs.items():
        r = float(np.corrcoef(np.array(xy).T)[0, 1])
        assert r == pytest.approx(math.exp(-0.5), abs=0.15), name


def test_hard_worlds_scatter_lambda_and_fly_winds_the_forecast_and_the_ascent_do_not_have() -> None:
    """What the hard worlds promise, measured on their flights: σ ln λ in 0.05–0.15; the descent crosses
    each height tens of kilometres and one to two hours from where the ascent crossed it; the winds it
    meets there differ from the forecast's and from the ascent's by a few m/s."""
    rng = np.random.default_rng(3)
    error = replace(HARD["forecast_error"], seed=3).field()  # type: ignore[arg-type]
    lambdas, apart_km, apart_h, vs_forecast, vs_ascent = [], [], [], [], []
    for k in range(12):
        lam = math.exp(rng.normal(0.0, HARD["rate_log_sigma"]))  # type: ignore[arg-type]
        lambdas.append(lam)
        path, burst_s, _ = fly(6 * 3600.0 + 2400.0 * k, 45.5, 5.0, rng.uniform(26_000, 30_000), lam, NOISE_ONLY,
                               error=error)  # fmt: skip
        up, down = path[path[:, 0] <= burst_s], path[path[:, 0] > burst_s][::-1]
        for h in (8_000.0, 12_000.0, 16_000.0, 20_000.0):
            a = [float(np.interp(h, up[:, 3], up[:, i])) for i in range(3)]
            d = [float(np.interp(h, down[:, 3], down[:, i])) for i in range(3)]
            north = math.radians(d[1] - a[1]) * 6_371_000.0
            east = math.radians(d[2] - a[2]) * 6_371_000.0 * math.cos(math.radians(45.5))
            apart_km.append(math.hypot(north, east) / 1000.0)
            apart_h.append((d[0] - a[0]) / 3600.0)
            forecast = np.array(wind(h, d[0] / 3600.0, d[1], d[2]))
            flown = forecast + np.array(error.at(h, d[1], d[2], d[0]))
            measured = np.array(wind(h, a[0] / 3600.0, a[1], a[2])) + np.array(error.at(h, a[1], a[2], a[0]))
            vs_forecast.append(float(np.linalg.norm(flown - forecast)))
            vs_ascent.append(float(np.linalg.norm(flown - measured)))
    assert 0.05 <= float(np.std(np.log(lambdas))) <= 0.15
    assert 10.0 <= float(np.median(apart_km)) <= 150.0
    assert 0.75 <= float(np.median(apart_h)) <= 2.5
    assert 1.5 <= float(np.sqrt(np.mean(np.square(vs_forecast)))) <= 8.0
    assert 1.5 <= float(np.sqrt(np.mean(np.square(vs_ascent)))) <= 10.0


def test_the_effects_no_library_term_has_are_the_physics_they_claim() -> None:
    """The drift is 1 + 0.25·t (t hours since release); the Reynolds drag solves v = v_law·(Re(v)/Re_ref)^(k/2)
    with Sutherland's viscosity, ~20 % slower than the law at 28 km and within 3 % of it near the ground."""
    assert RATE_DRIFT.rate_factor(10_000.0, 1800.0) == pytest.approx(1.125)
    for z in (28_000.0, 15_000.0, 1_000.0):
        law = math.sqrt(2 * MASS_KG * gravity(z, 45.5) / (density(z, 45.5) * CDA_M2))
        v = REYNOLDS_DRAG.through_air(law, z, 45.5)
        t, _ = temperature_pressure(geopotential_height(z, 45.5))
        reynolds = density(z, 45.5) * v * CANOPY_DIAMETER_M / viscosity(t)
        assert v == pytest.approx(
            law * (reynolds / REYNOLDS_REF) ** (REYNOLDS_DRAG.reynolds_exponent / 2), rel=1e-9
        )
        if z == 28_000.0:
            assert 0.7 < v / law < 0.9
        if z == 1_000.0:
            assert v / law == pytest.approx(1.0, abs=0.03)

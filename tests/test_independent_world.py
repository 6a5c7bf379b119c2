"""The independent generator itself: its files read as real ones, and its truth is the physics it claims."""

from __future__ import annotations

import math
from pathlib import Path

import numpy as np
import pytest

from predictor.environment import load_weather
from predictor.tracks import clean, read_track
from tests.independent_world import (
    CDA_M2,
    GROUND_M,
    MASS_KG,
    NOISE_ONLY,
    TWO_REGIME,
    density,
    fly,
    geometric_altitude,
    geopotential_height,
    gravity,
    height_of_pressure,
    make_world,
    temperature_pressure,
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

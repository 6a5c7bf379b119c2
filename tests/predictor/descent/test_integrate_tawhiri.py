"""A cross-implementation known answer: Tawhiri's synthetic jet case (shared/docs/predictor_anchors.md §5.4).

Tawhiri (RK4, 60 s steps, sphere of radius 6 371 009 m + altitude) was run on this field by the
research for this project; only its published outputs are used here, no code. With the same descent
law (``SeaLevelRate``: 1.1045·v_sl/sqrt(ρ), NASA-Glenn density) and the same linear-in-height winds,
an independent predictor should agree to about 0.2 % of the drift.
"""

from __future__ import annotations

import math
from datetime import UTC, datetime

import numpy as np
import pytest

from predictor import Model, WeatherCube, predict
from predictor.descent import Release
from predictor.descent.model import SeaLevelRate, Wind
from predictor.prediction import FlightSetup

LEVELS_HPA = np.array([*range(1000, 99, -25), 70, 50, 30, 20, 10, 7, 5, 3, 2, 1], dtype=float)
R_AIR = 287.053
G0 = 9.80665
# US Standard Atmosphere 1976 layers:
# base geopotential height (m), base temperature (K), lapse rate (K/m), base pressure (Pa).
USSA_LAYERS = (
    (0.0, 288.15, -0.0065, 101325.0),
    (11000.0, 216.65, 0.0, 22632.06),
    (20000.0, 216.65, 0.001, 5474.889),
    (32000.0, 228.65, 0.0028, 868.0187),
    (47000.0, 270.65, 0.0, 110.9063),
)


def ussa_height(p_pa: float) -> float:
    """Geopotential height of a pressure (at most 1013.25 hPa) in the US Standard Atmosphere 1976."""
    base_h, base_t, lapse, base_p = next(layer for layer in reversed(USSA_LAYERS) if p_pa <= layer[3])
    if lapse == 0.0:
        return base_h - R_AIR * base_t / G0 * math.log(p_pa / base_p)
    return base_h + base_t / lapse * ((p_pa / base_p) ** (-lapse * R_AIR / G0) - 1.0)


def nasa_glenn_density(h: float) -> float:
    """NASA Glenn Research Center's 'Earth Atmosphere Model' (public formulas), kg/m³."""
    if h > 25000.0:
        t = -131.21 + 0.00299 * h
        p = 2.488 * ((t + 273.1) / 216.6) ** -11.388
    elif h > 11000.0:
        t = -56.46
        p = 22.65 * math.exp(1.73 - 0.000157 * h)
    else:
        t = 15.04 - 0.00649 * h
        p = 101.29 * ((t + 273.1) / 288.08) ** 5.256
    return p / (0.2869 * (t + 273.1))


def tawhiri_field() -> WeatherCube:
    z = np.array([ussa_height(p * 100.0) for p in LEVELS_HPA])
    lats, lons = np.arange(48.0, 56.1, 0.5), np.arange(-4.0, 6.1, 0.5)
    shape = (2, z.size, lats.size, lons.size)
    column = np.broadcast_to(z[None, :, None, None], shape)
    u = 10.0 + 20.0 * np.exp(-(((column - 12000.0) / 4000.0) ** 2))
    v = 5.0 * np.sin(column / 5000.0)
    rho = np.broadcast_to(np.array([nasa_glenn_density(h) for h in z])[None, :, None, None], shape)
    return WeatherCube(
        times=np.array(["2024-01-01T00:00", "2024-01-01T12:00"], dtype="datetime64[s]"),
        lead_h=np.array([0.0, 12.0]),
        levels_hpa=LEVELS_HPA,
        lats=lats,
        lons=lons,
        z_m=column.astype(float),
        u=u,
        v=v,
        temperature_k=np.full(shape, 250.0),
        density=rho.astype(float),
        source="Tawhiri synthetic jet field",
    )


def test_levels_reproduce_the_published_heights() -> None:
    z = [ussa_height(p * 100.0) for p in LEVELS_HPA]
    assert z[0] == pytest.approx(111.0, abs=1.0)
    assert z[-1] == pytest.approx(47820.0, abs=5.0)


def test_synthetic_jet_case_agrees_with_tawhiri_within_0_2_percent_of_the_drift() -> None:
    model = Model((SeaLevelRate(rate_ms=5.0), Wind()))
    res = predict(
        tawhiri_field(),
        Release(datetime(2024, 1, 1, 6, tzinfo=UTC), 52.0, 0.5, 30000.0),
        FlightSetup(model=model),
    )
    # Tawhiri's drift east/north are its angles times its radius; ours are our angles times the
    # WGS84 radii of curvature at the mean latitude (each model's own metres on the ground).
    phi = math.radians((52.0 + res.landing.lat) / 2.0)
    w = 1.0 - 6.69437999014e-3 * math.sin(phi) ** 2
    meridian_km = 6378.137 * (1.0 - 6.69437999014e-3) / w**1.5
    normal_km = 6378.137 / math.sqrt(w)
    north_km = math.radians(res.landing.lat - 52.0) * meridian_km
    east_km = math.radians(res.landing.lon - 0.5) * normal_km * math.cos(phi)
    drift = math.hypot(42.021, 4.651)
    assert res.descent_s == pytest.approx(2755.8, rel=1e-3)
    assert abs(east_km - 42.021) < 0.002 * drift
    assert abs(north_km - 4.651) < 0.002 * drift

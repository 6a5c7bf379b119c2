"""Analytic atmospheres with closed-form descents, built directly as WeatherCubes (no files).

The isothermal atmosphere has density ρ0·exp(−z/H) at every level; the stepper interpolates
log-density linearly in altitude, so it sees exactly this profile and the fall time has a closed form.
"""

from __future__ import annotations

import math
from collections.abc import Callable
from datetime import UTC, datetime

import numpy as np

from predictor.environment.cube import WeatherCube

R_DRY = 287.05
G0 = 9.80665
R_GRAVITY = 6371009.0
P0_HPA = 1013.25
T_ISO = 250.0
H_ISO = R_DRY * T_ISO / G0
RHO0 = P0_HPA * 100.0 / (R_DRY * T_ISO)
LEVELS_HPA = np.array(
    [1000, 925, 850, 700, 500, 400, 300, 250, 200, 150, 100, 70, 50, 30, 20, 10, 7, 5], float
)
RELEASE = datetime(2024, 5, 1, 6, 0, tzinfo=UTC)

WindFn = Callable[[np.ndarray, np.ndarray, np.ndarray, np.ndarray], np.ndarray]


def level_altitudes(levels_hpa: np.ndarray = LEVELS_HPA) -> np.ndarray:
    return -H_ISO * np.log(levels_hpa / P0_HPA)


def isothermal_cube(
    lats: np.ndarray | None = None,
    lons: np.ndarray | None = None,
    u: float | WindFn = 0.0,
    v: float | WindFn = 0.0,
    hours: tuple[float, ...] = (-6.0, 18.0),
    lead_h: tuple[float, ...] | None = None,
    levels_hpa: np.ndarray = LEVELS_HPA,
    is_demo: bool = False,
) -> WeatherCube:
    """An isothermal atmosphere around RELEASE; u, v constants or functions of (t_h, z, lat, lon)."""
    lats = np.arange(40.0, 53.0, 1.0) if lats is None else np.asarray(lats, float)
    lons = np.arange(0.0, 13.0, 1.0) if lons is None else np.asarray(lons, float)
    t_h = np.asarray(hours, float)
    z_lev = level_altitudes(levels_hpa)
    shape = (t_h.size, z_lev.size, lats.size, lons.size)
    tt, zz, yy, xx = np.meshgrid(t_h, z_lev, lats, lons, indexing="ij")
    u_field = np.broadcast_to(u(tt, zz, yy, xx) if callable(u) else float(u), shape).astype(float)
    v_field = np.broadcast_to(v(tt, zz, yy, xx) if callable(v) else float(v), shape).astype(float)
    rho = RHO0 * np.exp(-zz / H_ISO)
    base = np.datetime64(RELEASE.replace(tzinfo=None), "s")
    times = base + (t_h * 3600).astype("timedelta64[s]")
    return WeatherCube(
        times=times,
        lead_h=np.asarray(lead_h if lead_h is not None else t_h + 6.0, float),
        levels_hpa=np.asarray(levels_hpa, float),
        lats=lats,
        lons=lons,
        z_m=zz.astype(float),
        u=u_field,
        v=v_field,
        temperature_k=np.full(shape, T_ISO),
        density=rho,
        source="analytic isothermal test atmosphere",
        is_demo=is_demo,
    )


def closed_form_fall_time(
    mass_kg: float, cda_m2: float, z_top: float, z_bottom: float = 0.0, beta: float = 0.0
) -> float:
    """∫ dz / v for v = sqrt(2 m g(z) / (ρ Cd·A))·(ρ/ρ_ref)^(−β), isothermal ρ, ρ_ref = 1.225, g spherical."""
    v0 = math.sqrt(2.0 * mass_kg * G0 / (RHO0 * cda_m2)) * (RHO0 / 1.225) ** (-beta)
    a = 0.5 / H_ISO + beta / H_ISO

    def primitive(z: float) -> float:
        # ∫ (1 + z/R) e^(−a z) dz
        return -math.exp(-a * z) / a - math.exp(-a * z) * (a * z + 1.0) / (a * a * R_GRAVITY)

    return (primitive(z_top) - primitive(z_bottom)) / v0

"""The U.S. Standard Atmosphere 1976 below 84 km: pressure and temperature where none was measured.

A flight's own ascent measures wind and (on SuperBIT) pressure, but not the ambient temperature
(the logged temperature is inside the payload), so the density a descent needs comes from the
measured pressure and this temperature. Typical real temperatures differ from it by up to ~10 %,
which is the size of the density error that remains.
"""

from __future__ import annotations

import numpy as np

G0 = 9.80665
R_DRY_AIR = 287.0531
"""Specific gas constant of dry air in J/(kg K), as the 1976 standard defines it."""
EARTH_RADIUS_M = 6_356_766.0

_BASE_H_M = np.array([0.0, 11_000.0, 20_000.0, 32_000.0, 47_000.0, 51_000.0, 71_000.0])
_LAPSE_K_PER_M = np.array([-6.5e-3, 0.0, 1.0e-3, 2.8e-3, 0.0, -2.8e-3, -2.0e-3])
_BASE_T_K = np.array([288.15, 216.65, 216.65, 228.65, 270.65, 270.65, 214.65])
_BASE_P_PA = np.array([101_325.0, 22_632.06, 5_474.889, 868.0187, 110.9063, 66.93887, 3.956420])


def geopotential_m(z_m: np.ndarray) -> np.ndarray:
    return EARTH_RADIUS_M * z_m / (EARTH_RADIUS_M + z_m)


def pressure_temperature(z_m: float | np.ndarray) -> tuple[np.ndarray, np.ndarray]:
    """(pressure Pa, temperature K) at geometric altitude ``z_m`` (valid from -5 km to 84 km)."""
    h = geopotential_m(np.asarray(z_m, dtype=float))
    layer = np.clip(np.searchsorted(_BASE_H_M, h, side="right") - 1, 0, len(_BASE_H_M) - 1)
    dh = h - _BASE_H_M[layer]
    lapse = _LAPSE_K_PER_M[layer]
    base_t = _BASE_T_K[layer]
    temperature = base_t + lapse * dh
    isothermal = lapse == 0.0
    safe_lapse = np.where(isothermal, 1.0, lapse)
    gradient = _BASE_P_PA[layer] * (base_t / temperature) ** (G0 / (R_DRY_AIR * safe_lapse))
    flat = _BASE_P_PA[layer] * np.exp(-G0 * dh / (R_DRY_AIR * base_t))
    return np.where(isothermal, flat, gradient), temperature

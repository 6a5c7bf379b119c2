"""The region of weather a descent can reach: all that needs decoding from a GRIB file.

Light on purpose (no numpy): the command line sizes the region before it decides to load anything.
"""

from __future__ import annotations

import math

WEATHER_MARGIN_DEG = 6.0
"""Half-size of the weather region decoded around the release (a 30 km descent drifts ≲ 300 km)."""
FLOAT_WIND_MAX_MS = 60.0
"""Fastest wind assumed at float altitude when sizing the region for a drift before release."""
POLAR_CAP_DEG = 10.0
"""A region reaching this close to a pole takes every longitude: meridians converge there, and a
descent near the pole may circle it (Antarctic long-duration flights launch at 78° S)."""


def weather_bbox(lat: float, lon: float, drift_minutes: float) -> tuple[float, float, float, float]:
    """The region a descent (and the drift before it) can reach: its longitude half-width is sized at
    the box's poleward edge, where a degree of longitude is shortest."""
    half = WEATHER_MARGIN_DEG + FLOAT_WIND_MAX_MS * drift_minutes * 60.0 / 111_000.0
    south, north = max(lat - half, -90.0), min(lat + half, 90.0)
    poleward = max(abs(south), abs(north))
    half_lon = half / max(math.cos(math.radians(poleward)), 1e-9)
    if 90.0 - poleward <= POLAR_CAP_DEG or half_lon >= 180.0:
        return south, north, lon - 180.0, lon + 180.0
    return south, north, lon - half_lon, lon + half_lon

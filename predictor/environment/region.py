"""The region of weather a descent can reach: all that needs decoding from a GRIB file.

Light on purpose (no numpy): the command line sizes the region before it decides to load anything.
"""

from __future__ import annotations

import math

WEATHER_MARGIN_DEG = 6.0
"""Half-size of the weather region decoded around the release (a 30 km descent drifts ≲ 300 km)."""
FLOAT_WIND_MAX_MS = 60.0
"""Fastest wind assumed at float altitude when sizing the region for a drift before release."""


def weather_bbox(lat: float, lon: float, drift_minutes: float) -> tuple[float, float, float, float]:
    """The region a descent (and the drift before it) can reach."""
    half = WEATHER_MARGIN_DEG + FLOAT_WIND_MAX_MS * drift_minutes * 60.0 / 111_000.0
    half_lon = min(half / max(math.cos(math.radians(lat)), 0.05), 179.0)
    return max(lat - half, -90.0), min(lat + half, 90.0), lon - half_lon, lon + half_lon

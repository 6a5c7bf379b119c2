"""A whole landing prediction for tests that care about a few of its numbers (a sample has no optional landing)."""

from __future__ import annotations

from datetime import UTC, datetime
from typing import Any

from drs_link.ops.telemetry import Contour, PredictionSample

RELEASED = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)


def prediction(**fields: Any) -> PredictionSample:
    """A prediction 47 km east of Esrange; ``fields`` replace its numbers."""
    whole: dict[str, Any] = {
        "release_in_min": 0,
        "release_lat": 67.8887,
        "release_lon": 21.0856,
        "release_time": RELEASED,
        "landing_lat": 67.9501,
        "landing_lon": 22.2289,
        "landing_time": datetime(2026, 9, 1, 12, 41, tzinfo=UTC),
        "descent_s": 2460.0,
        "distance_km": 47.4,
        "bearing_deg": 81.2,
        "sigma_par_km": 1.97,
        "sigma_perp_km": 1.73,
        "major_axis_bearing_deg": 81.2,
        "contours": (Contour(2.0, 0.865, 3.94, 3.46),),
        "outline_2sigma": ((22.1, 67.93), (22.3, 67.93), (22.3, 67.97), (22.1, 67.97)),
        "path": ((21.0856, 67.8887), (22.2289, 67.9501)),
    }
    return PredictionSample(**{**whole, **fields})


REQUIRED: dict[str, dict[str, Any]] = {
    "link": {"up": True},
    "release": {"state": "idle"},
    "gnss": {"has_fix": False},
    "prediction": dict(vars(prediction())),
    "prediction_status": {"short": "waiting", "text": "waiting for a position"},
    "balloon": {"lat": 67.9, "lon": 21.1, "alt_m": 31_200.0},
    "gateway": {"credentials_ok": True},
}
"""The least each kind holds, as keyword arguments; the kinds not here may arrive with every part unknown."""

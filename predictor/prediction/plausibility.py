"""Values that parse but are probably not what the operator meant: each check gives one line, or None.

Why: a tired operator types 31.5 for a release at 31.5 km, or a zones file has its coordinates in
(lat, lon) order. Every such slip produced a confident, wrong answer (a six-second descent, every zone
probability 0.000) and no hint. These checks never refuse: the value may be meant (a tower drop test),
so the command goes on and the line says what looks wrong and what was probably meant.
"""

from __future__ import annotations

import sys
from collections.abc import Sequence
from typing import TYPE_CHECKING

from predictor.prediction.uncertainty import GEOD

if TYPE_CHECKING:  # shapely loads with the zone checks, not with `drs recovery`
    from shapely.geometry.base import BaseGeometry


KM_LIKE_ALTITUDE_M = (1.0, 60.0)
"""An --alt in this range of metres is very likely kilometres: balloons release from 1–60 km, and a
release a few metres up is a tower test that would not be typed as a fraction."""

FAR_FROM_RELEASE_KM = 1000.0
"""A descent from 40 km drifts at most ~300 km even in a strong jet, and the predictor reads weather
600 km around the release: a zone or target 1000 km from every release cannot matter, so the file is
probably not the one meant, or has its coordinates swapped."""

FAR_FROM_CAPSULE_KM = 1000.0
"""No chase team is 1000 km from the capsule it is recovering: a position that far is a typo, swapped
coordinates, or a GPS that has not yet got a fix."""


def release_altitude_warning(alt_m: float, flag: str = "--alt") -> str | None:
    low, high = KM_LIKE_ALTITUDE_M
    if low <= alt_m < high:
        return (
            f"{flag} {alt_m:g} m is a release {alt_m:g} metres up; did you mean {alt_m:g} km "
            f"({flag} {alt_m * 1000:.0f})?"
        )
    return None


def _distance_km(geometry: BaseGeometry, lat: float, lon: float) -> float:
    """Great-circle distance from a point to the nearest point of a geometry (lon, lat degrees)."""
    import shapely
    from shapely.ops import nearest_points

    nearest = nearest_points(geometry, shapely.Point(lon, lat))[0]
    return float(GEOD.inv(lon, lat, nearest.x, nearest.y)[2]) / 1000.0


def _swapped(geometry: BaseGeometry) -> BaseGeometry:
    import shapely

    return shapely.transform(geometry, lambda xy: xy[:, ::-1])


def far_features_warning(
    kind: str, geometries: Sequence[BaseGeometry], releases: Sequence[tuple[float, float]]
) -> str | None:
    """A warning when every zone (or target) is further than ``FAR_FROM_RELEASE_KM`` from every release.

    ``releases`` are (lat, lon). When swapping each geometry's coordinates would bring it near, the
    warning says so: GeoJSON is (lon, lat), and files exported from spreadsheets often are not.
    """
    if not geometries or not releases:
        return None
    nearest = min(_distance_km(g, lat, lon) for g in geometries for lat, lon in releases)
    if nearest <= FAR_FROM_RELEASE_KM:
        return None
    text = f"every {kind} is over {nearest:.0f} km from the release; none can be reached by a descent"
    swapped = [_swapped(g) for g in geometries]
    if all(-90.0 <= g.bounds[1] and g.bounds[3] <= 90.0 for g in swapped):
        nearest_swapped = min(_distance_km(g, lat, lon) for g in swapped for lat, lon in releases)
        if nearest_swapped <= FAR_FROM_RELEASE_KM:
            hint = f"with longitude and latitude swapped the nearest is {nearest_swapped:.0f} km"
            return f"{text} ({hint}: GeoJSON is [longitude, latitude])"
    return text + " (is it the file for this flight?)"


def far_team_warning(team: tuple[float, float], capsule: tuple[float, float]) -> str | None:
    """A warning when the team's position is implausibly far from the capsule (both (lat, lon))."""
    distance = float(GEOD.inv(team[1], team[0], capsule[1], capsule[0])[2]) / 1000.0
    if distance <= FAR_FROM_CAPSULE_KM:
        return None
    hint = ""
    if abs(team[1]) <= 90.0:
        swapped = float(GEOD.inv(team[0], team[1], capsule[1], capsule[0])[2]) / 1000.0
        if swapped <= FAR_FROM_CAPSULE_KM:
            hint = f"; as LON,LAT it would be {swapped:.0f} km away: --from takes LAT,LON"
    return f"your position is {distance:.0f} km from the capsule; is it right{hint}?"


def emit(*warnings: str | None) -> None:
    """Each warning that applies, as one `drs: warning:` line on stderr (stdout stays the command's output)."""
    for warning in warnings:
        if warning is not None:
            print(f"drs: warning: {warning}", file=sys.stderr)

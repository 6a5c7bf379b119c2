"""Lines and rings cut at the antimeridian, rings counter-clockwise, coordinates rounded.

A ring or path that crosses ±180° and is written point by point becomes a band round the globe in
every tool that joins points straight in longitude (QGIS, Leaflet, shapely). RFC 7946 §3.1.9 asks
for such geometry to be cut at the antimeridian, and §3.1.6 for exterior rings to run
counter-clockwise. KML states no rule of its own, and Google Earth and QGIS both draw the cut parts
correctly, so every format writes the same parts.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from itertools import pairwise

import antimeridian
import numpy as np
from shapely.geometry import MultiPolygon, Polygon
from shapely.geometry.polygon import orient

DEGREE_DECIMALS = 6
"""0.11 m at the equator: finer than any GNSS fix, without float noise for readers (RFC 7946 §11.2)."""
ALTITUDE_DECIMALS = 1

Coordinate = tuple[float, ...]
"""(lon, lat) or (lon, lat, altitude m), in the order GeoJSON and KML both use."""


def wrap_lon(lon: float) -> float:
    return (lon + 180.0) % 360.0 - 180.0


def _rounded(point: Sequence[float]) -> Coordinate:
    lon, lat, *alt = point
    return (
        round(lon, DEGREE_DECIMALS),
        round(lat, DEGREE_DECIMALS),
        *(round(a, ALTITUDE_DECIMALS) for a in alt),
    )


def position(point: Sequence[float]) -> Coordinate:
    """One (lon, lat[, alt]) point, longitude wrapped into [-180, 180) and rounded."""
    if not all(math.isfinite(v) for v in point):
        raise ValueError(f"a position must be finite numbers, not {tuple(point)}")
    return _rounded((wrap_lon(point[0]), *point[1:]))


def line_parts(points: Sequence[Sequence[float]]) -> list[list[Coordinate]]:
    """The line as parts that each stay on one side of ±180°, joined where they cross it.

    A step longer than 180° of longitude is taken the short way round, across the antimeridian;
    the crossing's latitude and altitude are interpolated along the step. Points with a non-finite
    number (a gap in a record) are left out rather than written as NaN. The ``antimeridian``
    package cuts lines too, but only in two dimensions, and descent paths carry altitude.
    """
    finite = [tuple(float(v) for v in p) for p in points if all(math.isfinite(v) for v in p)]
    if not finite:
        return []
    finite = [(wrap_lon(p[0]), *p[1:]) for p in finite]
    parts: list[list[Coordinate]] = [[finite[0]]]
    for before, after in pairwise(finite):
        step = after[0] - before[0]
        if abs(step) > 180.0:
            edge = math.copysign(180.0, before[0])
            fraction = (edge - before[0]) / (step - math.copysign(360.0, step))
            rest = tuple(b + fraction * (a - b) for b, a in zip(before[1:], after[1:], strict=True))
            parts[-1].append((edge, *rest))
            parts.append([(-edge, *rest)])
        parts[-1].append(after)
    return [line for part in parts if len(line := _distinct(part)) >= 2]


def _distinct(part: list[Coordinate]) -> list[Coordinate]:
    """Rounded, without repeats of the point before (an edge of zero length is invalid in shapely)."""
    out: list[Coordinate] = []
    for point in part:
        r = _rounded(point)
        if not out or r != out[-1]:
            out.append(r)
    return out


def polygon_parts(ring: Sequence[Sequence[float]]) -> list[list[Coordinate]]:
    """A closed (lon, lat) ring as the exterior rings of polygons cut at ±180°, each counter-clockwise.

    The ring is first made continuous in longitude and turned counter-clockwise there, where its
    direction means something; only then is it wrapped and cut, so that the cutter never mistakes
    a clockwise ellipse for the rest of the globe.
    """
    lons = np.degrees(np.unwrap(np.radians([p[0] for p in ring])))
    continuous = orient(Polygon(zip(lons, (p[1] for p in ring), strict=True)), 1.0)
    wrapped = Polygon([(wrap_lon(x), y) for x, y in continuous.exterior.coords])
    cut = antimeridian.fix_polygon(wrapped, fix_winding=False, great_circle=False)
    polygons = cut.geoms if isinstance(cut, MultiPolygon) else [cut]
    return [_distinct([tuple(c) for c in orient(p, 1.0).exterior.coords]) for p in polygons]

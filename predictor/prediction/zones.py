"""Exclusion zones and recovery targets from GeoJSON, and what a landing ellipse says about them.

Why integrate over the ellipse: a landing whose centre is 3 km from a lake but whose 1σ is 4 km lands in
the lake with a real probability; asking only "is the centre inside" says 0. So the probability of
landing in a zone is the bivariate normal integrated over the polygon, and the distance from the nearest
target is an expectation over the same normal.

How: every geometry is projected once into a local azimuthal-equidistant plane (km) centred near the
release (``LocalPlane``), where a landing is a 2-D Gaussian (centre, 2×2 covariance). The probability
is the Gaussian's mass inside the polygon, computed as a boundary integral in the Gaussian's own
(whitened) frame (``gaussian_mass``); the indicator of a polygon is discontinuous, so neither a grid
nor a smooth rule over the area would be accurate. The expected distance is smooth and uses a 12×12
Gauss–Hermite product rule.

Longitudes: GeoJSON edges are straight lines in (lon, lat). Consecutive vertices are joined the short
way round (an edge never spans more than 180° of longitude), so a ring given as 179 → -179 crosses the
antimeridian, as does one given as 179 → 181, and a polygon split at ±180 into a MultiPolygon (as RFC
7946 recommends) is two pieces that meet at the cut. Rings are densified to 0.05° in (lon, lat) before
projection so their edges stay where GeoJSON puts them.
"""

from __future__ import annotations

import json
import math
from collections.abc import Sequence
from dataclasses import dataclass
from pathlib import Path
from typing import Any

import numpy as np
import shapely
from numpy.polynomial.hermite_e import hermegauss
from pyproj import Transformer
from shapely.geometry.base import BaseGeometry

from predictor.errors import PredictorError

DENSIFY_DEG = 0.05
CLIP_SIGMA = 6.0
EDGE_SIGMA = 0.25
HERMITE_NODES = 12
_LEGENDRE_X, _LEGENDRE_W = np.polynomial.legendre.leggauss(8)
LEGENDRE_T = 0.5 * (_LEGENDRE_X + 1.0)
LEGENDRE_W = 0.5 * _LEGENDRE_W
POLYGON_TYPES = ("Polygon", "MultiPolygon")
TARGET_TYPES = ("Point", "MultiPoint", "LineString", "MultiLineString")


class ZoneFileError(PredictorError):
    """A zone or target file cannot be used; the message names the file and the feature."""


@dataclass(frozen=True)
class Feature:
    """One named geometry in (lon, lat) degrees, longitudes made continuous along each ring/line."""

    name: str
    geometry: BaseGeometry


def _unwrap(coords: np.ndarray) -> np.ndarray:
    """Longitudes shifted by multiples of 360° so that no step between vertices exceeds 180°."""
    out = coords.copy()
    if len(out) > 1:
        steps = np.diff(out[:, 0])
        out[1:, 0] = out[0, 0] + np.cumsum(steps - 360.0 * np.round(steps / 360.0))
    return out


def _positions(raw: Any, where: str) -> np.ndarray:
    try:
        arr = np.asarray(raw, dtype=np.float64)
    except (TypeError, ValueError):
        raise ZoneFileError(f"{where}: coordinates must be [lon, lat] number pairs") from None
    if arr.ndim != 2 or arr.shape[1] < 2 or arr.shape[0] == 0:
        raise ZoneFileError(f"{where}: coordinates must be a list of [lon, lat] positions")
    arr = arr[:, :2]
    if not np.isfinite(arr).all():
        raise ZoneFileError(f"{where}: a coordinate is not a finite number")
    if (np.abs(arr[:, 1]) > 90.0).any():
        bad = float(arr[np.abs(arr[:, 1]) > 90.0][0, 1])
        raise ZoneFileError(f"{where}: latitude {bad:g} is beyond ±90° (GeoJSON order is [lon, lat])")
    return arr


def _ring(raw: Any, where: str) -> np.ndarray:
    ring = _positions(raw, where)
    if len(ring) < 4:
        raise ZoneFileError(f"{where}: a polygon ring needs at least 4 positions, got {len(ring)}")
    if not np.array_equal(ring[0], ring[-1]):
        raise ZoneFileError(f"{where}: a polygon ring must end where it starts (first position = last)")
    ring = _unwrap(ring)
    if abs(ring[-1, 0] - ring[0, 0]) > 1e-9:
        raise ZoneFileError(f"{where}: the ring goes all the way round the Earth; split it into polygons")
    return ring


def _polygon(rings: Any, where: str) -> BaseGeometry:
    """The polygon, made valid when it is not (a self-touching ring): then it may be a multi-part shape."""
    if not isinstance(rings, list) or not rings:
        raise ZoneFileError(f"{where}: a Polygon needs a list of rings")
    shell = _ring(rings[0], f"{where} ring 0")
    holes = []
    for i, raw in enumerate(rings[1:], start=1):
        hole = _ring(raw, f"{where} ring {i}")
        # A hole belongs on the same side of the antimeridian as its shell.
        hole[:, 0] += 360.0 * np.round((shell[0, 0] - hole[0, 0]) / 360.0)
        holes.append(hole)
    polygon = shapely.Polygon(shell, holes)
    return polygon if polygon.is_valid else shapely.make_valid(polygon)


def _geometry(geom: Any, where: str, allowed: Sequence[str]) -> BaseGeometry:
    if not isinstance(geom, dict) or "type" not in geom:
        raise ZoneFileError(f"{where}: missing geometry")
    kind = geom["type"]
    if kind not in allowed:
        raise ZoneFileError(f"{where}: geometry type {kind!r} is not allowed here (use {', '.join(allowed)})")
    coords = geom.get("coordinates")
    if coords is None:
        raise ZoneFileError(f"{where}: geometry has no coordinates")
    if kind == "Polygon":
        return _polygon(coords, where)
    if kind == "MultiPolygon":
        if not isinstance(coords, list) or not coords:
            raise ZoneFileError(f"{where}: a MultiPolygon needs a list of polygons")
        parts = [_polygon(p, f"{where} polygon {i}") for i, p in enumerate(coords)]
        polygons = [p for p in parts if isinstance(p, shapely.Polygon)]
        # A self-touching part comes back from make_valid as several: the zone is then their union.
        return shapely.MultiPolygon(polygons) if len(polygons) == len(parts) else shapely.union_all(parts)
    if kind == "Point":
        return shapely.Point(_positions([coords], where)[0])
    if kind == "MultiPoint":
        return shapely.MultiPoint(_positions(coords, where))
    if kind == "LineString":
        line = _unwrap(_positions(coords, where))
        if len(line) < 2:
            raise ZoneFileError(f"{where}: a LineString needs at least 2 positions")
        return shapely.LineString(line)
    lines = []
    for i, raw in enumerate(coords if isinstance(coords, list) else []):
        line = _unwrap(_positions(raw, f"{where} line {i}"))
        if len(line) < 2:
            raise ZoneFileError(f"{where} line {i}: a LineString needs at least 2 positions")
        lines.append(shapely.LineString(line))
    if not lines:
        raise ZoneFileError(f"{where}: a MultiLineString needs at least one line")
    return shapely.MultiLineString(lines)


def _read_features(path: str | Path, allowed: Sequence[str], what: str) -> tuple[Feature, ...]:
    file = Path(path)
    try:
        doc = json.loads(file.read_text(encoding="utf-8"))
    except FileNotFoundError:
        raise ZoneFileError(f"{what} file {file} does not exist") from None
    except (OSError, UnicodeDecodeError) as exc:
        raise ZoneFileError(f"{what} file {file} cannot be read: {exc}") from None
    except json.JSONDecodeError as exc:
        raise ZoneFileError(f"{what} file {file}: not JSON (line {exc.lineno}: {exc.msg})") from None
    if not isinstance(doc, dict):
        raise ZoneFileError(f"{what} file {file}: expected a GeoJSON object")
    if doc.get("type") == "FeatureCollection":
        raw_features = doc.get("features")
        if not isinstance(raw_features, list):
            raise ZoneFileError(f"{what} file {file}: a FeatureCollection needs a list of features")
    elif doc.get("type") == "Feature":
        raw_features = [doc]
    else:
        raw_features = [{"type": "Feature", "geometry": doc, "properties": {}}]
    features = []
    for i, raw in enumerate(raw_features):
        props = raw.get("properties") if isinstance(raw, dict) else None
        name = str(props.get("name", f"#{i}")) if isinstance(props, dict) else f"#{i}"
        where = f"{file} feature {i} ({name})"
        geometry = _geometry(raw.get("geometry") if isinstance(raw, dict) else None, where, allowed)
        features.append(Feature(name=name, geometry=geometry))
    if not features:
        raise ZoneFileError(f"{what} file {file} holds no features")
    return tuple(features)


def load_zones(path: str | Path) -> tuple[Feature, ...]:
    """Exclusion zones: Polygon / MultiPolygon features (``properties.name`` names them)."""
    return _read_features(path, POLYGON_TYPES, "zone")


def load_targets(path: str | Path) -> tuple[Feature, ...]:
    """Recovery targets: Point / MultiPoint / LineString / MultiLineString features."""
    return _read_features(path, TARGET_TYPES, "target")


class LocalPlane:
    """Azimuthal-equidistant plane in km around one point: distances from the centre are exact.

    Across a few hundred km (a release sweep) the scale error elsewhere is below 0.1 %.
    """

    def __init__(self, lat: float, lon: float) -> None:
        self.lat = float(lat)
        self.lon = float((lon + 180.0) % 360.0 - 180.0)
        crs = f"+proj=aeqd +lat_0={self.lat} +lon_0={self.lon} +ellps=WGS84 +units=km"
        self._forward = Transformer.from_crs("EPSG:4326", crs, always_xy=True)
        self._inverse = Transformer.from_crs(crs, "EPSG:4326", always_xy=True)

    def to_xy(self, lon: np.ndarray, lat: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        x, y = self._forward.transform(np.asarray(lon, float), np.asarray(lat, float))
        return np.asarray(x), np.asarray(y)

    def to_lonlat(self, x: np.ndarray, y: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lon, lat = self._inverse.transform(np.asarray(x, float), np.asarray(y, float))
        return (np.asarray(lon) + 180.0) % 360.0 - 180.0, np.asarray(lat)

    def covariance_in_plane(self, lon: np.ndarray, lat: np.ndarray, east_north: np.ndarray) -> np.ndarray:
        """(N, 2, 2) covariances given in local (east, north) km², turned into the plane's axes.

        Away from the centre the plane's y axis is not quite north (meridian convergence: ~2.5° at
        200 km and 60° N), so each Gaussian is rotated by the local angle of north in the plane.
        """
        lon = np.atleast_1d(np.asarray(lon, float))
        lat = np.atleast_1d(np.asarray(lat, float))
        x0, y0 = self.to_xy(lon, lat)
        step = np.where(lat < 89.0, 0.01, -0.01)
        x1, y1 = self.to_xy(lon, lat + step)
        angle = np.arctan2(x1 - x0, (y1 - y0) * np.sign(step))
        c, s = np.cos(angle), np.sin(angle)
        rotation = np.stack([np.stack([c, s], -1), np.stack([-s, c], -1)], -2)
        cov = np.broadcast_to(np.asarray(east_north, float), (lon.size, 2, 2))
        return np.einsum("nij,njk,nlk->nil", rotation, cov, rotation)

    def project(self, geometry: BaseGeometry) -> BaseGeometry:
        dense = shapely.segmentize(geometry, DENSIFY_DEG)

        def forward(coords: np.ndarray) -> np.ndarray:
            x, y = self.to_xy(coords[:, 0], coords[:, 1])
            return np.column_stack([x, y])

        projected = shapely.transform(dense, forward)
        return projected if projected.is_valid else shapely.make_valid(projected)


def _hermite_grid() -> tuple[np.ndarray, np.ndarray]:
    x, w = hermegauss(HERMITE_NODES)
    gx, gy = np.meshgrid(x, x, indexing="ij")
    weights = np.outer(w, w).ravel()
    return np.column_stack([gx.ravel(), gy.ravel()]), weights / weights.sum()


DISTANCE_NODES, DISTANCE_WEIGHTS = _hermite_grid()


def _points(centers: np.ndarray, covariances: np.ndarray, nodes: np.ndarray) -> np.ndarray:
    """(N, K, 2) points: each Gaussian's centre + its Cholesky factor applied to the standard nodes."""
    centers = np.asarray(centers, float).reshape(-1, 2)
    covariances = np.asarray(covariances, float).reshape(-1, 2, 2)
    # A tiny jitter keeps a degenerate (zero-width) Gaussian factorisable; it moves nothing measurable.
    factor = np.linalg.cholesky(covariances + np.eye(2) * 1e-12)
    return centers[:, None, :] + np.einsum("nij,kj->nki", factor, nodes)


@dataclass(frozen=True)
class ZoneHits:
    any_zone: np.ndarray
    """Probability of landing inside at least one zone, per Gaussian."""
    per_zone: np.ndarray
    """Probability per (Gaussian, zone)."""


def _ring_mass(coords: np.ndarray) -> float:
    """(1/2π)·∮ (1 − exp(−r²/2)) dθ along one ring in the whitened frame (signed by orientation).

    Along an edge a + t·d, dθ = (a × d)/r² dt, and (1 − exp(−r²/2))/r² is smooth (½ at r = 0), so an
    8-point Gauss–Legendre rule per edge of ≤ 0.25σ is accurate to far below any other error here.
    """
    a = coords[:-1]
    d = coords[1:] - coords[:-1]
    cross = a[:, 0] * d[:, 1] - a[:, 1] * d[:, 0]
    pts = a[:, None, :] + LEGENDRE_T[None, :, None] * d[:, None, :]
    r2 = (pts**2).sum(axis=-1)
    safe = np.maximum(r2, 1e-300)
    f = np.where(r2 > 1e-12, -np.expm1(-0.5 * r2) / safe, 0.5)
    return float((cross * (f @ LEGENDRE_W)).sum() / (2.0 * math.pi))


def gaussian_mass(region: BaseGeometry, center: np.ndarray, covariance: np.ndarray) -> float:
    """The probability that a 2-D normal (centre, covariance) falls inside a (multi)polygon.

    Why a boundary integral: the indicator of a polygon is discontinuous, so any fixed 2-D grid is
    biased by up to half a cell along every edge (0.2σ cells miss by 0.03). By Green's theorem the
    mass inside is a sum over the boundary of a smooth 1-D integral in the Gaussian's whitened frame,
    exact but for a Gauss–Legendre rule on smooth integrands. The region is first clipped to ±6σ
    (what lies beyond holds < 1e-8).
    """
    sd = np.sqrt(np.diag(covariance))
    lo, hi = center - CLIP_SIGMA * sd, center + CLIP_SIGMA * sd
    clipped = shapely.clip_by_rect(region, lo[0], lo[1], hi[0], hi[1])
    if clipped.is_empty:
        return 0.0
    inverse = np.linalg.inv(np.linalg.cholesky(covariance))
    whitened = shapely.transform(clipped, lambda xy: (xy - center) @ inverse.T)
    whitened = shapely.segmentize(whitened, EDGE_SIGMA)
    total = 0.0
    for part in shapely.get_parts(whitened):
        if not isinstance(part, shapely.Polygon):
            continue
        oriented = shapely.geometry.polygon.orient(part, sign=1.0)
        total += _ring_mass(np.asarray(oriented.exterior.coords))
        for hole in oriented.interiors:
            total += _ring_mass(np.asarray(hole.coords))
    return min(max(total, 0.0), 1.0)


def zone_probabilities(
    zones: Sequence[BaseGeometry], centers: np.ndarray, covariances: np.ndarray
) -> ZoneHits:
    """P(landing inside each zone, and inside any) for Gaussians given in the zones' plane (km, km²)."""
    centers = np.asarray(centers, float).reshape(-1, 2)
    covariances = np.asarray(covariances, float).reshape(-1, 2, 2)
    union = shapely.union_all(list(zones)) if zones else shapely.Polygon()
    per_zone = np.zeros((len(centers), len(zones)))
    any_zone = np.zeros(len(centers))
    for i, (center, cov) in enumerate(zip(centers, covariances, strict=True)):
        for j, zone in enumerate(zones):
            per_zone[i, j] = gaussian_mass(zone, center, cov)
        if len(zones) > 1:
            any_zone[i] = gaussian_mass(union, center, cov)
        elif zones:
            any_zone[i] = per_zone[i, 0]
    return ZoneHits(any_zone=any_zone, per_zone=per_zone)


def inside_any(zones: Sequence[BaseGeometry], x: np.ndarray, y: np.ndarray) -> np.ndarray:
    """Whether each plane point (km) is inside at least one zone (ensemble members are counted so)."""
    inside = np.zeros(np.shape(x), dtype=bool)
    for zone in zones:
        shapely.prepare(zone)
        inside |= shapely.contains_xy(zone, x, y)
    return inside


def expected_distance_km(
    targets: Sequence[BaseGeometry], centers: np.ndarray, covariances: np.ndarray
) -> np.ndarray:
    """E[distance to the nearest target] under each Gaussian (targets in the same plane, km)."""
    union = shapely.union_all(list(targets))
    shapely.prepare(union)
    pts = _points(centers, covariances, DISTANCE_NODES)
    n, k, _ = pts.shape
    distance = shapely.distance(shapely.points(pts.reshape(-1, 2)), union).reshape(n, k)
    return distance @ DISTANCE_WEIGHTS


def distance_at_center_km(targets: Sequence[BaseGeometry], centers: np.ndarray) -> np.ndarray:
    union = shapely.union_all(list(targets))
    return np.asarray(shapely.distance(shapely.points(np.asarray(centers, float).reshape(-1, 2)), union))


def ellipse_covariance(
    sigma_parallel_km: float, sigma_perpendicular_km: float, bearing_deg: float
) -> np.ndarray:
    """2×2 covariance in (east, north) km² of a Gaussian with σ along/across a bearing (° from north)."""
    b = math.radians(bearing_deg)
    along = np.array([math.sin(b), math.cos(b)])
    across = np.array([math.cos(b), -math.sin(b)])
    return sigma_parallel_km**2 * np.outer(along, along) + sigma_perpendicular_km**2 * np.outer(
        across, across
    )

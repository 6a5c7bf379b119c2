"""A strict RFC 7946 GeoJSON checker for the tests: every MUST of the RFC, and the SHOULDs that GIS
tools and check-geojson enforce (counter-clockwise exterior rings, shapes cut at ±180°).

No GeoJSON validator is in the project's lock (``jsonschema`` is not either), so the rules are written
out here from the RFC's sections, each problem naming its section and its place in the document.
"""

from __future__ import annotations

import math
from typing import Any

GEOMETRY_TYPES = {"Point", "MultiPoint", "LineString", "MultiLineString", "Polygon", "MultiPolygon",
                  "GeometryCollection"}  # fmt: skip
FORBIDDEN = {
    # §7.1: members that must not appear on an object of the type (they belong to another type).
    "FeatureCollection": {"coordinates", "geometries", "geometry", "properties"},
    "Feature": {"coordinates", "geometries", "features"},
    **{kind: {"geometry", "properties", "features"} for kind in GEOMETRY_TYPES},
}


def problems(document: Any) -> list[str]:
    """Everything wrong with ``document`` (parsed JSON), one line each; empty when it is valid."""
    found: list[str] = []
    _object(document, "$", found)
    return found


def _object(node: Any, where: str, found: list[str]) -> None:
    if not isinstance(node, dict):
        found.append(f"{where}: a GeoJSON object must be a JSON object (§3)")
        return
    kind = node.get("type")
    if kind not in GEOMETRY_TYPES | {"Feature", "FeatureCollection"}:
        found.append(f"{where}: 'type' {kind!r} is not a GeoJSON type (§1.4)")
        return
    for member in sorted(FORBIDDEN[kind] & node.keys()):
        found.append(f"{where}: a {kind} must not have '{member}' (§7.1)")
    if "bbox" in node:
        _bbox(node["bbox"], where, found)
    if kind == "FeatureCollection":
        features = node.get("features")
        if not isinstance(features, list):
            found.append(f"{where}: a FeatureCollection needs a 'features' array (§3.3)")
            return
        for index, feature in enumerate(features):
            if not isinstance(feature, dict) or feature.get("type") != "Feature":
                found.append(f"{where}.features[{index}]: each member of 'features' must be a Feature (§3.3)")
            else:
                _object(feature, f"{where}.features[{index}]", found)
    elif kind == "Feature":
        if "geometry" not in node or "properties" not in node:
            found.append(f"{where}: a Feature needs 'geometry' and 'properties' members (§3.2)")
        if node.get("geometry") is not None:
            if not isinstance(node["geometry"], dict) or node["geometry"].get("type") not in GEOMETRY_TYPES:
                found.append(f"{where}.geometry: must be a geometry object or null (§3.2)")
            else:
                _object(node["geometry"], f"{where}.geometry", found)
        if node.get("properties") is not None and not isinstance(node["properties"], dict):
            found.append(f"{where}.properties: must be an object or null (§3.2)")
        if "id" in node and not isinstance(node["id"], str | int | float):
            found.append(f"{where}.id: must be a string or a number (§3.2)")
    elif kind == "GeometryCollection":
        geometries = node.get("geometries")
        if not isinstance(geometries, list):
            found.append(f"{where}: a GeometryCollection needs a 'geometries' array (§3.1.8)")
            return
        for index, geometry in enumerate(geometries):
            _object(geometry, f"{where}.geometries[{index}]", found)
    else:
        _coordinates(kind, node.get("coordinates"), f"{where}.coordinates", found)


def _bbox(box: Any, where: str, found: list[str]) -> None:
    if not (isinstance(box, list) and len(box) in (4, 6) and all(_number(v) for v in box)):
        found.append(f"{where}.bbox: must be 2×2 or 2×3 numbers (§5)")


def _number(value: Any) -> bool:
    return isinstance(value, int | float) and not isinstance(value, bool) and math.isfinite(value)


def _position(value: Any, where: str, found: list[str]) -> bool:
    if not (isinstance(value, list) and 2 <= len(value) <= 3 and all(_number(v) for v in value)):
        found.append(f"{where}: a position is 2 or 3 finite numbers (§3.1.1)")
        return False
    lon, lat = value[0], value[1]
    if not (-180.0 <= lon <= 180.0 and -90.0 <= lat <= 90.0):
        found.append(f"{where}: ({lon}, {lat}) is outside longitude -180…180, latitude -90…90 (§4)")
        return False
    return True


def _positions(value: Any, where: str, found: list[str], least: int) -> list[list[float]] | None:
    if not isinstance(value, list) or len(value) < least:
        found.append(f"{where}: needs an array of at least {least} positions (§3.1)")
        return None
    ok = [_position(p, f"{where}[{i}]", found) for i, p in enumerate(value)]
    return value if all(ok) else None


def _line(value: Any, where: str, found: list[str]) -> None:
    points = _positions(value, where, found, 2)
    if points is not None:
        _not_across_the_antimeridian(points, where, found)


def _ring(value: Any, where: str, found: list[str], exterior: bool) -> None:
    points = _positions(value, where, found, 4)
    if points is None:
        return
    if points[0] != points[-1]:
        found.append(f"{where}: a linear ring must end where it starts (§3.1.6)")
    _not_across_the_antimeridian(points, where, found)
    area2 = sum(a[0] * b[1] - b[0] * a[1] for a, b in zip(points, points[1:], strict=False))
    if exterior and area2 <= 0:
        found.append(f"{where}: an exterior ring runs counter-clockwise (§3.1.6, right-hand rule)")
    if not exterior and area2 >= 0:
        found.append(f"{where}: a hole runs clockwise (§3.1.6, right-hand rule)")


def _not_across_the_antimeridian(points: list[list[float]], where: str, found: list[str]) -> None:
    for index, (a, b) in enumerate(zip(points, points[1:], strict=False)):
        if abs(b[0] - a[0]) > 180.0:
            found.append(
                f"{where}[{index}]: a step of {b[0] - a[0]:.1f}° of longitude: cut it at ±180° (§3.1.9)"
            )
            return


def _coordinates(kind: str, value: Any, where: str, found: list[str]) -> None:
    if kind == "Point":
        _position(value, where, found)
    elif kind == "MultiPoint":
        _positions(value, where, found, 0)
    elif kind == "LineString":
        _line(value, where, found)
    elif kind == "MultiLineString" or kind == "Polygon":
        if not isinstance(value, list):
            found.append(f"{where}: must be an array (§3.1)")
            return
        for index, part in enumerate(value):
            if kind == "MultiLineString":
                _line(part, f"{where}[{index}]", found)
            else:
                _ring(part, f"{where}[{index}]", found, exterior=index == 0)
    elif kind == "MultiPolygon":
        if not isinstance(value, list):
            found.append(f"{where}: must be an array (§3.1.7)")
            return
        for index, polygon in enumerate(value):
            _coordinates("Polygon", polygon, f"{where}[{index}]", found)

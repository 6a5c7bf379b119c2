"""GeoJSON (RFC 7946) features that each carry the product's provenance and demo status.

GIS tools (QGIS, ogr2ogr) drop a FeatureCollection's own members and keep only each feature's
properties, so a demo warning written once at the top vanishes as the file opens: every feature
repeats it.

The collection's own facts (title, source, DEMO, warnings, a plan's verdict) are a foreign member,
``"drs"`` (RFC 7946 §6.1): a FeatureCollection must not have ``properties`` (§7.1). A position
given again as a feature's ``lat``/``lon`` properties keeps the coordinates' 6 decimals (0.1 m).
"""

from __future__ import annotations

import json
import math
from collections.abc import Mapping, Sequence
from dataclasses import dataclass
from typing import Any

from predictor.geofiles import DEMO_LABEL
from predictor.geofiles.geometry import DEGREE_DECIMALS, Coordinate, line_parts, polygon_parts, position

Geometry = dict[str, Any]


@dataclass(frozen=True)
class Provenance:
    title: str
    """What the file is, naming demo weather when it is demo (e.g. "DRS landing prediction ...")."""
    source: str
    """Where the numbers came from: the weather source, or the reports a track was built from."""
    is_demo: bool

    def properties(self) -> dict[str, Any]:
        return {
            "title": self.title,
            "source": self.source,
            "is_demo": self.is_demo,
            "demo": DEMO_LABEL if self.is_demo else None,
        }


def point(where: Sequence[float]) -> Geometry:
    return {"type": "Point", "coordinates": list(position(where))}


def multipoint(points: Sequence[Sequence[float]]) -> Geometry:
    return {"type": "MultiPoint", "coordinates": [list(position(p)) for p in points]}


def line(points: Sequence[Sequence[float]]) -> Geometry:
    """A LineString, or a MultiLineString cut at ±180° (RFC 7946 §3.1.9)."""
    parts = line_parts(points)
    if len(parts) == 1:
        return {"type": "LineString", "coordinates": _lists(parts[0])}
    return {"type": "MultiLineString", "coordinates": [_lists(p) for p in parts]}


def polygon(ring: Sequence[Sequence[float]]) -> Geometry:
    """A counter-clockwise Polygon, or a MultiPolygon cut at ±180° (RFC 7946 §3.1.6, §3.1.9)."""
    parts = polygon_parts(ring)
    if len(parts) == 1:
        return {"type": "Polygon", "coordinates": [_lists(parts[0])]}
    return {"type": "MultiPolygon", "coordinates": [[_lists(p)] for p in parts]}


def _lists(points: Sequence[Coordinate]) -> list[list[float]]:
    return [list(p) for p in points]


COLLECTION_MEMBER = "drs"
"""The FeatureCollection's foreign member holding what the whole file is."""


def feature(geometry: Geometry, kind: str, provenance: Provenance, **properties: Any) -> dict[str, Any]:
    return {
        "type": "Feature",
        "geometry": geometry,
        "properties": {"kind": kind, **_rounded_positions(_json_safe(properties)), **provenance.properties()},
    }


def _rounded_positions(properties: dict[str, Any]) -> dict[str, Any]:
    """``lat``/``lon`` (and ``*_lat``/``*_lon``) to the coordinates' decimals: no false precision."""
    return {
        name: round(value, DEGREE_DECIMALS)
        if isinstance(value, float) and (name in ("lat", "lon") or name.endswith(("_lat", "_lon")))
        else value
        for name, value in properties.items()
    }


def _json_safe(value: Any) -> Any:
    """NaN and infinity (an unknown number) as null: JSON has no NaN, and GIS readers reject it."""
    if isinstance(value, float) and not math.isfinite(value):
        return None
    if isinstance(value, Mapping):
        return {k: _json_safe(v) for k, v in value.items()}
    if isinstance(value, list | tuple):
        return [_json_safe(v) for v in value]
    return value


def collection(
    features: Sequence[Mapping[str, Any]], provenance: Provenance, **properties: Any
) -> dict[str, Any]:
    return {
        "type": "FeatureCollection",
        COLLECTION_MEMBER: {**_json_safe(properties), **provenance.properties()},
        "features": list(features),
    }


def dumps(document: Mapping[str, Any]) -> str:
    return json.dumps(document, indent=1, ensure_ascii=False, allow_nan=False)

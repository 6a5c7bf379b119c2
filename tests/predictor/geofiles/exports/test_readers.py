"""Every GPX read with gpxpy and every GeoJSON with shapely, as handhelds and GIS tools read them."""

from __future__ import annotations

import json
import math
from collections.abc import Iterator
from typing import Any

import gpxpy
import pytest
import shapely
from pyproj import Geod
from shapely.geometry import shape

from tests.predictor.geofiles.exports.conftest import PRODUCTS, Written

GEOD = Geod(ellps="WGS84")
GEOJSON = [p for p in PRODUCTS if not p.startswith("recovery")]
GPX = [p for p in PRODUCTS if not p.startswith("plan")]


def _refuse(constant: str) -> float:
    raise AssertionError(f"the JSON holds {constant}, which is not JSON")


def _features(written: Written) -> list[dict[str, Any]]:
    assert written.geojson is not None
    document = json.loads(written.geojson, parse_constant=_refuse)
    assert document["type"] == "FeatureCollection"
    return document["features"]


def _numbers(coordinates: Any) -> Iterator[float]:
    if isinstance(coordinates, list):
        for item in coordinates:
            yield from _numbers(item)
    else:
        yield coordinates


def _parts(geometry: shapely.Geometry) -> list[shapely.Geometry]:
    return list(geometry.geoms) if hasattr(geometry, "geoms") else [geometry]


@pytest.mark.parametrize("product", GEOJSON)
def test_geojson_geometries_are_valid_counter_clockwise_rounded_and_within_the_globe(
    products: dict[str, Written], product: str
) -> None:
    for feature in _features(products[product]):
        geometry = shape(feature["geometry"])
        assert geometry.is_valid, (feature["properties"]["kind"], shapely.is_valid_reason(geometry))
        assert all(round(v, 6) == v for v in _numbers(feature["geometry"]["coordinates"]))
        for part in _parts(geometry):
            west, south, east, north = part.bounds
            assert -180.0 <= west and east <= 180.0 and -90.0 <= south and north <= 90.0
            if part.geom_type != "Point":
                assert east - west < 5.0, (
                    f"{feature['properties']['kind']} spans {east - west:.1f}° of longitude"
                )
            if part.geom_type == "Polygon":
                assert shapely.is_ccw(part.exterior), "RFC 7946 §3.1.6: exterior rings run counter-clockwise"


@pytest.mark.parametrize("product", GEOJSON)
def test_every_geojson_feature_carries_demo_status_and_provenance(
    products: dict[str, Written], product: str
) -> None:
    written = products[product]
    for feature in _features(written):
        properties = feature["properties"]
        assert properties["is_demo"] is written.is_demo
        assert properties["source"] and properties["title"].startswith("DRS")
        assert ("DEMO WEATHER" in properties["title"]) is written.is_demo
        assert (properties["demo"] == "DEMO WEATHER, NOT A FORECAST") is written.is_demo


@pytest.mark.parametrize("product", [p for p in GEOJSON if "180" in p])
def test_geojson_cut_at_the_antimeridian_keeps_each_shape_its_size(
    products: dict[str, Written], product: str
) -> None:
    """A band round the globe would measure thousands of km; the cut parts add up to the shape itself."""
    cut = set()
    for feature in _features(products[product]):
        geometry = shape(feature["geometry"])
        cut |= {geometry.geom_type} & {"MultiLineString", "MultiPolygon"}
        properties = feature["properties"]
        if "semi_major_km" in properties:
            area_km2 = abs(sum(GEOD.geometry_area_perimeter(p)[0] for p in _parts(geometry))) / 1e6
            expected = math.pi * properties["semi_major_km"] * properties["semi_minor_km"]
            assert area_km2 == pytest.approx(expected, rel=0.01)
        if geometry.geom_type == "MultiLineString":
            parts = [GEOD.geometry_length(p) for p in _parts(geometry)]
            joined = [c for p in _parts(geometry) for c in p.coords]
            whole = sum(GEOD.inv(a[0], a[1], b[0], b[1])[2] for a, b in zip(joined, joined[1:], strict=False))
            assert sum(parts) == pytest.approx(whole, rel=1e-3)
    straddles = {"MultiLineString", "MultiPolygon"} if product.startswith("predict") else {"MultiLineString"}
    assert cut >= straddles, f"the product was meant to straddle ±180° but only {cut or 'nothing'} was cut"


@pytest.mark.parametrize("product", GPX)
def test_gpx_reads_in_gpxpy_with_short_ascii_names_symbols_and_no_nan(
    products: dict[str, Written], product: str
) -> None:
    written = products[product]
    assert written.gpx is not None
    assert "nan" not in written.gpx.lower() and written.gpx.isascii()
    gpx = gpxpy.parse(written.gpx)
    names = [w.name for w in gpx.waypoints]
    assert any(name.endswith("PRED LAND") for name in names), names
    for waypoint in gpx.waypoints:
        assert waypoint.name and len(waypoint.name) <= 14 and waypoint.name.upper() == waypoint.name
        assert waypoint.symbol and waypoint.description
        assert waypoint.name.startswith("DEMO") is written.is_demo
        assert -180.0 <= waypoint.longitude < 180.0 and math.isfinite(waypoint.elevation)
    points = [p for track in gpx.tracks for segment in track.segments for p in segment.points]
    assert points and all(math.isfinite(p.elevation) and -180.0 <= p.longitude < 180.0 for p in points)


@pytest.mark.parametrize("product", [p for p in GPX if p.startswith("recovery")])
def test_recovery_gpx_of_a_single_fix_landing_says_so_instead_of_nan(
    products: dict[str, Written], product: str
) -> None:
    """Flight 18-8-3 lands on one fix: there is no scatter to give, and the waypoint says so."""
    gpx = gpxpy.parse(products[product].gpx)
    [landing] = [w for w in gpx.waypoints if w.name == "DRS1 LAND"]
    assert landing.symbol == "Flag, Red" and "1 fix kept" in landing.description

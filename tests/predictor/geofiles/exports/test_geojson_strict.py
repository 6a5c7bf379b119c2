"""Every GeoJSON the project writes passes a strict RFC 7946 check (issue #25 item 4), and every GPX
track that crosses ±180° comes back from gpxpy as one segment per side (item 5)."""

from __future__ import annotations

import json
from datetime import UTC, datetime, timedelta
from typing import Any

import gpxpy
import pytest

from predictor.geofiles import gpx
from predictor.geofiles.geojson import COLLECTION_MEMBER
from tests.predictor.geofiles.exports.conftest import PRODUCTS, Written
from tests.predictor.geofiles.exports.rfc7946 import problems

GEOJSON = [p for p in PRODUCTS if not p.startswith("recovery")]
GPX_ACROSS = [p for p in PRODUCTS if "180" in p and not p.startswith("plan")]


@pytest.mark.parametrize("product", GEOJSON)
def test_every_geojson_passes_a_strict_rfc_7946_check(products: dict[str, Written], product: str) -> None:
    assert products[product].geojson is not None
    document = json.loads(products[product].geojson)
    assert problems(document) == []
    assert "properties" not in document, "RFC 7946 §7.1: a FeatureCollection has no 'properties'"
    about = document[COLLECTION_MEMBER]
    assert about["title"].startswith("DRS") and about["is_demo"] is products[product].is_demo


@pytest.mark.parametrize("product", GEOJSON)
def test_feature_lat_and_lon_properties_keep_the_coordinates_six_decimals(
    products: dict[str, Written], product: str
) -> None:
    assert products[product].geojson is not None
    seen = 0
    for feature in json.loads(products[product].geojson)["features"]:
        for name, value in feature["properties"].items():
            if name in ("lat", "lon") or name.endswith(("_lat", "_lon")):
                assert isinstance(value, float) and round(value, 6) == value, (name, value)
                seen += 1
    assert seen or product.startswith("plan"), "a prediction's release and landing carry lat/lon"


@pytest.mark.parametrize(
    ("document", "says"),
    [
        (
            {"type": "FeatureCollection", "features": [], "properties": {}},
            "must not have 'properties' (§7.1)",
        ),
        ({"type": "Feature", "geometry": None}, "needs 'geometry' and 'properties'"),
        ({"type": "Feature", "properties": {}, "geometry": {"type": "Point", "coordinates": [190, 0]}}, "§4"),
        ({"type": "LineString", "coordinates": [[179.5, 0], [-179.5, 0]]}, "cut it at ±180°"),
        ({"type": "Polygon", "coordinates": [[[0, 0], [0, 1], [1, 1], [1, 0], [0, 0]]]}, "counter-clockwise"),
        ({"type": "Polygon", "coordinates": [[[0, 0], [1, 0], [1, 1], [0, 1]]]}, "end where it starts"),
        ({"type": "Point", "coordinates": [0, float("nan")]}, "finite numbers"),
    ],
)
def test_the_checker_refuses_what_the_rfc_forbids(document: dict[str, Any], says: str) -> None:
    """The check above can fail: each of these is one rule broken."""
    assert any(says in problem for problem in problems(document)), problems(document)


def test_a_gpx_track_across_180_is_one_segment_per_side() -> None:
    start = datetime(2024, 5, 1, 6, tzinfo=UTC)
    lons = [179.2, 179.6, 179.95, -179.7, -179.3, -179.8, 179.9, 179.5]
    points = [gpx.TrackPoint(-44.7 + 0.01 * i, lon, 1000.0 - 100 * i, start + timedelta(minutes=i))
              for i, lon in enumerate(lons)]  # fmt: skip
    parsed = gpxpy.parse(gpx.to_gpx("test", [], [("across", points)]))
    [track] = parsed.tracks
    sides = [[p.longitude for p in segment.points] for segment in track.segments]
    assert sides == [[179.2, 179.6, 179.95], [-179.7, -179.3, -179.8], [179.9, 179.5]]
    for segment in track.segments:
        steps = [
            abs(b.longitude - a.longitude) for a, b in zip(segment.points, segment.points[1:], strict=False)
        ]
        assert max(steps, default=0.0) < 1.0, "no segment draws a line across the map"


@pytest.mark.parametrize("product", GPX_ACROSS)
def test_every_gpx_track_written_across_180_is_split_there(
    products: dict[str, Written], product: str
) -> None:
    assert products[product].gpx is not None
    parsed = gpxpy.parse(products[product].gpx)
    segments = [s for t in parsed.tracks for s in t.segments]
    assert len(segments) > len(parsed.tracks), "a track crossing ±180° has more than one segment"
    for segment in segments:
        lons = [p.longitude for p in segment.points]
        assert all(abs(b - a) < 180.0 for a, b in zip(lons, lons[1:], strict=False))

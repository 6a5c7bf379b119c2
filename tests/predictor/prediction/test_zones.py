"""Zone probability and target distance over a landing Gaussian, against Monte-Carlo counting."""

from __future__ import annotations

import json
from pathlib import Path
from typing import Any

import numpy as np
import pytest
import shapely

from predictor.errors import PredictorError
from predictor.prediction.zones import (
    LocalPlane,
    ellipse_covariance,
    expected_distance_km,
    load_targets,
    load_zones,
    zone_probabilities,
)

MC_SAMPLES = 200_000


def write_geojson(path: Path, geometries: list[dict[str, Any]], names: list[str] | None = None) -> Path:
    names = names or [f"z{i}" for i in range(len(geometries))]
    features = [
        {"type": "Feature", "properties": {"name": n}, "geometry": g}
        for n, g in zip(names, geometries, strict=True)
    ]
    path.write_text(json.dumps({"type": "FeatureCollection", "features": features}))
    return path


def polygon(ring: list[tuple[float, float]]) -> dict[str, Any]:
    return {"type": "Polygon", "coordinates": [[list(p) for p in ring]]}


def monte_carlo_in_lonlat(
    plane: LocalPlane, center_lonlat: tuple[float, float], cov: np.ndarray, inside_lonlat: Any
) -> float:
    """Draw landings in km around the centre, map them to lon/lat, and count with a lon/lat test."""
    rng = np.random.default_rng(1)
    cx, cy = plane.to_xy(np.array([center_lonlat[0]]), np.array([center_lonlat[1]]))
    xy = rng.multivariate_normal([cx[0], cy[0]], cov, MC_SAMPLES)
    lon, lat = plane.to_lonlat(xy[:, 0], xy[:, 1])
    return float(np.mean(inside_lonlat(lon, lat)))


def test_probability_matches_monte_carlo_for_an_ellipse_partly_over_a_polygon(tmp_path: Path) -> None:
    # A lake-shaped (concave) polygon; the ellipse's centre is outside, its tail over the lake.
    ring = [(6.0, 46.0), (6.3, 46.0), (6.3, 46.2), (6.15, 46.1), (6.0, 46.2), (6.0, 46.0)]
    (zone,) = load_zones(write_geojson(tmp_path / "z.geojson", [polygon(ring)]))
    plane = LocalPlane(46.0, 6.0)
    projected = plane.project(zone.geometry)
    center = (6.12, 45.97)
    cov = ellipse_covariance(6.0, 2.5, 60.0)
    cx, cy = plane.to_xy(np.array([center[0]]), np.array([center[1]]))
    cov_plane = plane.covariance_in_plane(center[0], center[1], cov)
    hits = zone_probabilities([projected], np.array([[cx[0], cy[0]]]), cov_plane)
    lonlat = shapely.Polygon(ring)
    expected = monte_carlo_in_lonlat(
        plane, center, cov_plane[0], lambda x, y: shapely.contains_xy(lonlat, x, y)
    )
    assert 0.15 < expected < 0.6, "the test must put the ellipse partly over the zone"
    assert hits.any_zone[0] == pytest.approx(expected, abs=0.005)
    centre_inside = shapely.contains_xy(lonlat, *center)
    assert not centre_inside, "the point test at the centre would say 0: the integral is what matters"


def test_probability_is_exact_for_a_half_plane_and_a_disc() -> None:
    from math import erf, exp, sqrt

    # A Gaussian 1σ (along its major axis) from the edge of a half-plane, rotated: P = Φ(−1).
    cov = ellipse_covariance(3.0, 1.0, 0.0)
    half_plane = shapely.box(-100.0, 3.0, 100.0, 100.0)
    got = zone_probabilities([half_plane], np.zeros((1, 2)), cov[None]).any_zone[0]
    assert got == pytest.approx(0.5 * (1 + erf(-1 / sqrt(2))), abs=1e-6)
    # An isotropic Gaussian at the centre of a (finely polygonised) disc of radius R: 1 − exp(−R²/2σ²).
    disc = shapely.Point(0.0, 0.0).buffer(2.0, quad_segs=512)
    got = zone_probabilities([disc], np.zeros((1, 2)), np.eye(2)[None] * 1.5**2).any_zone[0]
    assert got == pytest.approx(1 - exp(-(2.0**2) / (2 * 1.5**2)), abs=1e-4)


def test_probability_of_two_overlapping_zones_counts_the_union_once(tmp_path: Path) -> None:
    a = polygon([(0.0, 0.0), (0.2, 0.0), (0.2, 0.2), (0.0, 0.2), (0.0, 0.0)])
    b = polygon([(0.1, 0.0), (0.3, 0.0), (0.3, 0.2), (0.1, 0.2), (0.1, 0.0)])
    zones = load_zones(write_geojson(tmp_path / "z.geojson", [a, b]))
    plane = LocalPlane(0.1, 0.1)
    hits = zone_probabilities(
        [plane.project(z.geometry) for z in zones], np.zeros((1, 2)), np.eye(2)[None] * 25.0
    )
    union = shapely.box(0.0, 0.0, 0.3, 0.2)
    expected = monte_carlo_in_lonlat(
        plane, (0.1, 0.1), np.eye(2) * 25.0, lambda x, y: shapely.contains_xy(union, x, y)
    )
    assert hits.any_zone[0] == pytest.approx(expected, abs=0.005)
    assert hits.any_zone[0] < hits.per_zone[0].sum() - 0.05


def antimeridian_probability(path: Path, center_lon: float) -> float:
    (zone,) = load_zones(path)
    plane = LocalPlane(-45.0, 180.0)
    cov = ellipse_covariance(8.0, 4.0, 100.0)
    cx, cy = plane.to_xy(np.array([center_lon]), np.array([-45.02]))
    return float(
        zone_probabilities(
            [plane.project(zone.geometry)],
            np.array([[cx[0], cy[0]]]),
            plane.covariance_in_plane(center_lon, -45.02, cov),
        ).any_zone[0]
    )


def test_polygon_crossing_the_antimeridian_in_every_spelling_gives_the_monte_carlo_answer(
    tmp_path: Path,
) -> None:
    # One 0.2°×0.1° box straddling 180°, written three ways: wrapping (179.9 → -179.9), continuous
    # (179.9 → 180.1), and split at ±180 into a MultiPolygon as RFC 7946 recommends.
    wrapped = polygon([(179.9, -45.1), (-179.9, -45.1), (-179.9, -45.0), (179.9, -45.0), (179.9, -45.1)])
    continuous = polygon([(179.9, -45.1), (180.1, -45.1), (180.1, -45.0), (179.9, -45.0), (179.9, -45.1)])
    split = {
        "type": "MultiPolygon",
        "coordinates": [
            [[[179.9, -45.1], [180.0, -45.1], [180.0, -45.0], [179.9, -45.0], [179.9, -45.1]]],
            [[[-180.0, -45.1], [-179.9, -45.1], [-179.9, -45.0], [-180.0, -45.0], [-180.0, -45.1]]],
        ],
    }
    box = shapely.box(179.9, -45.1, 180.1, -45.0)
    plane = LocalPlane(-45.0, 180.0)
    for center_lon in (179.97, -179.97):
        cov = plane.covariance_in_plane(center_lon, -45.02, ellipse_covariance(8.0, 4.0, 100.0))[0]
        expected = monte_carlo_in_lonlat(
            plane,
            (center_lon, -45.02),
            cov,
            lambda x, y: shapely.contains_xy(box, np.where(x < 0, x + 360, x), y),
        )
        assert 0.05 < expected < 0.5
        for i, geom in enumerate((wrapped, continuous, split)):
            got = antimeridian_probability(write_geojson(tmp_path / f"a{i}.geojson", [geom]), center_lon)
            assert got == pytest.approx(expected, abs=0.005), (i, center_lon)


def test_a_ring_is_joined_the_short_way_round(tmp_path: Path) -> None:
    # Without unwrapping, 170 → -170 would be a 340°-wide polygon covering the whole latitude band.
    geom = {"type": "Polygon", "coordinates": [[[170, 10], [-170, 10], [-170, 11], [170, 11], [170, 10]]]}
    path = tmp_path / "short.geojson"
    path.write_text(json.dumps(geom))
    (zone,) = load_zones(path)
    assert zone.geometry.bounds[2] - zone.geometry.bounds[0] == pytest.approx(20.0)


def test_a_bow_tie_part_of_a_multipolygon_is_its_two_triangles(tmp_path: Path) -> None:
    """A self-crossing part is made valid as two triangles (it once stopped the file with a ValueError)."""
    bow_tie = [[[0, 0], [1, 1], [1, 0], [0, 1], [0, 0]]]
    square = [[[5, 5], [6, 5], [6, 6], [5, 6], [5, 5]]]
    path = write_geojson(
        tmp_path / "bow.geojson", [{"type": "MultiPolygon", "coordinates": [bow_tie, square]}]
    )
    (zone,) = load_zones(path)
    assert zone.geometry.area == pytest.approx(0.5 + 1.0)
    assert zone.geometry.contains(shapely.Point(0.2, 0.5)) and not zone.geometry.contains(
        shapely.Point(0.5, 0.2)
    )


def test_expected_distance_to_a_road_matches_monte_carlo(tmp_path: Path) -> None:
    road = {"type": "LineString", "coordinates": [[10.0, 60.0], [10.3, 60.1], [10.6, 60.05]]}
    (target,) = load_targets(write_geojson(tmp_path / "t.geojson", [road]))
    plane = LocalPlane(60.0, 10.0)
    line_xy = plane.project(target.geometry)
    center = np.array([[12.0, 2.0]])
    cov = ellipse_covariance(4.0, 2.0, 30.0)[None]
    got = expected_distance_km([line_xy], center, cov)[0]
    rng = np.random.default_rng(2)
    xy = rng.multivariate_normal(center[0], cov[0], 50_000)
    mc = float(np.mean(shapely.distance(shapely.points(xy), line_xy)))
    assert got == pytest.approx(mc, rel=0.02)
    assert got > float(shapely.distance(shapely.Point(center[0]), line_xy)) - 1e-9


@pytest.mark.parametrize(
    ("content", "message"),
    [
        ("not json", "not JSON"),
        ('{"type": "FeatureCollection", "features": []}', "holds no features"),
        ('{"type": "Point", "coordinates": [1, 2]}', "not allowed here"),
        ('{"type": "Polygon", "coordinates": [[[0,0],[1,0],[1,1],[0,0.5]]]}', "must end where it starts"),
        ('{"type": "Polygon", "coordinates": [[[0,0],[1,0],[0,0]]]}', "at least 4 positions"),
        ('{"type": "Polygon", "coordinates": [[[0,0],[0,95],[1,1],[0,0]]]}', "beyond ±90°"),
        ('{"type": "Polygon", "coordinates": [[[0,0],["a",1],[1,1],[0,0]]]}', "number pairs"),
        ('{"type": "Polygon"}', "no coordinates"),
    ],
)
def test_bad_zone_files_are_refused_with_a_specific_message(
    tmp_path: Path, content: str, message: str
) -> None:
    path = tmp_path / "bad.geojson"
    path.write_text(content)
    with pytest.raises(PredictorError, match=message):
        load_zones(path)


def test_missing_zone_file_and_polygon_targets_are_refused(tmp_path: Path) -> None:
    with pytest.raises(PredictorError, match="does not exist"):
        load_zones(tmp_path / "nope.geojson")
    path = write_geojson(tmp_path / "t.geojson", [polygon([(0, 0), (1, 0), (1, 1), (0, 0)])])
    with pytest.raises(PredictorError, match="not allowed here"):
        load_targets(path)

"""The shared rules of every geographic export: cutting at ±180°, ring direction, handheld names."""

from __future__ import annotations

import math

import pytest
import shapely
from shapely.geometry import LineString, Polygon

from predictor.geofiles.geometry import line_parts, polygon_parts, position
from predictor.geofiles.gpx import NAME_LENGTH, ascii_text, short_name


def test_a_path_across_the_antimeridian_is_cut_where_it_crosses_with_its_altitude_interpolated() -> None:
    east, west = line_parts([(179.8, -45.0, 3000.0), (179.9, -45.1, 2000.0), (-179.9, -45.3, 1000.0)])
    assert east[-1] == (180.0, -45.2, 1500.0) and west[0] == (-180.0, -45.2, 1500.0)
    assert east[0] == (179.8, -45.0, 3000.0) and west[-1] == (-179.9, -45.3, 1000.0)


def test_a_path_keeps_its_points_unwrapped_longitudes_wrapped_and_gaps_dropped() -> None:
    [line] = line_parts([(190.0, 1.0), (math.nan, 1.5), (191.0, 2.0)])
    assert line == [(-170.0, 1.0), (-169.0, 2.0)]
    assert line_parts([(5.0, 1.0)]) == [] and line_parts([]) == []


def test_a_clockwise_ring_comes_out_counter_clockwise_and_a_straddling_one_in_two_pieces() -> None:
    clockwise = [(1.0, 1.0), (1.0, 2.0), (2.0, 2.0), (2.0, 1.0), (1.0, 1.0)]
    assert not shapely.is_ccw(LineString(clockwise))
    [ring] = polygon_parts(clockwise)
    assert shapely.is_ccw(LineString(ring)) and Polygon(ring).area == pytest.approx(1.0)
    straddling = [(179.5, -45.0), (179.5, -44.0), (-179.5, -44.0), (-179.5, -45.0), (179.5, -45.0)]
    pieces = polygon_parts(straddling)
    assert len(pieces) == 2 and all(shapely.is_ccw(LineString(p)) for p in pieces)
    assert sum(Polygon(p).area for p in pieces) == pytest.approx(1.0)


def test_a_position_is_rounded_to_six_decimals_and_a_nan_is_refused() -> None:
    assert position((185.123456789, -44.0000004, 12.345)) == (-174.876543, -44.0, 12.3)
    with pytest.raises(ValueError, match="finite"):
        position((5.0, math.nan))


def test_handheld_names_are_short_upper_case_ascii_and_keep_what_the_point_is() -> None:
    assert short_name("Wānaka capsule ±2", "PRED LAND") == "WANA PRED LAND"
    assert len(short_name("a" * 40, "LAND")) == NAME_LENGTH
    assert ascii_text("±12 m, 1σ at 90°") == "+/-12 m, 1sigma at 90 deg"

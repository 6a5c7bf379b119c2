"""The braille landing map: where things are drawn, honest distances, zones, scale bar, antimeridian."""

from __future__ import annotations

import math
import re

from console.widgets.landing_map import BRAILLE_BASE, KM_PER_DEG_LAT, MapLayers, render_map

LAT = 67.9


def lon_offset(km: float, lat: float = LAT) -> float:
    return km / (KM_PER_DEG_LAT * math.cos(math.radians(lat)))


def lat_offset(km: float) -> float:
    return km / KM_PER_DEG_LAT


def map_rows(lines: list[str]) -> list[str]:
    """The map itself: every line above the scale bar."""
    return lines[: next(i for i, line in enumerate(lines) if line.startswith("├"))]


def scale_line(lines: list[str]) -> str:
    return lines[len(map_rows(lines))]


def find(lines: list[str], glyph: str) -> tuple[int, int]:
    """Row and column of a marker on the map (not in the legend)."""
    hits = [(row, line.index(glyph)) for row, line in enumerate(map_rows(lines)) if glyph in line]
    assert len(hits) == 1, f"{glyph!r} drawn {len(hits)} times"
    return hits[0]


def draw(layers: MapLayers, width: int = 60, height: int = 20) -> list[str]:
    return render_map(layers, width, height).plain.split("\n")


def is_braille(char: str) -> bool:
    return BRAILLE_BASE < ord(char) <= BRAILLE_BASE + 0xFF


def test_map_fills_exactly_the_cells_it_is_given() -> None:
    layers = MapLayers(release=(21.0, LAT), landing=(21.0 + lon_offset(30), LAT + lat_offset(5)))
    for width, height in ((20, 6), (40, 15), (78, 20)):
        lines = draw(layers, width, height)
        assert len(lines) == height
        assert all(len(line) <= width for line in lines)


def test_north_is_up_and_east_is_right() -> None:
    release = (21.0, LAT)
    lines = draw(
        MapLayers(release=release, landing=(21.0 + lon_offset(20), LAT), team=(21.0, LAT + lat_offset(10)))
    )
    release_at, landing_at, team_at = find(lines, "R"), find(lines, "X"), find(lines, "T")
    assert landing_at[1] > release_at[1] and landing_at[0] == release_at[0]
    assert team_at[0] < release_at[0] and team_at[1] == release_at[1]


def test_kilometres_east_and_north_take_the_same_dots() -> None:
    """A cell is two dots wide and four tall, and twice as tall as wide: 10 km is 10 km either way."""
    lines = draw(
        MapLayers(
            release=(21.0, LAT), landing=(21.0 + lon_offset(20), LAT), team=(21.0, LAT + lat_offset(20))
        ),
        width=70,
        height=22,
    )
    (r_row, r_col), x_col, t_row = find(lines, "R"), find(lines, "X")[1], find(lines, "T")[0]
    east_dots = (x_col - r_col) * 2
    north_dots = (r_row - t_row) * 4
    assert abs(east_dots - north_dots) <= 4, (east_dots, north_dots)


def test_path_is_drawn_without_gaps_from_release_to_landing() -> None:
    release, landing = (21.0, LAT), (21.0 + lon_offset(40), LAT)
    path = [(release[0] + (landing[0] - release[0]) * i / 3, LAT) for i in range(4)]
    lines = draw(MapLayers(path=path, release=release, landing=landing))
    row, start = find(lines, "R")
    end = find(lines, "X")[1]
    between = lines[row][start + 1 : end]
    assert between and all(is_braille(c) for c in between), between


def test_ellipse_is_a_ring_around_the_landing_not_a_filled_blob() -> None:
    landing = (21.0, LAT)
    ring = [(21.0 + lon_offset(8 * math.cos(a)), LAT + lat_offset(4 * math.sin(a)))
            for a in (i * 2 * math.pi / 48 for i in range(48))]  # fmt: skip
    lines = draw(MapLayers(ellipse=ring, landing=landing, release=(21.0 - lon_offset(30), LAT)))
    row, col = find(lines, "X")
    right = lines[row][col + 1 :]
    first_dot = next(i for i, c in enumerate(right) if is_braille(c))
    assert first_dot > 0, "the ring should leave space between the landing and its 2σ edge"
    assert right[first_dot + 2 :].strip() == "", "the ring's edge is at most two cells thick"
    assert any(is_braille(c) for c in lines[row - 2]) and any(is_braille(c) for c in lines[row + 2])


def test_exclusion_zone_is_shaded_inside_and_not_outside() -> None:
    zone = [(21.0, LAT), (21.0 + lon_offset(10), LAT), (21.0 + lon_offset(10), LAT + lat_offset(10)),
            (21.0, LAT + lat_offset(10))]  # fmt: skip
    inside = (21.0 + lon_offset(5), LAT + lat_offset(5))
    outside = (21.0 + lon_offset(30), LAT + lat_offset(5))
    lines = draw(MapLayers(zones=[zone], landing=outside, release=(21.0 - lon_offset(10), LAT)))
    text = "\n".join(map_rows(lines))
    assert "░" in text
    x_row, x_col = find(lines, "X")
    assert "░" not in lines[x_row][x_col:]
    assert "X" not in text.split("░")[0].split("\n")[-1]
    shaded_rows = [r for r, line in enumerate(lines) if "░" in line]
    zone_rows = range(min(shaded_rows), max(shaded_rows) + 1)
    assert x_row in zone_rows, "the landing is at the zone's latitude, so on one of its rows"
    lines_with_inside = draw(MapLayers(zones=[zone], landing=inside, release=(21.0 - lon_offset(10), LAT)))
    row, col = find(lines_with_inside, "X")
    assert "░" in lines_with_inside[row][:col] and "░" in lines_with_inside[row][col:]


def test_scale_bar_matches_the_drawn_distance() -> None:
    lines = draw(MapLayers(release=(21.0, LAT), landing=(21.0 + lon_offset(50), LAT)), width=70, height=12)
    cells_for_50_km = find(lines, "X")[1] - find(lines, "R")[1]
    bar = re.match(r"(├─*┤) (\d+(?:\.\d+)?) km", scale_line(lines))
    assert bar is not None, scale_line(lines)
    bar_km_per_cell = float(bar.group(2)) / len(bar.group(1))
    assert math.isclose(bar_km_per_cell, 50 / cells_for_50_km, rel_tol=0.1)


def test_descent_across_the_antimeridian_stays_a_few_kilometres_wide() -> None:
    release, landing = (179.95, -45.0), (-179.95, -45.0)
    lines = draw(MapLayers(release=release, landing=landing, path=[release, landing]))
    bar = re.match(r"├─*┤ (\d+(?:\.\d+)?) km", scale_line(lines))
    assert bar is not None and float(bar.group(1)) <= 5, scale_line(lines)
    assert find(lines, "X")[1] > find(lines, "R")[1], "east of the release, across 180°"


def test_legend_names_every_glyph_drawn_so_the_map_reads_without_colour() -> None:
    zone = [(21.1, LAT), (21.2, LAT), (21.2, LAT + 0.05)]
    everything = MapLayers(path=[(21.0, LAT), (21.5, LAT)], ellipse=[(21.5, LAT + 0.01), (21.49, LAT)],
                           zones=[zone], landing=(21.5, LAT), release=(21.0, LAT), balloon=(21.0, LAT + 0.01),
                           team=(21.3, LAT - 0.05))  # fmt: skip
    lines = draw(everything, width=40, height=20)
    legend = " ".join(lines[len(map_rows(lines)) + 1 :])
    for words in ("X landing", "R release", "B balloon", "T team", "⠿ path", "⠿ 2σ ring", "░ zone"):
        assert words in legend
    assert "N↑" in scale_line(lines)
    assert all(len(line) <= 40 for line in lines)


def test_legend_lists_only_what_is_on_the_map() -> None:
    lines = draw(MapLayers(release=(21.0, LAT), landing=(21.5, LAT)), width=120)
    assert lines[-1] == "X landing  R release"


def test_a_marker_under_another_is_not_in_the_legend() -> None:
    lines = draw(MapLayers(release=(21.0, LAT), balloon=(21.0, LAT), landing=(21.5, LAT)), width=120)
    assert "B" in "".join(map_rows(lines)) and "R" not in "".join(map_rows(lines))
    assert lines[-1] == "X landing  B balloon"


def test_a_zone_out_of_view_is_not_in_the_legend() -> None:
    far = [(30.0, 60.0), (30.1, 60.0), (30.1, 60.1)]
    lines = draw(MapLayers(zones=[far], release=(21.0, LAT), landing=(21.5, LAT)), width=120)
    assert "░" not in "\n".join(lines)


def test_a_map_too_small_to_read_says_so_instead_of_drawing() -> None:
    text = render_map(MapLayers(release=(21.0, LAT), landing=(21.5, LAT)), 40, 4).plain
    assert text == "map: too small here; widen the terminal"


def test_nothing_to_map_says_so() -> None:
    assert render_map(MapLayers(), 40, 10).plain == "no position yet: nothing to map"

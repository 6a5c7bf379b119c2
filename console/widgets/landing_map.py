"""A terminal map of a descent: path, landing, 2σ ellipse, exclusion zones, balloon and team.

Character cells are about twice as tall as wide, so x is scaled by two to keep distances honest;
the legend and the scale bar are part of the text, so the map reads the same without colour.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field

KM_PER_DEG_LAT = 110.57


@dataclass
class MapLayers:
    path: Sequence[tuple[float, float]] = ()
    ellipse: Sequence[tuple[float, float]] = ()
    zones: Sequence[Sequence[tuple[float, float]]] = ()
    landing: tuple[float, float] | None = None
    release: tuple[float, float] | None = None
    balloon: tuple[float, float] | None = None
    team: tuple[float, float] | None = None
    scatter: Sequence[tuple[float, float]] = field(default_factory=list)


def _points(layers: MapLayers) -> list[tuple[float, float]]:
    points = [*layers.path, *layers.ellipse, *layers.scatter]
    points += [p for p in (layers.landing, layers.release, layers.balloon, layers.team) if p is not None]
    return points


def _edge_points(ring: Sequence[tuple[float, float]], per_edge: int = 12) -> list[tuple[float, float]]:
    out = []
    for (x0, y0), (x1, y1) in zip(ring, [*ring[1:], ring[0]], strict=True):
        out += [(x0 + (x1 - x0) * i / per_edge, y0 + (y1 - y0) * i / per_edge) for i in range(per_edge)]
    return out


def render_map(layers: MapLayers, width: int, height: int) -> str:
    """Text of ``height`` lines × ``width`` columns; (lon, lat) everywhere, as in GeoJSON."""
    points = _points(layers)
    if not points or width < 10 or height < 4:
        return "no position yet: nothing to map"
    rows = height - 1
    lon0 = sum(p[0] for p in points) / len(points)
    lat0 = sum(p[1] for p in points) / len(points)
    kx = KM_PER_DEG_LAT * math.cos(math.radians(lat0))

    def km(p: tuple[float, float]) -> tuple[float, float]:
        return (p[0] - lon0) * kx, (p[1] - lat0) * KM_PER_DEG_LAT

    xs, ys = zip(*(km(p) for p in points), strict=True)
    span = max(max(xs) - min(xs), (max(ys) - min(ys)) * width / (2 * rows), 1.0) * 1.1
    km_per_col = span / width
    km_per_row = km_per_col * 2
    cx, cy = (max(xs) + min(xs)) / 2, (max(ys) + min(ys)) / 2
    grid = [[" "] * width for _ in range(rows)]

    def put(p: tuple[float, float], glyph: str) -> None:
        x, y = km(p)
        col = round((x - cx) / km_per_col + width / 2)
        row = round(rows / 2 - (y - cy) / km_per_row)
        if 0 <= col < width and 0 <= row < rows:
            grid[row][col] = glyph

    for zone in layers.zones:
        for p in _edge_points(zone):
            put(p, "#")
    for p in layers.ellipse:
        put(p, "o")
    for p in layers.path:
        put(p, "·")
    for p in layers.scatter:
        put(p, "+")
    for p, glyph in ((layers.release, "R"), (layers.balloon, "B"), (layers.team, "T"), (layers.landing, "X")):
        if p is not None:
            put(p, glyph)
    legend = f"X landing o 2σ · path # zone B balloon T team | 1 col = {km_per_col:.2f} km"
    return "\n".join("".join(r) for r in grid) + "\n" + legend[:width]

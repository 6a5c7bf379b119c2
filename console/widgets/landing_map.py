"""A terminal map of a descent: path, landing, 2σ ellipse, exclusion zones, balloon and team.

Drawn in braille (2 × 4 dots per character cell), so a 40-column map has 80 × 4·rows dots: a 2σ
ellipse a few kilometres across is a smooth ring, not three letters. Dots are square because a
cell is about twice as tall as wide, so distances read the same east-west and north-south. The
meaning never rests on colour alone: markers are letters, zones are shaded ``░``, and the last
line carries a scale bar and the legend.
"""

from __future__ import annotations

import math
from collections.abc import Iterator, Sequence, Set
from dataclasses import dataclass, field

import numpy as np
import shapely
from rich.text import Text
from textual.reactive import reactive
from textual.widget import Widget

KM_PER_DEG_LAT = 110.57
DOTS_X, DOTS_Y = 2, 4
BRAILLE_BASE = 0x2800
DOT_BITS = ((0x01, 0x08), (0x02, 0x10), (0x04, 0x20), (0x40, 0x80))
"""Unicode braille bit of the dot at (row 0-3, column 0-1) within a cell."""
ZONE_FILL = "░"
SCALE_STEPS_KM = (0.05, 0.1, 0.2, 0.5, 1, 2, 5, 10, 20, 50, 100, 200, 500, 1000)

LINE_LAYERS = ("path", "ahead", "ellipse", "scatter", "zone")
"""Dot layers, most important first: a cell takes the colour of the first one it shows."""
STYLES = {
    "path": "bold",
    "ahead": "dim",
    "ellipse": "dark_orange3",
    "scatter": "magenta",
    "zone": "red",
    "landing": "bold red",
    "release": "bold",
    "balloon": "bold cyan",
    "team": "bold green",
}
MARKERS = (("release", "R"), ("balloon", "B"), ("team", "T"), ("landing", "X"))
"""Marker letters, drawn in this order so the landing wins a shared cell."""
LEGEND = {"landing": "X landing", "release": "R release", "balloon": "B balloon", "team": "T team",
          "path": "⠿ path", "ahead": "⠿ predicted", "ellipse": "⠿ 2σ ring", "scatter": "⠿ last fixes", "zones": "░ zone"}  # fmt: skip


@dataclass
class MapLayers:
    """Everything to draw, as (lon, lat) pairs like GeoJSON."""

    path: Sequence[tuple[float, float]] = ()
    ahead: Sequence[tuple[float, float]] = ()
    """Where a descending capsule is predicted to go from its latest fix."""
    ellipse: Sequence[tuple[float, float]] = ()
    zones: Sequence[Sequence[tuple[float, float]]] = ()
    landing: tuple[float, float] | None = None
    release: tuple[float, float] | None = None
    balloon: tuple[float, float] | None = None
    team: tuple[float, float] | None = None
    scatter: Sequence[tuple[float, float]] = field(default_factory=list)

    def markers(self) -> Iterator[tuple[str, str, tuple[float, float]]]:
        for name, glyph in MARKERS:
            point = getattr(self, name)
            if point is not None:
                yield name, glyph, point

    def legend(self, hidden: Set[str] = frozenset()) -> list[str]:
        """The legend entries of what is on this map, markers first, less those hidden or out of view."""
        return [
            LEGEND[name]
            for name in LEGEND
            if getattr(self, name) not in (None, (), []) and name not in hidden
        ]


@dataclass(frozen=True)
class Projection:
    """Local kilometres around a centre, then dot coordinates (x right = east, y down = south).

    Longitudes are unwrapped around the centre so a descent across the antimeridian stays a few
    kilometres wide instead of spanning the globe.
    """

    lon0: float
    lat0: float
    km_per_dot: float
    centre_km: tuple[float, float]
    size_dots: tuple[int, int]

    @classmethod
    def fit(cls, points: Sequence[tuple[float, float]], width: int, rows: int) -> Projection:
        lon0, lat0 = points[0]
        unwrapped = [(_unwrap(lon, lon0), lat) for lon, lat in points]
        lon0 = sum(p[0] for p in unwrapped) / len(unwrapped)
        lat0 = sum(p[1] for p in unwrapped) / len(unwrapped)
        probe = cls(lon0, lat0, 1.0, (0.0, 0.0), (width * DOTS_X, rows * DOTS_Y))
        xs, ys = zip(*(probe.km(p) for p in unwrapped), strict=True)
        span_x, span_y = max(max(xs) - min(xs), 1.0), max(max(ys) - min(ys), 1.0)
        km_per_dot = 1.15 * max(span_x / (width * DOTS_X), span_y / (rows * DOTS_Y))
        centre = ((max(xs) + min(xs)) / 2, (max(ys) + min(ys)) / 2)
        return cls(lon0, lat0, km_per_dot, centre, (width * DOTS_X, rows * DOTS_Y))

    def km(self, point: tuple[float, float]) -> tuple[float, float]:
        lon, lat = point
        kx = KM_PER_DEG_LAT * math.cos(math.radians(self.lat0))
        return (_unwrap(lon, self.lon0) - self.lon0) * kx, (lat - self.lat0) * KM_PER_DEG_LAT

    def dot(self, point: tuple[float, float]) -> tuple[int, int]:
        x, y = self.km(point)
        return (
            round((x - self.centre_km[0]) / self.km_per_dot + self.size_dots[0] / 2),
            round(self.size_dots[1] / 2 - (y - self.centre_km[1]) / self.km_per_dot),
        )

    def cell_centres_km(self) -> tuple[np.ndarray, np.ndarray]:
        """Kilometre coordinates of every cell's centre, as (rows, columns) arrays."""
        columns = self.size_dots[0] // DOTS_X
        rows = self.size_dots[1] // DOTS_Y
        dx = (np.arange(columns) + 0.5) * DOTS_X - self.size_dots[0] / 2
        dy = self.size_dots[1] / 2 - (np.arange(rows) + 0.5) * DOTS_Y
        gx, gy = np.meshgrid(dx, dy)
        return self.centre_km[0] + gx * self.km_per_dot, self.centre_km[1] + gy * self.km_per_dot


def _unwrap(lon: float, reference: float) -> float:
    return reference + (lon - reference + 180.0) % 360.0 - 180.0


def _segment(a: tuple[int, int], b: tuple[int, int]) -> Iterator[tuple[int, int]]:
    """Dots on the straight line from a to b, both ends included."""
    steps = max(abs(b[0] - a[0]), abs(b[1] - a[1]), 1)
    for i in range(steps + 1):
        yield round(a[0] + (b[0] - a[0]) * i / steps), round(a[1] + (b[1] - a[1]) * i / steps)


class BrailleGrid:
    """Character cells holding braille bits per layer, zone shading and marker letters."""

    def __init__(self, width: int, rows: int) -> None:
        self.width, self.rows = width, rows
        self.bits = {layer: np.zeros((rows, width), dtype=np.uint8) for layer in LINE_LAYERS}
        self.shaded = np.zeros((rows, width), dtype=bool)
        self.letters: dict[tuple[int, int], tuple[str, str]] = {}

    def plot(self, layer: str, dot: tuple[int, int]) -> None:
        x, y = dot
        if 0 <= x < self.width * DOTS_X and 0 <= y < self.rows * DOTS_Y:
            self.bits[layer][y // DOTS_Y, x // DOTS_X] |= DOT_BITS[y % DOTS_Y][x % DOTS_X]

    def polyline(self, layer: str, dots: Sequence[tuple[int, int]], closed: bool = False) -> None:
        if len(dots) == 1:
            self.plot(layer, dots[0])
        ends = [*dots[1:], dots[0]] if closed else dots[1:]
        for a, b in zip(dots, ends, strict=False):
            for dot in _segment(a, b):
                self.plot(layer, dot)

    def letter(self, dot: tuple[int, int], glyph: str, style: str) -> None:
        row, column = dot[1] // DOTS_Y, dot[0] // DOTS_X
        if 0 <= row < self.rows and 0 <= column < self.width:
            self.letters[(row, column)] = (glyph, style)

    def lines(self) -> list[Text]:
        out = []
        for row in range(self.rows):
            line = Text()
            for column in range(self.width):
                line.append(*self._cell(row, column))
            out.append(line)
        return out

    def _cell(self, row: int, column: int) -> tuple[str, str]:
        if (row, column) in self.letters:
            return self.letters[(row, column)]
        bits = 0
        style = ""
        for layer in LINE_LAYERS:
            layer_bits = int(self.bits[layer][row, column])
            if layer_bits and not style:
                style = STYLES[layer]
            bits |= layer_bits
        if bits:
            return chr(BRAILLE_BASE + bits), style
        if self.shaded[row, column]:
            return ZONE_FILL, STYLES["zone"]
        return " ", ""


def scale_bar(km_per_cell: float, width: int) -> str:
    """The longest round distance that fits in a third of the width, drawn to scale."""
    fitting = [km for km in SCALE_STEPS_KM if 3 <= km / km_per_cell <= max(3, width / 3)]
    km = fitting[-1] if fitting else SCALE_STEPS_KM[-1]
    cells = max(3, round(km / km_per_cell))
    return "├" + "─" * (cells - 2) + "┤ " + f"{km:g} km"


def legend_lines(entries: list[str], width: int) -> list[str]:
    """The legend entries packed into lines of at most ``width`` cells."""
    lines = [""]
    for entry in entries:
        candidate = f"{lines[-1]}  {entry}" if lines[-1] else entry
        if len(candidate) <= width or not lines[-1]:
            lines[-1] = candidate[:width]
        else:
            lines.append(entry[:width])
    return lines


def render_map(layers: MapLayers, width: int, height: int) -> Text:
    """``height`` lines of at most ``width`` cells: the map, a scale bar, and a legend of what is drawn."""
    points = [
        *layers.path,
        *layers.ahead,
        *layers.ellipse,
        *layers.scatter,
        *(p for _, _, p in layers.markers()),
    ]
    if not points or width < 10:
        return Text("no position yet: nothing to map")
    legend = legend_lines(layers.legend(), width)
    rows = height - 1 - len(legend)
    if rows < 3:
        return Text("map: too small here; widen the terminal")
    projection = Projection.fit(points, width, rows)
    grid = BrailleGrid(width, rows)
    centres_x, centres_y = projection.cell_centres_km()
    for zone in layers.zones:
        ring = [projection.km(p) for p in zone]
        if len(ring) >= 3:
            grid.shaded |= shapely.contains_xy(shapely.Polygon(ring), centres_x, centres_y)
        grid.polyline("zone", [projection.dot(p) for p in zone], closed=True)
    if layers.ellipse:
        grid.polyline("ellipse", [projection.dot(p) for p in layers.ellipse], closed=True)
    if layers.ahead:
        grid.polyline("ahead", [projection.dot(p) for p in layers.ahead])
    if layers.path:
        grid.polyline("path", [projection.dot(p) for p in layers.path])
    for point in layers.scatter:
        grid.plot("scatter", projection.dot(point))
    for name, glyph, point in layers.markers():
        grid.letter(projection.dot(point), glyph, STYLES[name])
    shown = {glyph for glyph, _ in grid.letters.values()}
    hidden = {name for name, glyph, _ in layers.markers() if glyph not in shown}
    if not grid.shaded.any() and not grid.bits["zone"].any():
        hidden.add("zones")
    scale = Text(scale_bar(projection.km_per_dot * DOTS_X, width) + "  N↑")
    scale.truncate(width)
    legend = legend_lines(layers.legend(hidden), width)
    return Text("\n").join([*grid.lines(), scale, *(Text(line, style="dim") for line in legend)])


class LandingMap(Widget):
    """The map as a widget that redraws at its own size, so a resize never shows a map drawn for another."""

    map_layers: reactive[MapLayers] = reactive(MapLayers)
    """Redrawn when the layers change (or the size), not on every assignment: the screens assign
    them on every refresh, and an unchanged map repainted was half the recovery screen's output."""

    def render(self) -> Text:
        return render_map(self.map_layers, self.size.width, self.size.height)

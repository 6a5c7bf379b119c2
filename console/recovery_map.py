"""The recovery team's picture: the measured track, the live predicted landing with its 1σ/2σ ellipses,
the last fix and the chase car, over terrain shading, as a PNG for a phone or a printer.

Drawn on a local flat map in kilometres about the picture's middle (east and north of it): over the tens
of kilometres a descent covers the flattening is far below a line's width, and the ellipses, the scale
bar and north are then exact by construction (north is up, a km is a km both ways). matplotlib is
imported only here, with its Agg canvas and no pyplot, so `drs --help` and every other command stay
quick and no display is needed.

``draw_recovery_map`` returns where each layer landed in the image (pixels from the top left): the test
reads the PNG back and checks each layer's colour there, and nothing else needs a person to look.
"""

from __future__ import annotations

import math
from collections.abc import Sequence
from dataclasses import dataclass, field
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

import numpy as np

from predictor.errors import PredictorError

if TYPE_CHECKING:
    from matplotlib.axes import Axes

    from drs_link.ops import Descent
    from predictor import Terrain

LatLon = tuple[float, float]

TRACK = "#1f4fbf"
ELLIPSE_1SIGMA = "#d01c1c"
ELLIPSE_2SIGMA = "#f08c00"
PREDICTED = "#d01c1c"
LAST_FIX = "#8a2be2"
LANDED = "#7a4a1a"
CHASE = "#1a9a3a"
KM_PER_DEG_LAT = 110.574
KM_PER_DEG_LON_EQUATOR = 111.320
MIN_HALF_SPAN_KM = 2.0
SHADE_CELLS = 240
"""Terrain samples across the picture: finer than a hill, coarser than a pixel, and quick."""


@dataclass(frozen=True)
class LiveLanding:
    """The live re-prediction's landing and its ellipse's principal axes (1σ), as the recovery view has it."""

    lat: float
    lon: float
    sigma_major_km: float
    sigma_minor_km: float
    major_axis_bearing_deg: float
    """Degrees clockwise from north."""


@dataclass(frozen=True)
class RecoveryPicture:
    capsule: str
    track: Sequence[LatLon] = ()
    """The measured fixes, oldest first; the last one is drawn as the last fix."""
    predicted: LiveLanding | None = None
    landed: LatLon | None = None
    """The landing the fixes show (once they show one)."""
    chase: LatLon | None = None
    caption: str = ""


@dataclass
class Placed:
    """Where each drawn layer is in the PNG, in pixels from the top left; only what was drawn."""

    size_px: tuple[int, int]
    points: dict[str, tuple[float, float]] = field(default_factory=dict)
    terrain: bool = False


@dataclass(frozen=True)
class _Plane:
    """Local east/north kilometres about (lat0, lon0)."""

    lat0: float
    lon0: float

    def km(self, lat: float, lon: float) -> tuple[float, float]:
        east = (lon - self.lon0 + 540.0) % 360.0 - 180.0
        return east * KM_PER_DEG_LON_EQUATOR * math.cos(math.radians(self.lat0)), (
            lat - self.lat0
        ) * KM_PER_DEG_LAT

    def lat_lon(self, east: np.ndarray, north: np.ndarray) -> tuple[np.ndarray, np.ndarray]:
        lat = self.lat0 + north / KM_PER_DEG_LAT
        lon = self.lon0 + east / (KM_PER_DEG_LON_EQUATOR * math.cos(math.radians(self.lat0)))
        return lat, (lon + 180.0) % 360.0 - 180.0


def recovery_picture(
    capsule: str, descent: Descent, chase: LatLon | None, weather: bool = True
) -> RecoveryPicture:
    """What the recovery view knows of a capsule, as the picture draws it (``picture_from``)."""
    live = descent.live
    predicted = None
    if live is not None and math.isfinite(live.sigma_major_km):
        predicted = LiveLanding(
            live.landing_lat, live.landing_lon, live.sigma_major_km, live.sigma_minor_km,
            live.major_axis_bearing_deg,
        )  # fmt: skip
    last = (descent.track[-1].time, descent.track[-1].alt_m) if descent.track else None
    return picture_from(
        capsule,
        tuple((p.lat, p.lon) for p in descent.track),
        last,
        (descent.landing.lat, descent.landing.lon) if descent.landing is not None else None,
        predicted,
        (live.landing_time, live.correction) if live is not None else None,
        descent.live_error,
        chase,
        weather,
    )


def picture_from(
    capsule: str,
    track: Sequence[LatLon],
    last: tuple[datetime, float] | None,
    landed: LatLon | None,
    predicted: LiveLanding | None,
    lands: tuple[datetime, str] | None,
    live_error: str | None,
    chase: LatLon | None,
    weather: bool = True,
) -> RecoveryPicture:
    """The picture from plain values (a descent here, or the operations server's ``DescentView``), with a
    caption saying what is and is not on it (no prediction without weather; none once the fixes show a
    landing). ``last`` is the last fix's time and altitude; ``lands`` the live prediction's landing time
    and the correction it used."""
    said = (
        [f"last fix {last[0]:%Y-%m-%d %H:%M:%S}Z at {last[1]:.0f} m"] if last is not None else ["no fix yet"]
    )
    if landed is not None:
        said.append("landed (from the fixes)")
    elif lands is not None:
        said.append(f"live prediction lands {lands[0]:%H:%M:%S}Z ({lands[1]})")
    elif live_error:
        said.append(f"no live prediction: {live_error}")
    elif not weather:
        said.append("no live prediction: give --weather")
    return RecoveryPicture(capsule, tuple(track), predicted, landed, chase, "; ".join(said))


def ellipse_ring(centre: tuple[float, float], landing: LiveLanding, n_sigma: float) -> np.ndarray:
    """The n-σ ellipse about ``centre`` (km) as a closed ring of (east, north) km."""
    theta = np.linspace(0.0, 2.0 * math.pi, 145)
    bearing = math.radians(landing.major_axis_bearing_deg)
    major = np.array([math.sin(bearing), math.cos(bearing)]) * n_sigma * landing.sigma_major_km
    minor = np.array([math.cos(bearing), -math.sin(bearing)]) * n_sigma * landing.sigma_minor_km
    ring = centre + np.outer(np.cos(theta), major) + np.outer(np.sin(theta), minor)
    return np.asarray(ring)


def _nice_length(span_km: float) -> float:
    """A round scale-bar length near a fifth of the picture's width: 1, 2 or 5 × 10ⁿ km."""
    target = span_km / 5.0
    power = 10.0 ** math.floor(math.log10(target))
    return min((m * power for m in (1.0, 2.0, 5.0, 10.0)), key=lambda length: abs(length - target))


def _extent(points: list[tuple[float, float]], pad: float) -> tuple[float, float, float, float]:
    xs, ys = [p[0] for p in points], [p[1] for p in points]
    cx, cy = (min(xs) + max(xs)) / 2.0, (min(ys) + max(ys)) / 2.0
    half = max((max(xs) - min(xs)) / 2.0, (max(ys) - min(ys)) / 2.0, MIN_HALF_SPAN_KM) * (1.0 + pad)
    return cx - half, cx + half, cy - half, cy + half


def draw_recovery_map(
    picture: RecoveryPicture,
    out: Path,
    terrain: Terrain | None = None,
    size_px: tuple[int, int] = (1000, 1000),
) -> Placed:
    """Write the PNG; refuses (``PredictorError``) when there is nothing to place on a map."""
    from matplotlib.backends.backend_agg import FigureCanvasAgg
    from matplotlib.figure import Figure

    everything: list[LatLon] = list(picture.track)
    everything += [p for p in (picture.landed, picture.chase) if p is not None]
    if picture.predicted is not None:
        everything.append((picture.predicted.lat, picture.predicted.lon))
    if not everything:
        raise PredictorError(
            f"{picture.capsule}: no fix, landing or prediction yet: nothing to draw a map of"
        )
    lats, lons = [p[0] for p in everything], [p[1] for p in everything]
    spread = [(lon - lons[0] + 540.0) % 360.0 - 180.0 for lon in lons]  # about the first: no jump at ±180°
    plane = _Plane((min(lats) + max(lats)) / 2.0, lons[0] + (min(spread) + max(spread)) / 2.0)
    extent_points = [plane.km(lat, lon) for lat, lon in everything]
    ring_2sigma = None
    if picture.predicted is not None:
        centre = plane.km(picture.predicted.lat, picture.predicted.lon)
        ring_2sigma = ellipse_ring(centre, picture.predicted, 2.0)
        extent_points += [(float(x), float(y)) for x, y in ring_2sigma]
    west, east, south, north = _extent(extent_points, pad=0.12)

    dpi = 100
    figure = Figure(figsize=(size_px[0] / dpi, size_px[1] / dpi), dpi=dpi)
    canvas = FigureCanvasAgg(figure)
    axes = figure.add_axes((0.08, 0.08, 0.88, 0.84))
    axes.set_xlim(west, east)
    axes.set_ylim(south, north)
    axes.set_aspect("equal", adjustable="box")
    axes.set_xlabel(f"km east of {plane.lon0:.4f}°")
    axes.set_ylabel(f"km north of {plane.lat0:.4f}°")
    placed = Placed(size_px)

    if terrain is not None:
        placed.terrain = _shade(axes, plane, terrain, (west, east, south, north))
    if picture.track:
        xy = np.array([plane.km(lat, lon) for lat, lon in picture.track])
        axes.plot(
            xy[:, 0],
            xy[:, 1],
            "-o",
            color=TRACK,
            markersize=3,
            linewidth=2.5,
            label="measured track",
            zorder=3,
        )
        placed.points["track"] = (float(xy[len(xy) // 2, 0]), float(xy[len(xy) // 2, 1]))
        last = xy[-1]
        axes.plot(last[0], last[1], "s", color=LAST_FIX, markersize=12, label="last fix", zorder=5)
        placed.points["last_fix"] = (float(last[0]), float(last[1]))
    if picture.predicted is not None and ring_2sigma is not None:
        centre = plane.km(picture.predicted.lat, picture.predicted.lon)
        ring_1sigma = ellipse_ring(centre, picture.predicted, 1.0)
        axes.fill(ring_2sigma[:, 0], ring_2sigma[:, 1], color=ELLIPSE_2SIGMA, alpha=0.18, zorder=2)
        for ring, colour, label in (
            (ring_2sigma, ELLIPSE_2SIGMA, "2σ (86.5 %)"),
            (ring_1sigma, ELLIPSE_1SIGMA, "1σ (39.3 %)"),
        ):
            axes.plot(ring[:, 0], ring[:, 1], color=colour, linewidth=3, label=label, zorder=2)
        axes.plot(
            *centre,
            "X",
            color=PREDICTED,
            markersize=16,
            markeredgecolor="white",
            label="predicted landing",
            zorder=6,
        )
        placed.points["predicted"] = centre
        placed.points["ellipse_1sigma"] = (float(ring_1sigma[0, 0]), float(ring_1sigma[0, 1]))
        placed.points["ellipse_2sigma"] = (float(ring_2sigma[0, 0]), float(ring_2sigma[0, 1]))
    if picture.landed is not None:
        landed = plane.km(*picture.landed)
        axes.plot(
            *landed, "*", color=LANDED, markersize=20, markeredgecolor="white", label="landed", zorder=6
        )
        placed.points["landed"] = landed
    if picture.chase is not None:
        chase = plane.km(*picture.chase)
        axes.plot(*chase, "^", color=CHASE, markersize=14, markeredgecolor="white", label="chase", zorder=6)
        placed.points["chase"] = chase
    axes.legend(loc="lower right", fontsize=9, framealpha=0.9)
    _scale_bar(axes, west, east, south, north)
    _north_arrow(axes)
    title = f"{picture.capsule} recovery"
    axes.set_title(f"{title}\n{picture.caption}" if picture.caption else title, fontsize=11)

    canvas.draw()
    height = size_px[1]
    for name, (x, y) in list(placed.points.items()):
        px, py = axes.transData.transform((x, y))
        placed.points[name] = (float(px), float(height - py))
    out.parent.mkdir(parents=True, exist_ok=True)
    canvas.print_png(str(out))
    return placed


def _shade(axes: Axes, plane: _Plane, terrain: Terrain, box: tuple[float, float, float, float]) -> bool:
    """Hill shading under everything; False (nothing drawn) where the DEM says nothing but sea level."""
    west, east, south, north = box
    xs, ys = np.linspace(west, east, SHADE_CELLS), np.linspace(south, north, SHADE_CELLS)
    grid_x, grid_y = np.meshgrid(xs, ys)
    lat, lon = plane.lat_lon(grid_x, grid_y)
    heights = np.asarray(terrain.elevation(lat, lon), dtype=float)
    if not np.isfinite(heights).any() or float(np.nanmax(heights) - np.nanmin(heights)) < 1.0:
        return False
    heights = np.nan_to_num(heights, nan=float(np.nanmin(heights)))
    cell_m = (east - west) * 1000.0 / (SHADE_CELLS - 1)
    from matplotlib.colors import LightSource

    shade = LightSource(azdeg=315, altdeg=45).hillshade(heights, vert_exag=3.0, dx=cell_m, dy=cell_m)
    axes.imshow(
        shade,
        cmap="gray",
        origin="lower",
        extent=(west, east, south, north),
        alpha=0.45,
        vmin=0.0,
        vmax=1.0,
        zorder=0,
    )
    return True


def _scale_bar(axes: Axes, west: float, east: float, south: float, north: float) -> None:
    length = _nice_length(east - west)
    x0, y0 = west + 0.05 * (east - west), south + 0.05 * (north - south)
    axes.plot([x0, x0 + length], [y0, y0], color="black", linewidth=4, solid_capstyle="butt", zorder=7)
    axes.text(
        x0 + length / 2.0, y0 + 0.015 * (north - south), f"{length:g} km", ha="center", va="bottom", zorder=7
    )


def _north_arrow(axes: Axes) -> None:
    axes.annotate(
        "N", xy=(0.06, 0.95), xytext=(0.06, 0.84), xycoords="axes fraction", ha="center", va="center",
        fontsize=14, fontweight="bold", arrowprops={"facecolor": "black", "width": 4, "headwidth": 12},
    )  # fmt: skip

"""The recovery picture (`drs recovery --map`), read back from the PNG: each layer's colour where it was
drawn, nothing of a layer that was not given, and terrain shading only where a DEM is given."""

from __future__ import annotations

from datetime import timedelta
from pathlib import Path

import numpy as np
import pytest
from PIL import Image

import console.commands.main as entry
from console.demo import write_demo_terrain
from console.recovery_map import (
    CHASE,
    ELLIPSE_1SIGMA,
    ELLIPSE_2SIGMA,
    LAST_FIX,
    PREDICTED,
    TRACK,
    LiveLanding,
    Placed,
    RecoveryPicture,
    draw_recovery_map,
)
from drs_link.iridium.firmware import format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.store import Store, utc_now
from predictor import Terrain
from tests.console.commands.test_cli_iridium import write_config
from tests.drs_link.iridium.helpers import IMEI, fix_at
from tests.release_helpers import write_weather

SITE = (67.89, 21.09)
TRACK_POINTS = [(SITE[0] - 0.01 * i, SITE[1] + 0.03 * i) for i in range(8)]
LANDING = LiveLanding(
    SITE[0] - 0.12, SITE[1] + 0.35, sigma_major_km=2.0, sigma_minor_km=1.0, major_axis_bearing_deg=60.0
)
CHASE_AT = (SITE[0] - 0.25, SITE[1] + 0.1)


def rgb(colour: str) -> np.ndarray:
    return np.array([int(colour[i : i + 2], 16) for i in (1, 3, 5)], dtype=float)


def near(image: np.ndarray, colour: str, at: tuple[float, float] | None = None, radius: int = 6) -> int:
    """Pixels within 40 (RGB distance) of ``colour``: within ``radius`` of ``at``, or anywhere."""
    pixels = image
    if at is not None:
        x, y = round(at[0]), round(at[1])
        pixels = image[max(0, y - radius) : y + radius + 1, max(0, x - radius) : x + radius + 1]
    distance = np.linalg.norm(pixels[..., :3].astype(float) - rgb(colour), axis=-1)
    return int((distance < 40).sum())


def drawn(
    tmp_path: Path, picture: RecoveryPicture, terrain: Terrain | None = None
) -> tuple[np.ndarray, Placed]:
    out = tmp_path / f"{picture.capsule}-{len(list(tmp_path.iterdir()))}.png"
    placed = draw_recovery_map(picture, out, terrain, size_px=(900, 800))
    with Image.open(out) as image:
        assert image.size == (900, 800) and image.format == "PNG"
        return np.asarray(image.convert("RGB")), placed


def test_every_layer_is_in_the_picture_in_its_colour_where_it_was_placed(tmp_path: Path) -> None:
    picture = RecoveryPicture("DRS1", TRACK_POINTS, LANDING, None, CHASE_AT, "last fix 12:00:00Z")
    image, placed = drawn(tmp_path, picture)
    assert set(placed.points) == {
        "track",
        "last_fix",
        "predicted",
        "ellipse_1sigma",
        "ellipse_2sigma",
        "chase",
    }
    for name, colour in [
        ("track", TRACK), ("last_fix", LAST_FIX), ("predicted", PREDICTED), ("ellipse_1sigma", ELLIPSE_1SIGMA),
        ("ellipse_2sigma", ELLIPSE_2SIGMA), ("chase", CHASE),
    ]:  # fmt: skip
        x, y = placed.points[name]
        assert 0 <= x < 900 and 0 <= y < 800, f"{name} is outside the image"
        assert near(image, colour, placed.points[name]) >= 4, f"no {name} colour at {placed.points[name]}"
    # North is up and east is right: the landing lies south-east of the first fix.
    first = draw_recovery_map(RecoveryPicture("DRS1", TRACK_POINTS[:1], LANDING), tmp_path / "one.png")
    assert first.points["predicted"][0] > first.points["last_fix"][0]
    assert first.points["predicted"][1] > first.points["last_fix"][1]
    # The 2σ ring is twice the 1σ ring's distance from the landing.
    cx, cy = placed.points["predicted"]
    r1 = np.hypot(placed.points["ellipse_1sigma"][0] - cx, placed.points["ellipse_1sigma"][1] - cy)
    r2 = np.hypot(placed.points["ellipse_2sigma"][0] - cx, placed.points["ellipse_2sigma"][1] - cy)
    assert r2 == pytest.approx(2 * r1, rel=0.01)


def test_a_layer_not_given_is_not_drawn_and_terrain_shades_only_with_a_dem(tmp_path: Path) -> None:
    bare, placed = drawn(tmp_path, RecoveryPicture("DRS1", TRACK_POINTS))
    assert set(placed.points) == {"track", "last_fix"} and not placed.terrain
    assert near(bare, CHASE) == 0 and near(bare, ELLIPSE_2SIGMA) == 0
    dem = Terrain.from_netcdf(write_demo_terrain(tmp_path / "dem" / "demo-dem.nc"))
    shaded, placed = drawn(tmp_path, RecoveryPicture("DRS1", TRACK_POINTS), dem)
    assert placed.terrain

    def background(image: np.ndarray) -> np.ndarray:  # inside the axes, away from the track and legend
        return image[150:300, 500:650, :3].astype(float)

    assert background(bare).std() < 1.0, "without a DEM the map's ground is plain"
    assert background(shaded).std() > 0.5 and background(shaded).mean() < 245, "with a DEM it is shaded"


def test_nothing_to_draw_is_a_one_line_refusal(tmp_path: Path) -> None:
    from predictor.errors import PredictorError

    with pytest.raises(PredictorError, match="nothing to draw a map of"):
        draw_recovery_map(RecoveryPicture("DRS1"), tmp_path / "empty.png")


def test_drs_recovery_map_draws_the_live_prediction_from_the_stored_reports(
    tmp_path: Path, capsys: pytest.CaptureFixture[str]
) -> None:
    """Through the real command: stored Iridium reports of a descent, the weather, the chase position."""
    config = write_config(tmp_path)
    reports = ReportStore(Store.open(tmp_path / "data" / "drs.sqlite"))
    start = utc_now().replace(microsecond=0) - timedelta(minutes=10)
    for i in range(4):
        moment = start + timedelta(minutes=2 * i)
        fix = fix_at(moment, SITE[0] - 0.01 * i, SITE[1] + 0.04 * i, 24000.0 - 4000.0 * i, 30.0)
        reports.add(Delivery(IMEI, i, format_mo(fix, 8.9, i).hex(), "test", moment))
    weather = write_weather(tmp_path / "gfs")
    out = tmp_path / "recovery.png"
    chase = f"{CHASE_AT[0]},{CHASE_AT[1]}"
    code = entry.main(
        ["--config", str(config), "recovery", "DRS1", "--map", str(out), "--chase", chase,
         "--weather", *map(str, weather)]
    )  # fmt: skip
    assert code == 0, capsys.readouterr().err
    assert f"wrote {out}" in capsys.readouterr().out
    with Image.open(out) as image:
        pixels = np.asarray(image.convert("RGB"))
    for colour in (TRACK, LAST_FIX, PREDICTED, ELLIPSE_1SIGMA, ELLIPSE_2SIGMA, CHASE):
        assert near(pixels, colour) >= 20, f"{colour} is missing from the map"

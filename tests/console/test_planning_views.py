"""The release-window timeline (Predictions) and the live re-prediction (Recovery) in the running demo."""

from __future__ import annotations

import json
from datetime import datetime, timedelta
from pathlib import Path

import pytest

from console.app import DrsConsole
from console.demo import SERVO_A_AFTER_GO_S, DemoWorld
from console.predictions import PredictionService, ReleaseOrigin
from console.screens.predictions import PredictionScreen
from console.screens.recovery import RecoveryScreen
from console.widgets.landing_map import LandingMap
from console.widgets.release_timeline import GO, NO_GO, NO_LANDING, default_cursor, render_timeline
from drs_link.iridium.recovery import TrackPoint
from drs_link.ops import ReleaseCandidate, ReleaseWindow
from predictor.descent import PROFILES
from predictor.errors import PredictorError
from predictor.prediction import CalibratedModel
from tests.console.conftest import SITE, T0, wait_for


@pytest.mark.asyncio
async def test_the_predictions_screen_shows_the_release_window_with_a_recommended_time(
    demo: tuple[DemoWorld, DrsConsole],
) -> None:
    world, app = demo
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.fleet.capsules["DRS1"].predictions.get(0) is not None)
        await pilot.press("p")
        screen = app.screen
        assert isinstance(screen, PredictionScreen) and screen.capsule == "DRS1"
        await wait_for(pilot, lambda: screen.window is not None)
        window = screen.window
        assert window is not None
        candidates = window.candidates
        assert len(candidates) == 25  # 2 h at 5-minute steps, both ends included
        assert abs((candidates[0].time - world.clock()).total_seconds()) < 600
        recommended = window.recommended
        assert recommended is not None and candidates[recommended].go
        screen.refresh_view()
        text = str(screen.query_one("#release-timeline").render())
        assert f"recommended {candidates[recommended].time:%H:%M}Z" in text
        glyph_row = text.splitlines()[1].strip()
        assert len(glyph_row) == 25 and set(glyph_row) <= {GO, NO_GO, NO_LANDING}
        assert glyph_row.count(GO) == sum(c.go for c in candidates)
        before = screen.cursor if screen.cursor is not None else default_cursor(window)
        await pilot.press("right")
        assert screen.cursor == min(before + 1, 24)


def test_the_timeline_gives_the_reasons_of_the_first_no_go() -> None:
    at = datetime(2026, 9, 1, 12, 0)
    window = ReleaseWindow(at, 5.0, 2, tuple(
        ReleaseCandidate(at + timedelta(minutes=5 * i), i >= 2, i != 0,
                         () if i >= 2 else ("P(zone) 0.31 > 0.05 (Kiruna town)",))
        for i in range(4)
    ))  # fmt: skip
    text = render_timeline(window, default_cursor(window), "computed 1 s ago")
    lines = text.splitlines()
    assert lines[1].strip() == f"{NO_LANDING}{NO_GO}{GO}{GO}"
    assert "recommended 12:10Z" in lines[0] and "2/4 go" in lines[0]
    assert "at 12:00Z" in text and "P(zone) 0.31 > 0.05 (Kiruna town)" in text
    assert all(len(line) <= 80 for line in lines if not line.strip().startswith("at "))


def test_an_empty_window_says_no_go_and_marks_nothing_recommended() -> None:
    at = datetime(2026, 9, 1, 12, 0)
    window = ReleaseWindow(at, 5.0, None, (ReleaseCandidate(at, False, True, ("sigma too large",)),))
    text = render_timeline(window, default_cursor(window), "computed 1 s ago")
    assert "NO-GO window" in text and "▲" not in text.splitlines()[2] and "sigma too large" in text


@pytest.mark.asyncio
async def test_the_recovery_view_re_predicts_a_descending_capsule_from_its_reports(
    demo: tuple[DemoWorld, DrsConsole],
) -> None:
    world, app = demo
    # One report a minute, as an INTERVAL=1 command would set, so two fixes (one leg) arrive sooner.
    world.iridium[app.ops.state.ops("DRS1").config.imei].interval_min = 1  # type: ignore[union-attr]
    # The GO itself is the release flow's business (its own tests): here the simulated firmware
    # is simply put past it, so the demo world drops DRS1 and starts posting its reports.
    world.sims[0].firmware.go_at = world.clock() - timedelta(seconds=SERVO_A_AFTER_GO_S)
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("v")
        screen = app.screen
        assert isinstance(screen, RecoveryScreen) and screen.capsule == "DRS1"
        await wait_for(pilot, lambda: screen.live is not None and screen.live.legs_used >= 1)
        live = screen.live
        assert live is not None and screen.landing is None
        assert live.measured_rate_factor is not None and 0.3 < live.measured_rate_factor < 3.0
        assert live.report_alt_m < 31500.0 and live.remaining_drift_km > 0.0
        screen.refresh_view()
        text = str(screen.query_one("#recovery-text").render())
        assert "Live re-prediction from the" in text
        assert f"{live.landing_lat:.4f}, {live.landing_lon:.4f} at {live.landing_time:%H:%M:%S}Z" in text
        assert "measured rate factor" in text and "correction:" in text
        layers = screen.query_one("#recovery-map", LandingMap).map_layers
        assert layers.ahead == list(live.path) and layers.ahead[0] != layers.ahead[-1]
        assert layers.ellipse == list(live.outline_2sigma), "the live ring, not the release one"
        assert "⠿ predicted" in str(screen.query_one("#recovery-map").render())


def test_a_zone_over_every_landing_makes_the_whole_window_no_go_with_its_reason(
    prediction_service: PredictionService, tmp_path: Path
) -> None:
    ring = [[20.5, 67.3], [23.8, 67.3], [23.8, 68.6], [20.5, 68.6], [20.5, 67.3]]
    zones = tmp_path / "zones.geojson"
    zones.write_text(json.dumps({"type": "Feature", "properties": {"name": "Everywhere east"},
                                 "geometry": {"type": "Polygon", "coordinates": [ring]}}))  # fmt: skip
    window = prediction_service.release_window(ReleaseOrigin(SITE[0], SITE[1], 31500.0, "test"), zones)
    assert window.recommended is None and not any(c.go for c in window.candidates)
    text = render_timeline(window, default_cursor(window), "computed 0 s ago")
    assert "NO-GO window" in text and "(mostly Everywhere east)" in text
    open_sky = prediction_service.release_window(ReleaseOrigin(SITE[0], SITE[1], 31500.0, "test"), None)
    assert open_sky.recommended is not None and all(c.go for c in open_sky.candidates)
    assert open_sky.candidates[0].time.tzinfo is not None


def test_a_zone_file_that_is_not_geojson_is_refused_with_its_name(
    prediction_service: PredictionService, tmp_path: Path
) -> None:
    zones = tmp_path / "zones.geojson"
    zones.write_text("not json")
    with pytest.raises(PredictorError, match="zones.geojson"):
        prediction_service.release_window(ReleaseOrigin(SITE[0], SITE[1], 31500.0, "test"), zones)


def test_live_re_prediction_feeds_each_fix_once_and_skips_a_repeated_one(
    prediction_service: PredictionService,
) -> None:
    start = T0 + timedelta(minutes=5)
    fixes = [TrackPoint(start + timedelta(minutes=2 * n), 67.90 + 0.004 * n, 21.20 + 0.03 * n, 12000.0 - 1300.0 * n,
                        11.0) for n in range(4)]  # fmt: skip
    first = prediction_service.live("DRS9", fixes[:2])
    assert first is not None and first.legs_used == 1 and first.measured_rate_factor is not None
    again = prediction_service.live("DRS9", fixes[:2])
    assert again is first
    later = prediction_service.live("DRS9", [*fixes, fixes[-1]])
    assert later is not None and later.legs_used == 3
    assert later.report_alt_m == fixes[-1].alt_m and later.remaining_drift_km < first.remaining_drift_km
    assert later.report_time == fixes[-1].time and later.landing_time.tzinfo is not None


def test_the_release_window_flies_the_capsules_model_as_its_release_prediction_does(
    prediction_service: PredictionService,
) -> None:
    # A capsule whose model is twice as heavy falls faster: its sweep's landings come earlier, and the
    # window names the model (the go/no-go is decided on these landings).
    heavy = CalibratedModel(PROFILES["drs"].overridden(mass_kg=2 * PROFILES["drs"].mass_kg), (), None)
    service = prediction_service
    service.models["HEAVY"] = heavy
    try:
        origin = ReleaseOrigin(SITE[0], SITE[1], 31500.0, "test")
        default = service.release_window(origin, None)
        flown = service.release_window(origin, None, capsule="HEAVY")
    finally:
        del service.models["HEAVY"]
    assert default.model == "drs profile" and flown.model == heavy.label()
    pairs = list(zip(default.candidates, flown.candidates, strict=True))
    assert pairs and all(
        b.landing_time is not None and a.landing_time is not None and b.landing_time < a.landing_time
        for a, b in pairs
    )

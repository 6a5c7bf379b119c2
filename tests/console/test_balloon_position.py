"""The balloon's position reaches the console from the configured ground-station feed (here, the demo's UDP)."""

from __future__ import annotations

import threading
from pathlib import Path
from typing import Any

import pytest

from console.app import ConsoleSetup, DrsConsole
from console.demo import DemoWorld
from console.widgets.cells import FIELDS
from drs_link.ops.telemetry import GnssSample, PredictionSample
from tests.console.conftest import offline_config, offline_server, wait_for
from tests.console.test_fleet_view import detail_of, painted

pytestmark = pytest.mark.asyncio


async def test_the_demo_balloon_arrives_over_udp_and_starts_predictions_before_power_on(
    demo: tuple[DemoWorld, DrsConsole],
) -> None:
    world, app = demo
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.fleet.balloon.value is not None)
        value = app.fleet.balloon.value
        assert value is not None
        assert value.format == "ozimux"
        assert value.source == f"udp 127.0.0.1:{world.ground_station_port}"
        assert abs(value.lat - world.balloon[0]) < 0.05 and abs(value.lon - world.balloon[1]) < 0.1
        feed = app.setup.balloon_feed
        assert feed is not None
        status = feed.status()
        assert status.accepted >= 1 and status.rejected == 0
        await wait_for(pilot, lambda: "fixes" in str(app.screen.query_one("#balloon").render()))
        shown = str(app.screen.query_one("#balloon").render())
        assert f"(ozimux via udp 127.0.0.1:{world.ground_station_port})" in shown
        assert f"Feed udp 127.0.0.1:{world.ground_station_port} listening:" in shown
        assert app.fleet.capsules["DRS2"].reading(GnssSample).value is None, (
            "DRS2 is not powered: no GNSS of its own"
        )
        origin = app.prediction_origin("DRS2")
        assert (
            origin is not None
            and origin.source == f"balloon feed (udp 127.0.0.1:{world.ground_station_port})"
        )
        await wait_for(pilot, lambda: app.fleet.capsules["DRS2"].predictions.get(0) is not None)
        prediction = app.fleet.capsules["DRS2"].predictions[0].value
        assert prediction is not None and prediction.origin_source == origin.source


async def test_the_fleet_says_computing_until_the_first_prediction_then_shows_it(
    demo: tuple[DemoWorld, DrsConsole],
) -> None:
    """A first prediction that takes a while (numba compiling, weather decoding) is never a blank."""
    world, app = demo
    service = app.setup.predictions
    assert service is not None
    release = threading.Event()
    compute = service.predict

    def slow_predict(*args: Any, **kwargs: Any) -> Any:
        release.wait(timeout=120)
        return compute(*args, **kwargs)

    service.predict = slow_predict  # type: ignore[method-assign]
    async with app.run_test(size=(120, 40)) as pilot:
        try:
            await wait_for(pilot, lambda: "computing the landing from" in painted(detail_of(app)))
            prediction_field = next(field for field in FIELDS if field.kind == "prediction")
            assert prediction_field.cell(app.fleet.capsules["DRS1"], app.now()).text == "computing…"
        finally:
            release.set()
        await wait_for(pilot, lambda: app.fleet.capsules["DRS1"].reading(PredictionSample).value is not None)
        await wait_for(pilot, lambda: "landing " in painted(detail_of(app)))
        assert "computing" not in painted(detail_of(app))


async def test_without_weather_the_fleet_says_how_to_load_it(
    tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    config = offline_config(tmp_path)
    setup = ConsoleSetup(mode="live", capsules=["DRS1"], server=offline_server(config, request))
    app = DrsConsole(setup)
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for(pilot, lambda: "no weather loaded" in painted(detail_of(app)))
        assert "start with --weather FILES (or drs weather fetch)" in painted(detail_of(app))
        prediction_field = next(field for field in FIELDS if field.kind == "prediction")
        assert prediction_field.cell(app.fleet.capsules["DRS1"], app.now()).text == "no weather"

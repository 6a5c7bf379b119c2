"""The balloon's position reaches the console from the configured ground-station feed (here, the demo's UDP)."""

from __future__ import annotations

import pytest

from console.app import DrsConsole
from console.demo import DemoWorld
from tests.console.conftest import wait_for

pytestmark = pytest.mark.asyncio


async def test_the_demo_balloon_arrives_over_udp_and_starts_predictions_before_power_on(
    demo: tuple[DemoWorld, DrsConsole],
) -> None:
    world, app = demo
    async with app.run_test(size=(80, 24)) as pilot:
        await wait_for(pilot, lambda: app.fleet.balloon.value is not None)
        value = app.fleet.balloon.value
        assert value is not None
        assert value["format"] == "ozimux"
        assert value["source"] == f"udp 127.0.0.1:{world.ground_station_port}"
        assert abs(value["lat"] - world.balloon[0]) < 0.05 and abs(value["lon"] - world.balloon[1]) < 0.1
        feed = app.setup.balloon_feed
        assert feed is not None
        status = feed.status()
        assert status.accepted >= 1 and status.rejected == 0
        await wait_for(pilot, lambda: "fixes" in str(app.screen.query_one("#balloon").render()))
        shown = str(app.screen.query_one("#balloon").render())
        assert f"(ozimux via udp 127.0.0.1:{world.ground_station_port})" in shown
        assert f"Feed udp 127.0.0.1:{world.ground_station_port} listening:" in shown
        assert app.fleet.capsules["DRS2"].reading("gnss").value is None, (
            "DRS2 is not powered: no GNSS of its own"
        )
        origin = app.prediction_origin("DRS2")
        assert (
            origin is not None
            and origin.source == f"balloon feed (udp 127.0.0.1:{world.ground_station_port})"
        )
        await wait_for(pilot, lambda: app.fleet.capsules["DRS2"].predictions.get(0) is not None)
        prediction = app.fleet.capsules["DRS2"].predictions[0].value
        assert prediction is not None and prediction["origin_source"] == origin.source

"""A commanding console shows the telemetry the operations server polls (issue #29: the server polls each
Pi once for every console), and says once, not at every retry, when that stream stops."""

from __future__ import annotations

from typing import Any

import pytest

from console.app import EVENTS_RETRY_S, DrsConsole
from console.demo import DemoWorld
from drs_link.server import Client
from tests.console.conftest import wait_for

pytestmark = pytest.mark.asyncio
STOPPED = "the operations server's telemetry stopped"


async def test_the_console_shows_the_servers_polls_and_says_once_that_they_stopped(
    demo: tuple[DemoWorld, DrsConsole],
) -> None:
    _, app = demo
    said: list[str] = []
    notify = app.notify

    def heard(message: str, **options: Any) -> None:
        said.append(message)
        notify(message, **options)

    app.notify = heard  # type: ignore[method-assign]
    tries: list[int] = []
    client = app.context.client

    def connecting() -> Client:
        tries.append(1)
        return client()

    app.context.client = connecting  # type: ignore[method-assign]
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for(pilot, lambda: app.fleet.capsules["DRS1"].facts(app.now())["link_up"] is True)
        await wait_for(pilot, lambda: app.fleet.gateway.value is not None)
        assert app.setup.stop_server is not None
        app.setup.stop_server()
        await wait_for(pilot, lambda: any(STOPPED in line for line in said))
        before = len(tries)
        await pilot.pause(3 * EVENTS_RETRY_S)
        assert len(tries) >= before + 2, "the streams were tried again meanwhile, and failed again"
        assert sum(STOPPED in line for line in said) == 1, said

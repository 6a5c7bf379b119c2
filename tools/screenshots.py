"""Regenerate docs/screenshots/*.svg from the running demo (``make screenshots``).

Drives the same demo ``make demo`` starts (simulated capsules over SSH, the simulated RockBLOCK,
the UDP balloon feed, demo weather) through a release of DRS1 by keys, and saves each main
screen as Textual exports it, so the README shows what an operator sees today, not last month.
"""

from __future__ import annotations

import asyncio
import sys
import tempfile
import time
from collections.abc import Callable
from pathlib import Path

from textual.pilot import Pilot

from console.app import DrsConsole
from console.commands.console import demo_setup
from console.demo import DemoWorld
from drs_link.ops.arming import ArmState

SIZE = (120, 36)
SPEED = 20.0
OUT = Path(__file__).resolve().parent.parent / "docs" / "screenshots"


async def wait_for(
    pilot: Pilot[int], what: str, condition: Callable[[], bool], timeout_s: float = 120.0
) -> None:
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            told = "; ".join([n.message for n in pilot.app._notifications][-3:])
            raise SystemExit(f"screenshots: timed out waiting for {what} (last notices: {told or 'none'})")
        await pilot.pause(0.2)


def shown(app: DrsConsole, selector: str) -> str:
    return str(app.screen.query_one(selector).render())


async def save(pilot: Pilot[int], app: DrsConsole, name: str) -> None:
    await pilot.pause(0.5)
    app.save_screenshot(f"{name}.svg", str(OUT))
    print(f"wrote {OUT / name}.svg", flush=True)


async def drive(app: DrsConsole, world: DemoWorld) -> None:
    async with app.run_test(size=SIZE) as pilot:
        fleet = app.fleet.capsules
        await wait_for(pilot, "DRS1 link", lambda: fleet["DRS1"].facts(app.now())["link_up"] is True)
        await wait_for(pilot, "predictions", lambda: all(0 in fleet[n].predictions for n in ("DRS1", "DRS2")))
        await wait_for(pilot, "the balloon feed", lambda: "fixes" in shown(app, "#balloon"))
        await save(pilot, app, "fleet")
        await pilot.press("t")
        await save(pilot, app, "fleet-light")
        await pilot.press("t")

        await pilot.press("down", "p")
        await wait_for(pilot, "the release window", lambda: getattr(app.screen, "window", None) is not None)
        await save(pilot, app, "predictions")
        await pilot.press("escape")
        await wait_for(pilot, "the fleet", lambda: type(app.screen).__name__ == "FleetScreen")

        await pilot.press("up", "enter", "s")
        await wait_for(pilot, "DRS1 synced", lambda: fleet["DRS1"].facts(app.now())["sync_fraction"] == 1.0)
        await pilot.press("o")
        await pilot.press("tab", "enter")
        await wait_for(pilot, "go/no-go GO", lambda: app.gonogo("DRS1").go)
        await pilot.press("a")
        arming = app.ops.ops("DRS1").arming  # type: ignore[union-attr]
        await wait_for(pilot, "ARMED", lambda: arming.status().armed)
        await save(pilot, app, "release-armed")
        await pilot.press("f", *"DRS1")
        await save(pilot, app, "fire-confirmation")
        await pilot.press("enter", "enter", *"demo drop", "enter")
        await wait_for(pilot, "FIRED", lambda: arming.status().state is ArmState.FIRED)
        await pilot.press("escape")
        await wait_for(pilot, "the fleet", lambda: type(app.screen).__name__ == "FleetScreen")

        world.iridium[app.ops.ops("DRS1").config.imei].interval_min = 1  # type: ignore[union-attr]
        await pilot.press("v")
        await wait_for(
            pilot, "the live re-prediction", lambda: "Live re-prediction from" in shown(app, "#recovery-text")
        )
        await wait_for(pilot, "a measured leg", lambda: "from 1 leg" in shown(app, "#recovery-text"))
        await save(pilot, app, "recovery")
        await pilot.press("i")
        await wait_for(pilot, "the Iridium screen", lambda: type(app.screen).__name__ == "IridiumScreen")
        await app.workers.wait_for_complete()
        await pilot.press("c")
        await wait_for(pilot, "the PARACHUTE helper", lambda: type(app.screen).__name__ == "HazardModal")
        await save(pilot, app, "iridium-parachute")
        await pilot.press("escape", "escape", "escape")
        await wait_for(pilot, "the fleet", lambda: type(app.screen).__name__ == "FleetScreen")
        await pilot.press("h")
        await save(pilot, app, "history")


def main() -> int:
    world = DemoWorld(Path(tempfile.mkdtemp(prefix="drs-screenshots-")), SPEED)
    config = world.start()
    setup = None
    try:
        setup = demo_setup(world, config, world.root / "exports", poll_period_s=1.0)
        asyncio.run(drive(DrsConsole(setup), world))
    finally:
        if setup is not None:
            setup.close()
        world.stop()
    return 0


if __name__ == "__main__":
    sys.exit(main())

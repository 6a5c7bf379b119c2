"""The release flow driven by keys in the real app against the demo's simulated capsules over SSH.

The console acts through the demo's private operations server (``drs_link.server``): the ARM state it shows
is the server's, and the refusals are the server's, in the words of ``drs_link.ops``. Another account's
approval needs a shared server: ``tests/console/test_console_two_accounts.py``."""

from __future__ import annotations

from collections.abc import Callable

import msgspec
import pytest
from textual.pilot import Pilot
from textual.widgets import Label, Static

from console.app import DrsConsole, TelemetryArrived
from console.demo import DemoWorld
from console.screens.modals import ConfirmModal, HazardModal
from console.screens.release import ReleaseScreen
from drs_link.errors import RefusedError
from drs_link.ops.arming import ArmingController
from drs_link.ops.capsule import ReleaseState
from drs_link.ops.telemetry import LinkSample, TelemetryRecord
from drs_link.server.protocol import ArmState, Second
from drs_link.sim.firmware import BOOT_S
from tests.clock import SkipClock
from tests.console.conftest import wait_for

pytestmark = pytest.mark.asyncio


def booting(clock: SkipClock, speed: float) -> Callable[[], None]:
    """Skips through DRS1's boot (``BOOT_S`` of simulated time) in steps of 2 simulated seconds, one a
    look at the poll: the poll after the last step is fresh and GO, and nothing is armed meanwhile."""
    return clock.skipper(2.0 / speed, BOOT_S / speed)


async def open_release_go(
    pilot: Pilot[int], app: DrsConsole, boot: Callable[[], None] | None = None
) -> ReleaseScreen:
    """Fleet → release screen of DRS1, sync its data, power it on, wait until the poll is GO (``boot``:
    called while it boots, ``booting``)."""
    await wait_for(pilot, lambda: app.fleet.capsules["DRS1"].facts(app.now())["link_up"] is True)
    await pilot.press("enter")
    screen = app.screen
    assert isinstance(screen, ReleaseScreen) and screen.capsule == "DRS1"
    await pilot.press("s")
    try:
        await wait_for(pilot, lambda: app.fleet.capsules["DRS1"].facts(app.now())["sync_fraction"] == 1.0)
    except AssertionError:  # seen once in a fresh clone's quiet run: say what the console was told
        told = [n.message for n in app._notifications]
        sync = app.fleet.capsules["DRS1"].facts(app.now())["sync_fraction"]
        raise AssertionError(
            f"DRS1 never synced: sync fraction {sync}; the console was told {told}"
        ) from None
    await pilot.press("o")
    assert isinstance(app.screen, ConfirmModal)
    await pilot.press("tab", "enter")
    await wait_for(pilot, lambda: app.gonogo("DRS1").go, skip=boot)
    return screen


async def test_fire_is_disabled_until_armed_and_the_domain_refuses_it_anyway(
    demo: tuple[DemoWorld, DrsConsole],
) -> None:
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for(pilot, lambda: app.fleet.capsules["DRS1"].facts(app.now())["link_up"] is True)
        await pilot.press("enter")
        screen = app.screen
        assert screen.check_action("fire", ()) is None
        await pilot.press("f")
        assert app.screen is screen
        with pytest.raises(RefusedError, match="not armed"):  # the server's refusal, as ops words it
            app.context.fire("DRS1", "DRS1", Second(waiver="test"), lambda pending: None)
        assert world.sims[0].firmware.go_at is None


async def test_a_sync_that_fails_unexpectedly_is_said_to_the_operator_not_swallowed_by_its_worker(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch
) -> None:
    """A screen's worker that raises what it did not expect (here the server's answer does not parse)
    is said: Textual does not bubble a worker's failure from the screen to the app, and ``s`` once left
    "syncing data…" as the last word of a sync that had died."""
    world, app = demo

    def malformed(capsule: str) -> None:
        raise msgspec.ValidationError("Expected `object`, got `str`")

    async with app.run_test(size=(120, 40)) as pilot:
        await wait_for(pilot, lambda: app.fleet.capsules["DRS1"].facts(app.now())["link_up"] is True)
        await pilot.press("enter")
        assert isinstance(app.screen, ReleaseScreen)
        monkeypatch.setattr(app.context, "sync", malformed)
        await pilot.press("s")
        await wait_for(pilot, lambda: any(
            n.message == "sync failed: ValidationError: Expected `object`, got `str`" and n.severity == "error"
            for n in app._notifications
        ))  # fmt: skip


async def test_a_complete_release_by_keys_sends_go_to_the_simulated_capsule(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await open_release_go(pilot, app, booting(skip_clock, world.speed))
        polls_never_disarm(app, monkeypatch)
        await arm(pilot, app)
        assert shown(app).state == "armed" and screen.check_action("fire", ()) is True
        await pilot.press("f")
        assert isinstance(app.screen, HazardModal)
        await pilot.press(*"DRS1", "enter", "enter", *"test drop", "enter")
        await wait_for(pilot, lambda: world.sims[0].firmware.go_at is not None)
        await wait_for(pilot, lambda: shown(app).state == "fired")
        assert app.ops.state.ops("DRS1").machine.record().state is ReleaseState.RELEASED  # type: ignore[union-attr]
        actions = [(a.action, a.result) for a in app.store.audit("DRS1")]
        assert ("fire", "authorised") in actions and ("go", "released, Pi shut down") in actions
        for action in ("power_on", "arm", "fire", "sync", "waive"):
            assert screen.check_action(action, ()) is False, f"{action} after release: not in the footer"
        assert screen.check_action("reset", ()) is True
        await wait_for(pilot, lambda: app.gonogo("DRS1").summary().startswith("NO-GO: Released: released "))


async def arm(pilot: Pilot[int], app: DrsConsole) -> None:
    """``a``: the ARM goes to the server off the UI thread; FIRE is offered once the server says ARMED."""
    await pilot.press("a")
    await wait_for(pilot, lambda: shown(app).state == "armed" and shown(app).mine)


def shown(app: DrsConsole, capsule: str = "DRS1") -> ArmState:
    """The capsule's ARM window as the console has it from the server (disarmed before any push)."""
    return app.context.arm_state(capsule) or ArmState(capsule, "disarmed", None, None, 0.0, None)


def polls_never_disarm(app: DrsConsole, monkeypatch: pytest.MonkeyPatch) -> None:
    """DRS1's window, closed only by time and by FIRE: the console's go/no-go poll no longer disarms it.

    On a loaded machine the demo's poll (×8 pace) can see the SSH link 20 demo seconds stale, a
    2.5 s stall, and disarm with its own reason before what a test is about. That poll's disarming is
    pinned in ``tests/drs_link/ops/test_arming.py`` and by ``test_link_loss_disarms`` and
    ``test_stale_data_blocks_arm`` here; FIRE still polls again on the server.
    """
    monkeypatch.setattr(app, "watch_arming", lambda capsules, links_lost: None)


async def test_a_wrong_capsule_name_is_refused_and_nothing_is_sent(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        await open_release_go(pilot, app, booting(skip_clock, world.speed))
        polls_never_disarm(app, monkeypatch)
        await arm(pilot, app)
        await pilot.press("f", *"DRS2", "enter", "enter", *"alone", "enter")
        await wait_for(pilot, lambda: any(a.action == "fire" for a in app.store.audit("DRS1")))
        await pilot.pause(0.5)
        assert world.sims[0].firmware.go_at is None
        assert app.store.audit("DRS1", text="wrong capsule name")


async def test_link_loss_disarms(demo: tuple[DemoWorld, DrsConsole], skip_clock: SkipClock) -> None:
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        await open_release_go(pilot, app, booting(skip_clock, world.speed))
        await arm(pilot, app)
        app.post_message(TelemetryArrived([TelemetryRecord(app.now(), "DRS1", LinkSample(up=False))]))
        await wait_for(pilot, lambda: shown(app).state != "armed")
        assert shown(app).reason == "link lost"
        assert app.screen.check_action("fire", ()) is None


async def test_stale_data_blocks_arm(canned_app: Callable[..., DrsConsole]) -> None:
    """The server polls go/no-go itself for ARM: a capsule it cannot reach is NO-GO, refused on the
    record, and the screen says the server's refusal."""
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter", "a")
        await wait_for(pilot, lambda: any("ARM refused" in n.message for n in app._notifications))
        assert shown(app).state == "disarmed"
        refusal = [a for a in app.store.audit("DRS1") if a.action == "arm"][-1]
        assert refusal.result == "refused" and "NO-GO" in str(refusal.detail["reason"])


async def test_an_interval_command_is_queued_at_the_simulated_gateway_after_naming_the_capsule(
    demo: tuple[DemoWorld, DrsConsole],
) -> None:
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("i", "n", *"5", "enter")
        await pilot.press(*"DRS2", "enter")
        await pilot.pause(0.5)
        assert world.gateway is not None and world.gateway.requests == []
        await pilot.press("n", *"5", "enter", *"DRS1", "enter")
        await wait_for(pilot, lambda: len(world.gateway.requests) == 1)
        assert bytes.fromhex(world.gateway.requests[0].form["data"]) == b"[INTERVAL=5]"
        assert app.ops is not None
        await wait_for(
            pilot, lambda: [c.state for c in app.ops.iridium.commands("DRS1")] == ["not_sent", "queued"]
        )
        assert app.store.audit("DRS1", text="confirmation does not name the capsule")


async def test_time_runs_behind_the_fire_dialog_and_fire_after_the_arm_window_is_refused_naming_it(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    """The ARM window runs out while the FIRE dialog is open: the clock skips past its end (not waited
    out: 120 demo seconds were 15 s of wall clock at ×8), and FIRE then checks it again."""
    world, app = demo
    async with app.run_test(size=(80, 24)) as pilot:
        screen = await open_release_go(pilot, app, booting(skip_clock, world.speed))
        polls_never_disarm(app, monkeypatch)
        await arm(pilot, app)
        await pilot.press("f")
        modal = app.screen
        assert isinstance(modal, HazardModal)
        countdown = modal.query_one("#countdown", Label)
        assert str(countdown.render()).startswith("ARMED — ")
        behind = screen.query_one("#arm-status", Static)
        first = str(behind.render())
        await wait_for(pilot, lambda: str(behind.render()) != first)  # the screen behind keeps time
        assert shown(app).state == "armed"
        skip_clock.skip((shown(app).remaining_s + 1.0) / world.speed)
        await wait_for(pilot, lambda: shown(app).state != "armed")
        await wait_for(pilot, lambda: "ARM window expired at" in str(behind.render()))
        await wait_for(pilot, lambda: str(countdown.render()).startswith("NOT ARMED (ARM window expired at"))
        await pilot.press(*"DRS1", "enter", "enter", *"test drop", "enter")
        await wait_for(pilot, lambda: any("FIRE refused: not armed: ARM window expired at" in n.message
                                          for n in app._notifications))  # fmt: skip
        assert world.sims[0].firmware.go_at is None


async def test_asking_another_login_in_the_demo_is_refused_by_its_private_server_with_the_way_to_a_shared_one(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    """Only this account reaches the demo's private server, so no second account can approve there."""
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        await open_release_go(pilot, app, booting(skip_clock, world.speed))
        polls_never_disarm(app, monkeypatch)
        await arm(pilot, app)
        await pilot.press("f", *"DRS1")
        await pilot.click("#approval")
        await wait_for(pilot, lambda: any("require_second_operator needs a second account" in n.message
                                          and "drs setup server --group GROUP" in n.message
                                          for n in app._notifications))  # fmt: skip
        assert world.sims[0].firmware.go_at is None
        assert shown(app).state == "armed", "the refusal changed nothing"


async def test_a_window_another_console_holds_is_shown_as_theirs_and_fire_stays_off(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    """#23: two consoles were both ARMED on one capsule, each reading the other's notices as its own."""
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await open_release_go(pilot, app, booting(skip_clock, world.speed))
        polls_never_disarm(app, monkeypatch)
        assert app.ops is not None
        mine = app.ops.state.ops("DRS1").arming  # a console of before the server, on the same store
        other = ArmingController(app.store, mine.machine, "JM", clock=mine.clock, holder="jm@laptop2 pid 7")
        other.arm(app.gonogo("DRS1"))
        line = screen.query_one("#arm-status", Static)
        await wait_for(pilot, lambda: "ARMED by another console (held by JM at " in str(line.render()))
        assert screen.check_action("fire", ()) is None

        # ARM polls go/no-go first, and a NO-GO poll is refused before the window is looked at. Under load
        # (CI with two CPU hogs, 2026-12-03) the wait for the held window's refusal once ran out, with no
        # word of what came instead: an operator presses again after a NO-GO, and so does this test.
        def refusals() -> list[str]:
            return [n.message for n in app._notifications if "ARM refused" in n.message]

        for _ in range(5):
            seen = len(refusals())
            await pilot.press("a")
            await wait_for(pilot, lambda seen=seen: len(refusals()) > seen)
            if "ARM refused: ARM window #1 is held by JM at " in refusals()[-1]:
                break
        else:
            raise AssertionError(f"never refused for the window JM holds: {refusals()}")
        assert other.status().mine and other.status().armed, "the refusal changed nothing"
        assert world.sims[0].firmware.go_at is None

"""The release flow driven by keys in the real app against the demo's simulated capsules over SSH."""

from __future__ import annotations

from collections.abc import Callable

import pytest
from textual.pilot import Pilot
from textual.widgets import Label, Static

from console.app import DrsConsole, TelemetryArrived
from console.demo import DemoWorld
from console.screens.modals import ConfirmModal, HazardModal
from console.screens.release import ReleaseScreen
from drs_link.errors import RefusedError
from drs_link.ops.approval import ApprovalBook, Login, current_login
from drs_link.ops.arming import ArmingController, ArmState
from drs_link.ops.capsule import ReleaseState
from drs_link.ops.operations import SecondOperator
from drs_link.ops.telemetry import LinkSample, TelemetryRecord
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
    await wait_for(pilot, lambda: app.fleet.capsules["DRS1"].facts(app.now())["sync_fraction"] == 1.0)
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
        assert app.ops is not None
        with pytest.raises(RefusedError, match="not armed"):
            app.ops.fire("DRS1", "DRS1", lambda: app.gonogo("DRS1"), SecondOperator(waiver="test"))
        assert world.sims[0].firmware.go_at is None


async def test_a_complete_release_by_keys_sends_go_to_the_simulated_capsule(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await open_release_go(pilot, app, booting(skip_clock, world.speed))
        arming = polls_never_disarm(app, monkeypatch)
        await arm(pilot, app)
        assert arming.status().armed and screen.check_action("fire", ()) is True
        await pilot.press("f")
        assert isinstance(app.screen, HazardModal)
        await pilot.press(*"DRS1", "enter", "enter", *"test drop", "enter")
        await wait_for(pilot, lambda: world.sims[0].firmware.go_at is not None)
        await wait_for(pilot, lambda: arming.status().state is ArmState.FIRED)
        assert app.ops.ops("DRS1").machine.record().state is ReleaseState.RELEASED  # type: ignore[union-attr]
        actions = [(a.action, a.result) for a in app.store.audit("DRS1")]
        assert ("fire", "authorised") in actions and ("go", "released, Pi shut down") in actions
        for action in ("power_on", "arm", "fire", "sync", "waive"):
            assert screen.check_action(action, ()) is False, f"{action} after release: not in the footer"
        assert screen.check_action("reset", ()) is True
        await wait_for(pilot, lambda: app.gonogo("DRS1").summary().startswith("NO-GO: Released: released "))


async def arm(pilot: Pilot[int], app: DrsConsole) -> None:
    """``a``: the ARM is a store write off the UI thread; FIRE is offered once it is on the record."""
    await pilot.press("a")
    await wait_for(pilot, lambda: app.context.arming("DRS1").status().armed)


def polls_never_disarm(app: DrsConsole, monkeypatch: pytest.MonkeyPatch) -> ArmingController:
    """DRS1's arming, closed only by time and by FIRE: the go/no-go poll no longer disarms it.

    On a loaded machine the demo's poll (×8 pace) can see the SSH link 20 demo seconds stale, a
    2.5 s stall, and disarm (or refuse FIRE, which reads the poll again) with its own reason before
    what a test is about. That poll's disarming is pinned in ``tests/drs_link/ops/test_arming.py`` and
    by ``test_link_loss_disarms`` and ``test_stale_data_blocks_arm`` here.
    """
    arming = app.ops.ops("DRS1").arming  # type: ignore[union-attr]
    monkeypatch.setattr(arming, "observe", lambda report: arming.status())
    return arming


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
        arming = app.ops.ops("DRS1").arming  # type: ignore[union-attr]
        assert arming.status().armed
        app.post_message(TelemetryArrived([TelemetryRecord(app.now(), "DRS1", LinkSample(up=False))]))
        await wait_for(pilot, lambda: not arming.status().armed)
        assert arming.status().last_disarm_reason == "link lost"
        assert app.screen.check_action("fire", ()) is None


async def test_stale_data_blocks_arm(canned_app: Callable[..., DrsConsole]) -> None:
    from datetime import timedelta

    from tests.console.conftest import T0

    app = canned_app(now=T0 + timedelta(seconds=60))
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter", "a")
        assert app.ops is not None
        await wait_for(
            pilot, lambda: app.store.audit("DRS1", action="arm") != []
        )  # written off the UI thread
        status = app.ops.ops("DRS1").arming.status()
        assert status.state is ArmState.DISARMED
        refusal = app.store.audit("DRS1")[-1]
        assert (refusal.action, refusal.result) == ("arm", "refused") and "STALE" in refusal.detail["reason"]


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
        await wait_for(pilot, lambda: [c.state for c in app.ops.commands("DRS1")] == ["not_sent", "queued"])
        assert app.store.audit("DRS1", text="confirmation does not name the capsule")


async def test_time_runs_behind_the_fire_dialog_and_fire_after_the_arm_window_is_refused_naming_it(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    """The ARM window runs out while the FIRE dialog is open: the clock skips past its end (not waited
    out: 120 demo seconds were 15 s of wall clock at ×8), and FIRE then checks it again."""
    world, app = demo
    async with app.run_test(size=(80, 24)) as pilot:
        screen = await open_release_go(pilot, app, booting(skip_clock, world.speed))
        arming = polls_never_disarm(app, monkeypatch)
        await arm(pilot, app)
        assert arming.status().armed
        await pilot.press("f")
        modal = app.screen
        assert isinstance(modal, HazardModal)
        countdown = modal.query_one("#countdown", Label)
        assert str(countdown.render()).startswith("ARMED — ")
        behind = screen.query_one("#arm-status", Static)
        first = str(behind.render())
        await wait_for(pilot, lambda: str(behind.render()) != first)  # the screen behind keeps time
        assert arming.status().armed
        skip_clock.skip((arming.status().remaining_s + 1.0) / world.speed)
        await wait_for(pilot, lambda: not arming.status().armed)
        await wait_for(pilot, lambda: "ARM window expired at" in str(behind.render()))
        await wait_for(pilot, lambda: str(countdown.render()).startswith("NOT ARMED (ARM window expired at"))
        await pilot.press(*"DRS1", "enter", "enter", *"test drop", "enter")
        await wait_for(pilot, lambda: any("FIRE refused: not armed: ARM window expired at" in n.message
                                          for n in app._notifications))  # fmt: skip
        assert world.sims[0].firmware.go_at is None


async def test_fire_waits_for_another_login_to_approve_then_releases(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        await open_release_go(pilot, app, booting(skip_clock, world.speed))
        arming = polls_never_disarm(app, monkeypatch)
        await arm(pilot, app)
        await pilot.press("f", *"DRS1")
        await pilot.click("#approval")
        book = ApprovalBook(app.store)
        await wait_for(pilot, lambda: bool(book.open_requests("DRS1")))
        [request] = book.open_requests("DRS1")
        assert request.action == "go" and request.requester == current_login()
        await pilot.pause(0.5)
        assert world.sims[0].firmware.go_at is None, "nothing is sent while the request waits"
        with pytest.raises(RefusedError, match="cannot approve it"):
            book.decide(request.id, "EL", current_login(), approve=True)
        book.decide(request.id, "JM", Login("jm-on-the-other-console"), approve=True)
        await wait_for(pilot, lambda: arming.status().state is ArmState.FIRED)
        assert world.sims[0].firmware.go_at is not None
        [fire] = [a for a in app.store.audit("DRS1") if a.action == "fire" and a.result == "authorised"]
        assert fire.detail is not None and fire.detail["approved_by"] == "JM (jm-on-the-other-console)"


async def test_a_waiting_approval_is_a_live_line_with_its_countdown_and_c_cancels_it(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    """#23: the waiting request showed only as a toast and stayed pending after its window closed."""
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await open_release_go(pilot, app, booting(skip_clock, world.speed))
        polls_never_disarm(app, monkeypatch)
        assert screen.check_action("cancel_approval", ()) is False, "nothing waits: no cancel key"
        await arm(pilot, app)
        await pilot.press("f", *"DRS1")
        await pilot.click("#approval")
        book = ApprovalBook(app.store)
        await wait_for(pilot, lambda: bool(book.open_requests("DRS1")))
        [request] = book.open_requests("DRS1")
        assert request.command == f"ARM window #{request.window_id}"
        line = screen.query_one("#arm-status", Static)
        await wait_for(pilot, lambda: f"approval #{request.id}" in str(line.render()))
        first = str(line.render())
        assert "s left · c cancels" in first and screen.check_action("cancel_approval", ()) is True
        await wait_for(pilot, lambda: str(line.render()) != first)  # its own countdown runs
        await pilot.press("c")
        await wait_for(pilot, lambda: any(f"approval #{request.id} cancelled" in n.message
                                          for n in app._notifications))  # fmt: skip
        await wait_for(pilot, lambda: f"approval #{request.id}" not in str(line.render()))
        with pytest.raises(RefusedError, match="is cancelled"):
            book.decide(request.id, "JM", Login("jm-on-the-other-console"), approve=True)
        await pilot.pause(0.5)
        assert world.sims[0].firmware.go_at is None
        assert [a.result for a in app.store.audit("DRS1") if a.action == "approval.cancelled"] == [
            "cancelled"
        ]


async def test_a_window_another_console_holds_is_shown_as_theirs_and_fire_stays_off(
    demo: tuple[DemoWorld, DrsConsole], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    """#23: two consoles were both ARMED on one capsule, each reading the other's notices as its own."""
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        screen = await open_release_go(pilot, app, booting(skip_clock, world.speed))
        mine = polls_never_disarm(app, monkeypatch)
        other = ArmingController(app.store, mine.machine, "JM", clock=mine.clock, holder="jm@laptop2 pid 7")
        other.arm(app.gonogo("DRS1"))
        line = screen.query_one("#arm-status", Static)
        await wait_for(pilot, lambda: "ARMED by another console (held by JM at " in str(line.render()))
        assert screen.check_action("fire", ()) is None
        await pilot.press("a")
        await wait_for(pilot, lambda: any("ARM refused: ARM window #1 is held by JM at " in n.message
                                          for n in app._notifications))  # fmt: skip
        assert other.status().mine and other.status().armed, "the refusal changed nothing"
        assert world.sims[0].firmware.go_at is None

"""The console over SSH: a dropped session is a fault it survives, and consoles on one store see each other."""

from __future__ import annotations

import signal
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest
from textual.widgets import DataTable

from console.demo import DemoWorld
from console.screens.approvals import ApprovalScreen
from console.screens.modals import ConfirmModal
from drs_link.ops.approval import ApprovalBook, Login, current_login
from drs_link.ops.arm_window import ArmWindows
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.session import LOST, record_loss
from drs_link.store import Store
from tests.clock import SkipClock
from tests.console.conftest import (
    ConsoleUnderTest,
    console_on,
    offline_config,
    wait_for,
    window_of_this_account,
)
from tests.console.test_release_flow import arm, booting, open_release_go, polls_never_disarm, shown

pytestmark = pytest.mark.asyncio


async def test_sighup_while_armed_disarms_on_the_record_and_ends_the_console(
    canned_app: Callable[..., ConsoleUnderTest],
) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter")
        window_of_this_account(app)
        await wait_for(pilot, lambda: getattr(app.context.arm_state("DRS1"), "state", None) == "armed")
        app.session_lost(signal.SIGHUP)
        await wait_for(pilot, lambda: not app.is_running)
    assert app.return_value == 128 + signal.SIGHUP
    assert ("disarm", "session lost (SIGHUP)") in [(a.action, a.result) for a in app.store.audit("DRS1")]
    [lost] = [a for a in app.store.audit() if a.action == LOST]
    assert lost.detail == {"signal": "SIGHUP", "disarmed": ["DRS1"], "go_in_flight": []}


async def test_sigterm_during_go_lets_the_go_finish_before_the_console_ends(
    canned_app: Callable[..., ConsoleUnderTest],
) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        window = window_of_this_account(app, firing=True)  # Go is being sent, by the server
        await wait_for(pilot, lambda: getattr(app.context.arm_state("DRS1"), "state", None) == "firing")
        app.session_lost(signal.SIGTERM)
        await pilot.pause(0.6)
        assert app.is_running, "the Go's own worker must finish and record it first"
        ArmWindows(app.store).fired(window.id, app.store.clock())
        await wait_for(pilot, lambda: not app.is_running)
    assert app.return_value == 128 + signal.SIGTERM
    [lost] = [a for a in app.store.audit() if a.action == LOST]
    assert lost.detail is not None and lost.detail["go_in_flight"] == ["DRS1"]


def live_console(tmp_path: Path) -> ConsoleUnderTest:
    """A commanding console with its timers running, on capsules nobody listens for (port 9)."""
    from console.app import ConsoleSetup

    config = offline_config(tmp_path)
    store = Store.open(config.store_path)
    setup = ConsoleSetup(mode="live", capsules=["DRS1", "DRS2", "DRS3"], export_dir=tmp_path / "exports")
    return console_on(OperatorOps(config, store), setup)


async def test_the_next_console_shows_how_the_last_session_ended(tmp_path: Path) -> None:
    store = Store.open(offline_config(tmp_path).store_path)
    record_loss(store, "EL", "SIGHUP", [], go_in_flight=[])
    app = live_console(tmp_path)
    try:
        async with app.run_test(size=(120, 40)) as pilot:
            await wait_for(
                pilot, lambda: any("last console: session lost at" in n.message for n in app._notifications)
            )
            await pilot.press("q", "tab", "enter")
    finally:
        app.setup.close()
    assert [a.action for a in store.audit() if a.action.startswith("session.")][-1] == "session.started"


async def test_what_another_console_does_to_the_store_shows_here_with_who_did_it(tmp_path: Path) -> None:
    app = live_console(tmp_path)
    config = tmp_path / "other.toml"
    config.write_text(f'[operator]\nname = "JM"\n[data]\ndir = "{tmp_path / "data"}"\n'
                      '[[capsule]]\nname = "DRS2"\nhost = "127.0.0.1"\nport = 9\n')  # fmt: skip
    other_console = (
        "import sys; from drs_link.config import load_config; from drs_link.ops.operator_ops import OperatorOps; "
        "from drs_link.store import Store; c = load_config(sys.argv[1]); "
        "OperatorOps(c, Store.open(c.store_path)).state.ops('DRS2').waivers.grant('gnss', 'JM', 'no sky in the hangar')"
    )
    try:
        async with app.run_test(size=(120, 40)) as pilot:
            await pilot.pause(0.5)
            subprocess.run([sys.executable, "-c", other_console, str(config)], check=True)
            await wait_for(
                pilot, lambda: any("DRS2: waiver granted — JM" in n.message for n in app._notifications)
            )
            [note] = [n.message for n in app._notifications if "waiver granted" in n.message]
            assert app.store.session not in note and " pid " in note, "the other process is named"
            await pilot.press("q", "tab", "enter")
    finally:
        app.setup.close()


async def test_sighup_during_a_real_go_lets_it_finish_and_records_it_once(
    demo: tuple[DemoWorld, ConsoleUnderTest], monkeypatch: pytest.MonkeyPatch, skip_clock: SkipClock
) -> None:
    world, app = demo
    async with app.run_test(size=(120, 40)) as pilot:
        await open_release_go(pilot, app, booting(skip_clock, world.speed))
        polls_never_disarm(app, monkeypatch)
        sim = world.sims[0]  # the Pi has acted on Go; Go's answer is heard 3 s later (the polls at once:
        # ARM and FIRE poll over SSH on the server now, and a 15 s window must not run out behind them)
        held = property(lambda faults: 3.0 if sim.firmware.go_at is not None else 0.0)
        monkeypatch.setattr(type(sim.faults), "answer_delay_s", held)
        await arm(pilot, app)
        await pilot.press("f", *"DRS1", "enter", "enter", *"alone", "enter")
        await wait_for(pilot, lambda: shown(app).state == "firing")
        app.session_lost(signal.SIGHUP)
        await pilot.pause(0.5)
        assert app.is_running, "the console waits for the Go in flight"
        await wait_for(pilot, lambda: not app.is_running)
    assert world.sims[0].firmware.go_at is not None
    assert app.return_value == 128 + signal.SIGHUP
    released = [a for a in app.store.audit("DRS1") if a.action == "go" and a.result.startswith("released")]
    assert len(released) == 1
    [lost] = [a for a in app.store.audit() if a.action == LOST]
    assert lost.detail is not None and lost.detail["go_in_flight"] == ["DRS1"]


async def test_a_second_console_approves_from_its_own_login_and_the_requester_cannot(
    canned_app: Callable[..., ConsoleUnderTest],
) -> None:
    app = canned_app()
    book = ApprovalBook(app.store)
    approve = book.request("DRS1", "parachute", "[PARACHUTE=01:19]", "JM", Login("jm-at-the-tent"))
    reject = book.request("DRS3", "authority", "take-over: console2 died", "JM", Login("jm-at-the-tent"))
    mine = book.request("DRS2", "go", "release DRS2", "EL", current_login())
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("A")
        assert isinstance(app.screen, ApprovalScreen)
        table = app.screen.query_one("#approvals", DataTable)
        assert table.row_count == 3
        await pilot.press("enter")  # the first: another login's request
        assert isinstance(app.screen, ConfirmModal)
        await pilot.press("tab", "enter")
        await wait_for(pilot, lambda: book.get(approve.id).state == "approved")
        decider = book.get(approve.id).decider
        assert decider is not None and decider.user == current_login().user, (
            "the kernel's account, at the server"
        )
        await wait_for(pilot, lambda: table.row_count == 2)
        await pilot.press("x", *"console2 is back", "enter")
        await wait_for(pilot, lambda: book.get(reject.id).state == "rejected")
        assert book.get(reject.id).reason == "console2 is back"
        await wait_for(pilot, lambda: table.row_count == 1)
        await pilot.press("enter", "tab", "enter")  # this console's own request
        await wait_for(pilot, lambda: any("cannot approve it" in n.message for n in app._notifications))
        assert book.get(mine.id).state == "pending"


async def test_the_approvals_screen_shows_the_highlighted_requests_brief_as_drs_approve_prints_it(
    canned_app: Callable[..., ConsoleUnderTest],
) -> None:
    """Issue #29 Why-6: the approver reads the command, the verdicts and the waivers before Enter, and
    the confirmation says it again; both are ``Approval.for_approver``, the text `drs approve` prints."""
    from drs_link.ops.brief import ApprovalBrief, VerdictShown, WaiverShown

    app = canned_app()
    book = ApprovalBook(app.store)
    brief = ApprovalBrief(
        "Go: release DRS1 in ARM window #4",
        (
            VerdictShown("SSH link up", "GO", "up, 2 s old"),
            VerdictShown("GNSS fix fresh", "WAIVED", "no fix; waived by JM: shade"),
        ),
        (WaiverShown("gnss", "shade", "JM"),),
    )
    request = book.request("DRS1", "go", "Go: release DRS1", "JM", Login("jm-at-the-tent"), brief=brief)
    async with app.run_test(size=(140, 50)) as pilot:
        await pilot.press("A")
        assert isinstance(app.screen, ApprovalScreen)
        screen = app.screen
        expected = book.get(request.id).for_approver(app.setup.clock())[1:]
        detail = screen.query_one("#approval-detail")
        await wait_for(pilot, lambda: all(line in str(detail.render()) for line in expected))
        await pilot.press("enter")
        assert isinstance(app.screen, ConfirmModal)
        assert all(line in app.screen.body for line in expected)

"""The smaller trust defects of issue #23, item 7, each pinned where the operator reads it.

Each test fails on the console as the issue found it: a console without weather said "needs a fresh
position" on Predictions and in go/no-go, the gateway item said "credentials valid" though nothing had
been checked, and a released capsule's predictions said "computing" for ever.
"""

from __future__ import annotations

import os
import subprocess
import sys
from collections.abc import Callable
from pathlib import Path

import pytest

from console.app import NO_WEATHER, ConsoleSetup, DrsConsole
from console.screens.predictions import PredictionScreen
from drs_link.ops.telemetry import GatewaySample, ReleaseSample, TelemetryRecord
from tests.console.conftest import T0, offline_config, offline_server, wait_for


def painted(app: DrsConsole, selector: str) -> str:
    return str(app.screen.query_one(selector).render())


@pytest.mark.asyncio
async def test_without_weather_predictions_and_go_no_go_say_no_weather_loaded(
    tmp_path: Path, request: pytest.FixtureRequest
) -> None:
    config = offline_config(tmp_path)
    app = DrsConsole(ConsoleSetup(mode="live", capsules=["DRS1"], server=offline_server(config, request)))
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("p")
        assert isinstance(app.screen, PredictionScreen)
        await wait_for(pilot, lambda: "no weather loaded" in painted(app, "#prediction-numbers"))
        assert f"Release now: no prediction yet ({NO_WEATHER})" in painted(app, "#prediction-numbers")
        assert painted(app, "#release-timeline") == f"Release window: {NO_WEATHER}"
        assert "fresh position" not in painted(app, "#prediction-numbers") + painted(app, "#release-timeline")
        [item] = [i for i in app.gonogo("DRS1").items if i.key == "prediction"]
        assert item.detail == NO_WEATHER


@pytest.mark.asyncio
async def test_a_released_capsule_s_predictions_point_to_recovery(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    app.fleet.apply(TelemetryRecord(T0, "DRS3", ReleaseSample("released", released_at=T0)))
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("down", "down", "p")
        assert isinstance(app.screen, PredictionScreen) and app.screen.capsule == "DRS3"
        await wait_for(pilot, lambda: "Recovery" in painted(app, "#prediction-numbers"))
        assert (
            "Release now: no prediction yet (released: no more release predictions; where it is falling "
            "is on Recovery (Esc, then v))" in painted(app, "#prediction-numbers")
        )
        assert painted(app, "#release-timeline").startswith("Release window: released:")
        assert "computing" not in painted(app, "#release-timeline")


@pytest.mark.asyncio
async def test_the_gateway_item_says_configured_and_not_verified(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    app.fleet.apply(TelemetryRecord(T0, None, GatewaySample(True, "user ops")))
    [item] = [i for i in app.gonogo("DRS1").items if i.key == "gateway"]
    assert item.title == "Gateway configured" and item.detail.startswith("not verified, ")
    assert "valid" not in item.title + item.detail


def test_a_missing_configuration_is_named_with_the_path_looked_for(tmp_path: Path) -> None:
    env = {k: v for k, v in os.environ.items() if k != "DRS_CONFIG"}
    env.update(
        HOME=str(tmp_path / "home"),
        XDG_CONFIG_HOME=str(tmp_path / "config"),
        XDG_DATA_HOME=str(tmp_path / "data"),
    )
    done = subprocess.run(
        [sys.executable, "-m", "console.commands.main", "mo", "health", "DRS1"],
        env=env,
        capture_output=True,
        text=True,
        timeout=120,
    )
    assert done.returncode == 1
    assert done.stderr == (
        f"drs: error: no capsule named 'DRS1' in the defaults: no configuration file at "
        f"{tmp_path / 'config' / 'drs' / 'drs.toml'} (create it, or give --config FILE or $DRS_CONFIG) "
        "(known: none configured)\n"
    )


@pytest.mark.asyncio
async def test_every_key_is_in_the_footer_or_the_help(canned_app: Callable[..., DrsConsole]) -> None:
    """Iridium's `C` and `O` were bound but in neither the footer nor the help; Approvals' keys nowhere."""
    from console.screens.help import help_text
    from console.screens.iridium import IridiumScreen

    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("i")
        assert isinstance(app.screen, IridiumScreen)
        await pilot.pause()
        shown = {
            binding.key_display or binding.key
            for _, binding, _, _ in app.active_bindings.values()
            if binding.show
        }
        assert {"o/O", "c/C"} <= shown
    text = help_text()
    assert "`C` parachute at a time you type" in text
    assert "**Approvals**: `↑`/`↓` a request · `Enter` approve it · `x` reject it" in text


@pytest.mark.asyncio
async def test_a_waiver_reason_is_capped_at_its_stated_length(canned_app: Callable[..., DrsConsole]) -> None:
    """A 3,000-character reason pushed go/no-go and the checklist off the screen: the field takes 200, says
    so, and the operations layer refuses a longer one from any caller."""
    from console.screens.modals import TextPromptModal
    from drs_link.errors import RefusedError
    from drs_link.ops import WAIVER_REASON_MAX

    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("enter", "w", "w")
        prompt = app.screen
        assert isinstance(prompt, TextPromptModal)
        field = prompt.query_one("#answer")
        assert WAIVER_REASON_MAX == 200
        assert field.placeholder == "at most 200 characters"  # type: ignore[attr-defined]
        field.value = "x" * 195  # type: ignore[attr-defined]  # typed key by key, 210 keys took 13 s
        await pilot.press(*("x" * 15), "enter")  # the 201st to 210th keys must be refused by the field
        await wait_for(pilot, lambda: bool(app.store.audit("DRS1", text="xxxx")))
        [granted] = [
            r
            for r in app.store.audit("DRS1")
            if r.action == "waiver" and r.result == "granted" and "xxx" in str(r.detail)
        ]
        assert granted.detail is not None and len(granted.detail["reason"]) == 200
        assert app.ops is not None
        with pytest.raises(RefusedError, match=r"a waiver reason is at most 200 characters \(3000 given\)"):
            app.ops.state.ops("DRS1").waivers.grant("gnss", "EL", "y" * 3000)


@pytest.mark.asyncio
async def test_after_release_the_footer_offers_no_arm_fire_power_sync_or_waive(
    canned_app: Callable[..., DrsConsole],
) -> None:
    from console.screens.release import ReleaseScreen

    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("enter")
        assert isinstance(app.screen, ReleaseScreen)
        before = {binding.action for _, binding, enabled, _ in app.active_bindings.values() if binding.show}
        assert {"arm", "fire", "power_on", "sync", "waive"} <= before
        app.fleet.apply(TelemetryRecord(T0, "DRS1", ReleaseSample("released", released_at=T0)))
        app.refresh_screen()
        await pilot.pause()
        after = {binding.action for _, binding, _, _ in app.active_bindings.values() if binding.show}
        assert not {"arm", "fire", "power_on", "sync", "waive"} & after, after
        assert "reset" in {binding.action for _, binding, _, _ in app.active_bindings.values()}


@pytest.mark.asyncio
async def test_arm_while_armed_asks_before_it_restarts_the_window(
    canned_app: Callable[..., DrsConsole],
) -> None:
    from console.screens.modals import ConfirmModal
    from tests.console.conftest import window_of_this_account

    app = canned_app()

    def asked() -> int:
        """ARMs the server was asked for (offline here, each is refused NO-GO on the record)."""
        return len([r for r in app.store.audit("DRS1") if r.action == "arm"])

    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("enter")
        window = window_of_this_account(app)  # as the server's ARM writes it
        await wait_for(pilot, lambda: getattr(app.context.arm_state("DRS1"), "state", None) == "armed")
        await pilot.press("a")
        assert isinstance(app.screen, ConfirmModal), "a second `a` asks first"
        await pilot.press("enter")  # Cancel has the focus: a reflex Enter restarts nothing
        await wait_for(pilot, lambda: not isinstance(app.screen, ConfirmModal))
        await pilot.pause(0.3)
        assert asked() == 0 and getattr(app.context.arm_state("DRS1"), "window", None) == window.id
        await pilot.press("a", "tab", "enter")
        await wait_for(pilot, lambda: asked() == 1)

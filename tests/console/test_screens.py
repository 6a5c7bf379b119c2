"""The other screens by keys: Iridium with the parachute helper, replay, history, predictions, help, palette."""

from __future__ import annotations

from collections.abc import Callable
from datetime import datetime, timedelta
from pathlib import Path

import gpxpy
import pytest
from textual.widgets import DataTable, Input, Markdown, Static

from console.app import DrsConsole
from console.screens.help import HelpScreen
from console.screens.history import HistoryScreen
from console.screens.iridium import IridiumScreen
from console.screens.modals import TextPromptModal
from console.screens.predictions import PredictionScreen
from console.screens.recovery import RecoveryScreen
from console.screens.release import ReleaseScreen
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.ops.telemetry import BalloonSample, TelemetryRecord
from drs_link.store import Store
from tests.console.conftest import T0, wait_for

pytestmark = pytest.mark.asyncio


async def test_the_parachute_helper_refuses_an_out_of_window_time(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app(now=T0)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("down", "i")
        screen = app.screen
        assert isinstance(screen, IridiumScreen) and screen.capsule == "DRS2"
        await app.workers.wait_for_complete()
        await pilot.pause()
        await pilot.press("C")
        assert isinstance(app.screen, TextPromptModal)
        late = T0 + timedelta(hours=3)
        await pilot.press(*f"{late:%H:%M}", "enter")
        await pilot.pause()
        messages = [n.message for n in app._notifications]
        assert any("PARACHUTE refused" in m and "would be rejected" in m for m in messages)
        assert app.screen is screen
        assert app.ops is not None and app.ops.iridium.commands("DRS2") == []


async def test_the_parachute_helper_offers_a_window_and_needs_a_different_second_operator(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app(now=T0)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("down", "i")
        await app.workers.wait_for_complete()
        await pilot.press("c")
        await pilot.pause()
        assert type(app.screen).__name__ == "HazardModal"
        await pilot.press(*"DRS2", "enter", *"EL", "enter", "enter")
        await wait_for(pilot, lambda: any("different person" in n.message for n in app._notifications))
        assert app.ops is not None and app.ops.iridium.commands("DRS2") == []


async def test_parachute_in_flight_shows_no_landed_evidence_and_is_refused_with_nothing_sent(
    canned_app: Callable[..., DrsConsole],
) -> None:
    """The same gate as `drs mt send --parachute` (tests/drs_link/iridium/test_parachute_gate.py), from the console."""
    app = canned_app(now=T0)
    imei = app.ops.state.config.capsules[2].imei if app.ops else None
    assert imei is not None
    reports = ReportStore(app.store)
    for n in range(5):
        at = T0 - timedelta(minutes=10 - 2 * n)
        fix = GnssFix(at, 67.7, 21.6, 27_000.0 - 2_400.0 * n, 19.0, 90.0, 0.9, 9)
        reports.add(Delivery(imei, n, format_mo(fix, 8.7, n).hex(), "webhook", at + timedelta(seconds=20),
                             transmit_utc=at + timedelta(seconds=15)))  # fmt: skip
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("down", "down", "i")
        await app.workers.wait_for_complete()
        await pilot.press("c")
        await wait_for(pilot, lambda: type(app.screen).__name__ == "HazardModal")
        body = " ".join(str(w.render()) for w in app.screen.query(".dialog-body"))
        assert "NO LANDED EVIDENCE: NOT LANDED: last fix" in body, (
            "the evidence shows before any name is typed"
        )
        await pilot.press(*"DRS3", "enter", "enter", *"alone", "enter", "enter")
        await wait_for(pilot, lambda: any("no landed evidence" in n.message for n in app._notifications))
        assert app.ops is not None and app.ops.iridium.commands("DRS3") == []
        assert [a.result for a in app.store.audit() if a.action == "mt.parachute"] == ["refused"]


async def test_the_parachute_dialog_shows_the_landed_evidence_as_new_reports_change_it(
    canned_app: Callable[..., DrsConsole],
) -> None:
    """#23: the evidence was frozen at opening; a report that lands the capsule while the operator types
    shows in the dialog's live line (and the gate at submit reads it again)."""
    app = canned_app(now=T0)
    imei = app.ops.state.config.capsules[2].imei if app.ops else None
    assert imei is not None
    reports = ReportStore(app.store)

    def report(n: int, at: datetime, alt_m: float, speed: float) -> None:
        fix = GnssFix(at, 67.7, 21.6, alt_m, speed, 90.0, 0.9, 9)
        reports.add(Delivery(imei, n, format_mo(fix, 8.7, n).hex(), "webhook", at + timedelta(seconds=20),
                             transmit_utc=at + timedelta(seconds=15)))  # fmt: skip

    for n in range(5):
        report(n, T0 - timedelta(minutes=20 - 2 * n), 27_000.0 - 2_400.0 * n, 19.0)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("down", "down", "i")
        await app.workers.wait_for_complete()
        await pilot.press("c")
        await wait_for(pilot, lambda: type(app.screen).__name__ == "HazardModal")
        live = app.screen.query_one("#countdown")
        assert "evidence NOW" not in str(live.render())
        for n, minutes in enumerate((-8, -6, -4), start=5):
            report(n, T0 + timedelta(minutes=minutes), 400.0, 0.2)
        await wait_for(pilot, lambda: "evidence NOW (landed): landed" in str(live.render()))


async def test_replay_shows_a_banner_and_cannot_command(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app(mode="replay")
    async with app.run_test(size=(80, 24)) as pilot:
        assert "REPLAY" in app.banner() and not app.commanding
        await pilot.press("enter")
        screen = app.screen
        assert isinstance(screen, ReleaseScreen)
        for action in ("power_on", "arm", "fire", "sync", "waive", "tick"):
            assert screen.check_action(action, ()) is None
        await pilot.press("o", "a", "f")
        assert app.screen is screen
        assert [a.action for a in app.store.audit()] == ["power-on", "waiver"]


async def test_a_manual_tick_is_recorded_with_the_operator(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter", "space")
        await wait_for(
            pilot, lambda: app.store.audit("DRS1", action="checklist.done") != []
        )  # off the UI thread
        ticked = app.store.audit("DRS1")[-1]
        assert (ticked.operator, ticked.action, ticked.result) == (
            "EL",
            "checklist.done",
            "release-day/apply-24v",
        )


async def test_history_searches_the_audit_log_and_exports_it(
    canned_app: Callable[..., DrsConsole], tmp_path: Path
) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("h")
        assert isinstance(app.screen, HistoryScreen)
        table = app.screen.query_one("#audit")
        assert table.row_count == 2
        app.screen.query_one("#search").focus()
        await pilot.press(*"waiver")
        assert table.row_count == 1
        table.focus()
        await pilot.press("e")
        exported = list((tmp_path / "exports").glob("audit-*.jsonl"))
        assert len(exported) == 1 and '"waiver"' in exported[0].read_text()


async def test_predictions_show_the_ellipse_with_real_probabilities(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(160, 48)) as pilot:
        await pilot.press("p")
        assert isinstance(app.screen, PredictionScreen)
        text = str(app.screen.query_one("#prediction-numbers").render())
        assert "σ∥" in text and "holds 39.3%" in text and "holds 86.5%" in text and "holds 98.9%" in text
        assert "Release in 10 min" in text and "from DRS1 GNSS" in text
        drawn = str(app.screen.query_one("#prediction-map").render())
        assert "X" in drawn and "2σ ring" in drawn and any(0x2800 < ord(c) <= 0x28FF for c in drawn)


async def test_a_release_starts_from_the_capsule_fix_else_from_a_fresh_balloon_position(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(160, 48)):
        assert app.prediction_origin("DRS1").source == "DRS1 GNSS"
        balloon = BalloonSample(lat=67.9, lon=21.1, alt_m=31000.0, source="udp 0.0.0.0:8942")
        app.fleet.apply(TelemetryRecord(T0 - timedelta(seconds=5), None, balloon))
        from_feed = app.prediction_origin("DRS2")
        assert (from_feed.lat, from_feed.lon, from_feed.alt_m) == (67.9, 21.1, 31000.0)
        assert from_feed.source == "balloon feed (udp 0.0.0.0:8942)"
        app.fleet.apply(TelemetryRecord(T0 - timedelta(seconds=200), None, balloon))
        assert app.prediction_origin("DRS2") is None, "a stale balloon position must not start a prediction"


async def test_predictions_export_kml_geojson_and_gpx(
    canned_app: Callable[..., DrsConsole], tmp_path: Path
) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("p", "e")
        kml = list((tmp_path / "exports").glob("DRS1-*.kml"))
        geojson = list((tmp_path / "exports").glob("DRS1-*.geojson"))
        assert len(kml) == 1 and "<kml" in kml[0].read_text()
        assert len(geojson) == 1 and '"FeatureCollection"' in geojson[0].read_text()
        [gpx] = (tmp_path / "exports").glob("DRS1-*.gpx")
        assert [w.name for w in gpxpy.parse(gpx.read_text()).waypoints][0].endswith("PRED LAND")


async def test_the_command_palette_offers_every_screen_of_every_capsule(
    canned_app: Callable[..., DrsConsole],
) -> None:
    app = canned_app()
    async with app.run_test(size=(80, 24)):
        titles = [command.title for command in app.get_system_commands(app.screen)]
        for name in ("DRS1", "DRS2", "DRS3"):
            assert {
                f"Release: {name}",
                f"Predictions: {name}",
                f"Iridium: {name}",
                f"Recovery: {name}",
            } <= set(titles)
        assert "History" in titles


async def test_recovery_reads_the_landing_from_the_reports(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app()
    async with app.run_test(size=(160, 48)) as pilot:
        await pilot.press("down", "v")
        assert isinstance(app.screen, RecoveryScreen)
        await app.workers.wait_for_complete()
        await pilot.pause()
        text = str(app.screen.query_one("#recovery-text").render())
        assert "Landed" in text and "from the team" in text and "Phone: DRS2 on ground" in text


async def test_recovery_exports_the_recovery_picture_with_the_gpx_and_kml(
    canned_app: Callable[..., DrsConsole], tmp_path: Path
) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("down", "v")
        await app.workers.wait_for_complete()
        await pilot.pause()
        await pilot.press("e")
        await wait_for(pilot, lambda: bool(list((tmp_path / "exports").glob("DRS2-recovery-*.png"))))
        await app.workers.wait_for_complete()
    [png] = (tmp_path / "exports").glob("DRS2-recovery-*.png")
    assert png.read_bytes().startswith(b"\x89PNG") and png.stat().st_size > 10_000
    assert len(list((tmp_path / "exports").glob("DRS2-recovery-*.gpx"))) == 1


async def test_help_and_theme_keys_work(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("question_mark")
        assert isinstance(app.screen, HelpScreen)
        await pilot.press("escape", "t")
        assert app.theme == "textual-light"


async def test_reset_after_recovery_needs_the_capsule_name(canned_app: Callable[..., DrsConsole]) -> None:
    app = canned_app()
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("enter", "R", *"DRS9", "enter")
        await app.workers.wait_for_complete()
        await pilot.pause()
        assert ("reset", "refused") in [(a.action, a.result) for a in app.store.audit("DRS1")]
        await pilot.press("R", *"DRS1", "enter")
        await app.workers.wait_for_complete()
        await pilot.pause()
        audit = [(a.action, a.result) for a in app.store.audit("DRS1")]
        assert ("reset", "ok") in audit and ("checklist.done", "after-drop/reset-state") in audit


async def test_help_scrolls_to_its_last_line_at_80x24(canned_app: Callable[..., DrsConsole]) -> None:
    """The keys run to twice an 80×24 screen: the end must be reachable from the keyboard."""
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("question_mark")
        screen = app.screen
        assert isinstance(screen, HelpScreen)
        pane = screen.query_one("#help")
        last = list(screen.query_one(Markdown).children)[-1]
        assert "REPLAY sessions cannot command" in str(last.render())
        assert not pane.region.contains_region(last.region), (
            "the help fits: this test no longer tests scrolling"
        )
        await pilot.press("end")
        await wait_for(pilot, lambda: pane.region.contains_region(last.region))


async def test_typing_on_entering_history_searches_and_fires_no_key(
    canned_app: Callable[..., DrsConsole], tmp_path: Path
) -> None:
    """The trial typed "alone" on entry: its `e` wrote an export. Typing must search, nothing else."""
    app = canned_app()
    app.store.append_audit(
        "EL", "DRS1", "waiver", "granted", {"item": "sync", "reason": "alone on the ridge"}
    )
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("h")
        screen = app.screen
        assert isinstance(screen, HistoryScreen)
        await pilot.press(*"alone")
        assert screen.query_one("#search", Input).value == "alone"
        await wait_for(pilot, lambda: screen.query_one("#audit", DataTable).row_count == 1)
        assert not list((tmp_path / "exports").glob("audit-*.jsonl")), "a letter typed in the search exported"
        await pilot.press("down", "e")
        exported = list((tmp_path / "exports").glob("audit-*.jsonl"))
        assert len(exported) == 1 and "alone on the ridge" in exported[0].read_text()


async def test_history_names_the_console_an_entry_came_from_when_it_is_another(
    canned_app: Callable[..., DrsConsole],
) -> None:
    """#23: two consoles were both ARMED on one capsule and History could not tell their entries apart."""
    app = canned_app()
    other = Store.open(app.store.path)
    other.session = "jm@laptop2 pid 7"
    other.append_audit("JM", "DRS1", "arm", "armed", {"window": 1})
    app.store.append_audit("EL", "DRS1", "arm", "refused", {"reason": "held by JM"})
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("h", "enter")
        detail = app.screen.query_one("#audit-detail", Static)

        def shown() -> str:
            return " ".join(str(detail.render()).split())

        await wait_for(pilot, lambda: "arm refused" in shown())
        assert "from another console" not in shown(), "this console's own entry"
        await pilot.press("down")
        await wait_for(pilot, lambda: "arm armed · from another console: jm@laptop2 pid 7" in shown())


async def test_history_shows_the_highlighted_entrys_reason(canned_app: Callable[..., DrsConsole]) -> None:
    """Waiver and refusal reasons live in an entry's detail: the screen shows it for the highlighted one."""
    app = canned_app()
    reason = "no fix over the lake; dropping blind as the flown procedure allows it, decided with the PI"
    app.store.append_audit("EL", "DRS1", "waiver", "granted", {"item": "gnss", "reason": reason})
    app.store.append_audit(
        "EL", "DRS1", "fire", "refused", {"reason": "not armed: ARM window expired at 11:59:00Z"}
    )
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("h", "enter")
        screen = app.screen
        assert isinstance(screen, HistoryScreen)
        detail = screen.query_one("#audit-detail", Static)

        def shown() -> str:
            return " ".join(str(detail.render()).split())

        await wait_for(pilot, lambda: "fire refused" in shown())
        assert "reason: not armed: ARM window expired at 11:59:00Z" in shown()
        await pilot.press("down")
        await wait_for(pilot, lambda: "waiver granted" in shown())
        assert f"item: gnss · reason: {reason}" in shown()


@pytest.mark.parametrize("size", [(80, 24), (120, 40)], ids=["80x24", "120x40"])
async def test_the_checklist_shows_who_ticked_a_step_without_scrolling(
    canned_app: Callable[..., DrsConsole], size: tuple[int, int]
) -> None:
    """The step column used to push "By / when" off the right edge; the whole step is below the table."""
    app = canned_app()
    async with app.run_test(size=size) as pilot:
        await pilot.press("enter", "space")
        screen = app.screen
        assert isinstance(screen, ReleaseScreen)
        table = screen.query_one("#checklist", DataTable)
        await wait_for(pilot, lambda: str(table.get_row_at(0)[2]) == f"EL {T0:%H:%M:%S}Z")
        assert table.virtual_size.width <= table.scrollable_content_region.width, "a column is off screen"
        by = list(table.columns.values())[-1]
        assert str(by.label) == "By / when" and by.width >= len(f"EL {T0:%H:%M:%S}Z")


async def test_w_takes_the_operator_to_a_waivable_go_no_go_item_and_says_so(
    canned_app: Callable[..., DrsConsole],
) -> None:
    """Which item `w` waives was chosen by tabbing into go/no-go, which nothing said."""
    app = canned_app()
    async with app.run_test(size=(80, 24)) as pilot:
        await pilot.press("enter")
        screen = app.screen
        assert isinstance(screen, ReleaseScreen)
        hint = screen.query_one("#gonogo-hint", Static)
        gonogo = screen.query_one("#gonogo", DataTable)
        assert "w picks a go/no-go item to waive" in str(hint.render())
        await pilot.press("w")
        assert app.screen is screen and gonogo.has_focus, "w from the checklist must not waive blindly"
        assert "w waives GNSS fix fresh" in str(hint.render())
        await pilot.press("up")
        assert "Microcontroller talking cannot be waived" in str(hint.render())
        await pilot.press("w")
        assert app.screen is screen
        await pilot.press("down", "w")
        assert isinstance(app.screen, TextPromptModal)
        await pilot.press(*"no fix over the lake", "enter")
        waiver = {"item": "gnss", "reason": "no fix over the lake"}
        await wait_for(pilot, lambda: any(a.detail == waiver for a in app.store.audit("DRS1")))


async def test_a_waiver_and_a_tick_are_shown_as_the_server_answered_them(
    canned_app: Callable[..., DrsConsole],
) -> None:
    """The screen shows a key's write at once, from the verb's answer, not only after the next event."""
    app = canned_app()
    async with app.run_test(size=(120, 40)):
        app.context.waive("DRS1", "gnss", "no fix over the lake")
        assert [(w.item, w.reason, w.operator) for w in app.context.waivers("DRS1")] == [
            ("gnss", "no fix over the lake", "EL")
        ]
        assert app.context.waivers("DRS2") == []
        [sync] = [item for item in app.gonogo("DRS2").items if item.key == "sync"]
        assert sync.verdict.value == "NO-GO", "DRS2 is half synced"
        app.context.waive("DRS2", "sync", "the rest is on the spare card")
        [sync] = [item for item in app.gonogo("DRS2").items if item.key == "sync"]
        assert sync.verdict.value == "WAIVED", "go/no-go judged with the server's waiver"
        app.context.tick("DRS1", "release-day", "apply-24v")
        app.context.tick("DRS1", "preflight", "pcb-pi", "checked at the hangar")
        assert sorted((r.step, r.state.value) for r in app.context.step_records("DRS1")) == [
            ("apply-24v", "done"), ("pcb-pi", "skipped"),
        ]  # fmt: skip

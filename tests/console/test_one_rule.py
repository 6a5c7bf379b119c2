"""One rule, two front ends: `drs …` and the console give the same answer, because the rule is in drs_link.

Each test runs the same situation through the real CLI entry point and through the console (a Pilot
pressing the keys an operator would), against the simulated RockBLOCK gateway on loopback and the real
store, and compares what each did or said.
"""

from __future__ import annotations

import json
from collections.abc import Iterator
from datetime import datetime, timedelta
from pathlib import Path

import pytest

import console.commands.main as entry
from console.app import ConsoleSetup, DrsConsole
from console.commands.console import live_setup
from console.screens.iridium import IridiumScreen
from console.screens.modals import HazardModal, TextPromptModal
from drs_link.config import CapsuleConfig, load_config
from drs_link.errors import ConfigError
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.gateway import RockblockGateway
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.ops.checklist import PROCEDURE_DIR, ChecklistRun, StepState, load_checklists
from drs_link.ops.operations import Operations
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedRockblock
from drs_link.store import Store, utc_now
from tests.clock import ManualClock
from tests.console.conftest import wait_for

IMEI = "300434060000010"
PASSWORD = "pw-one-rule"
CAPSULE = CapsuleConfig(name="DRS1", host="127.0.0.1", imei=IMEI, rockblock_serial=17001)


@pytest.fixture
def gateway() -> Iterator[SimulatedRockblock]:
    with SimulatedRockblock(username="ops", password=PASSWORD, imeis=(IMEI,)) as simulated:
        yield simulated


def write_config(tmp_path: Path, gateway: SimulatedRockblock, extra: str = "") -> Path:
    path = tmp_path / "drs.toml"
    path.write_text(
        f'[operator]\nname = "alice"\n[data]\ndir = "{tmp_path / "data"}"\n'
        f'[rockblock]\nmt_url = "{gateway.url}"\nusername = "ops"\npassword_env = "DRS_ONE_RULE_RB"\n'
        f"timeout_s = 5.0\n[console]\nrequire_second_operator = false\n{extra}"
        f'[[capsule]]\nname = "DRS1"\nhost = "127.0.0.1"\nport = 9\nimei = "{IMEI}"\nrockblock_serial = 17001\n'
    )
    return path


def cli(config: Path, *argv: str) -> int:
    return entry.main(["--config", str(config), *argv])


def console_for(config_path: Path, clock=utc_now) -> DrsConsole:  # type: ignore[no-untyped-def]
    config = load_config(config_path)
    store = Store.open(config.store_path)
    operations = Operations(config, store, clock=clock, environ={"DRS_ONE_RULE_RB": PASSWORD})
    setup = ConsoleSetup(mode="live", capsules=["DRS1"], store=store, clock=clock, operations=operations)
    return DrsConsole(setup, live_timers=False)


def add_report(store: Store, momsn: int, at: datetime, alt_m: float, speed_ms: float) -> None:
    fix = GnssFix(at, 67.70 + 0.0001 * momsn if speed_ms else 67.71, 21.60, alt_m, speed_ms, 90.0, 0.9, 9)
    delivery = Delivery(IMEI, momsn, format_mo(fix, 8.7, momsn).hex(), "webhook", at + timedelta(seconds=20),
                        transmit_utc=at + timedelta(seconds=15))  # fmt: skip
    ReportStore(store).add(delivery)


def falling(store: Store, start: datetime, count: int) -> None:
    for n in range(count):
        add_report(store, n, start + timedelta(minutes=2 * n), 20000.0 - 2400.0 * n, 20.0)


def landed(store: Store, start: datetime, first_momsn: int, count: int) -> None:
    for n in range(count):
        add_report(store, first_momsn + n, start + timedelta(minutes=2 * n), 412.0, 0.0)


def sounder_off_step(store: Store) -> StepState:
    [after_drop] = [c for c in load_checklists(PROCEDURE_DIR) if c.id == "after-drop"]
    statuses = ChecklistRun(store, after_drop, "DRS1").statuses({})
    return next(s.state for s in statuses if s.step.id == "sounder-off")


async def console_sends_sounder_off(app: DrsConsole) -> None:
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("i")
        await wait_for(pilot, lambda: isinstance(app.screen, IridiumScreen))
        await pilot.press("o")
        await wait_for(pilot, lambda: isinstance(app.screen, TextPromptModal))
        await pilot.press(*"DRS1", "enter")
        await wait_for(pilot, lambda: any("[SOUNDER_OFF] queued" in n.message for n in app._notifications))
        await app.workers.wait_for_complete()


@pytest.mark.asyncio
@pytest.mark.parametrize("front_end", ["cli", "console"])
async def test_sounder_off_in_descent_leaves_the_in_hand_step_and_ticks_it_once_landed(
    tmp_path: Path, gateway: SimulatedRockblock, monkeypatch: pytest.MonkeyPatch, front_end: str
) -> None:
    """The trial: SOUNDER_OFF sent during the descent ticked "Sounder off once the capsule is in hand"."""
    monkeypatch.setenv("DRS_ONE_RULE_RB", PASSWORD)
    config = write_config(tmp_path, gateway)
    store = Store.open(load_config(config).store_path)
    start = utc_now() - timedelta(minutes=30)
    falling(store, start, 6)

    async def send() -> None:
        if front_end == "cli":
            assert cli(config, "mt", "send", "DRS1", "--sounder", "off", "--confirm", "DRS1") == 0
        else:
            await console_sends_sounder_off(console_for(config))

    await send()
    assert list(gateway.queues[IMEI]) == [b"[SOUNDER_OFF]"]
    assert sounder_off_step(store) is StepState.PENDING, "falling at 8 km: the capsule is not in hand"
    landed(store, start + timedelta(minutes=14), 6, 4)
    await send()
    assert sounder_off_step(store) is StepState.DONE
    store.close()


def history_on_a_commanded_interval(store: Store, gateway: SimulatedRockblock, now: datetime) -> None:
    """Eight reports 2 min apart, then [INTERVAL=5] (confirmed) and four 5 min apart, the last 10 s ago.

    The spacing alone (median 2 min over the last twelve fixes) says 2 min; the unit runs 5.
    """
    clock = ManualClock(now)
    life = lc.CommandLifecycle(store, "alice", clock)
    reports = ReportStore(store)
    capsule = SimulatedCapsule(imei=IMEI, rb_source=17001)
    client = RockblockGateway(gateway.url, "ops", PASSWORD, timeout_s=2.0, retry_delay_s=0.0)
    alarm = now - timedelta(minutes=8 * 2 + 4 * 5) + timedelta(minutes=2) - timedelta(seconds=10)
    for n in range(12):
        if n == 7:
            clock.now = alarm - timedelta(seconds=30)
            command = life.request(CAPSULE, MtComposer().add("INTERVAL", 5).build())
            life.send(command.id, "DRS1", client)
        fix = GnssFix(alarm, 67.71, 21.60, 412.0, 0.0, 0.0, 0.9, 9)
        mo = capsule.session(gateway, fix, alarm + timedelta(seconds=20))
        reports.add(Delivery(IMEI, mo.momsn, mo.payload.hex(), "webhook", alarm + timedelta(seconds=25),
                             transmit_utc=mo.transmit_time))  # fmt: skip
        alarm = capsule.next_cycle(alarm)
    clock.now = now
    life.observe(reports.for_imei(IMEI), IMEI)
    [interval] = life.for_imei(IMEI)
    assert interval.state == lc.EFFECT_CONFIRMED


@pytest.mark.asyncio
async def test_the_parachute_window_is_the_same_from_the_cli_and_the_console(
    tmp_path: Path, gateway: SimulatedRockblock, capsys: pytest.CaptureFixture[str]
) -> None:
    """Both plan on the INTERVAL the unit runs (5 min, commanded and confirmed), not on one inferred."""
    config = write_config(tmp_path, gateway)
    store = Store.open(load_config(config).store_path)
    history_on_a_commanded_interval(store, gateway, utc_now())
    assert cli(config, "mt", "send", "DRS1", "--parachute", "next", "--dry-run") == 0
    [from_cli] = [
        line.removeprefix("window: ")
        for line in capsys.readouterr().out.splitlines()
        if line.startswith("window: ")
    ]
    assert "cycle(s) of 5 min" in from_cli
    app = console_for(config)
    async with app.run_test(size=(120, 40)) as pilot:
        await pilot.press("i")
        await wait_for(pilot, lambda: isinstance(app.screen, IridiumScreen))
        await pilot.press("c")
        await wait_for(pilot, lambda: isinstance(app.screen, HazardModal))
        assert from_cli in app.screen.consequence  # type: ignore[attr-defined]
    store.close()


UNCLOSED = [[21.0, 67.8], [21.2, 67.8], [21.2, 67.9], [21.0, 67.9]]
SWAPPED = [[67.8, 97.8], [67.8, 97.9], [67.9, 97.9], [67.8, 97.8]]
"""A zone near 97.8° E written [lat, lon]."""


@pytest.mark.parametrize(
    ("ring", "reason"),
    [(UNCLOSED, "must end where it starts"), (SWAPPED, "latitude 97.8 is beyond ±90°")],
    ids=["unclosed", "lon-lat-swapped"],
)
def test_a_zone_file_is_refused_for_the_same_reason_by_drs_plan_and_the_console(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    capsys: pytest.CaptureFixture[str],
    ring: list[list[float]],
    reason: str,
) -> None:
    """One loader (predictor.prediction.zones): the console's go/no-go once accepted files the planner refused."""
    zones = tmp_path / "zones.geojson"
    feature = {
        "type": "Feature",
        "properties": {"name": "Kiruna"},
        "geometry": {"type": "Polygon", "coordinates": [ring]},
    }
    zones.write_text(json.dumps({"type": "FeatureCollection", "features": [feature]}))
    config = write_config(tmp_path, gateway, f'exclusion_zones_file = "{zones}"\n')
    plan = [
        "plan",
        "--weather",
        str(tmp_path / "none.grib2"),
        "--lat",
        "67.9",
        "--lon",
        "21.1",
        "--alt",
        "31500",
    ]
    assert cli(config, *plan, "--from", "2026-09-01T12:00Z", "--zones", str(zones)) == 1
    from_cli = capsys.readouterr().err.strip().removeprefix("drs: error: ")
    with pytest.raises(ConfigError) as refused:
        live_setup(load_config(config), None, None)
    from_console = str(refused.value).removeprefix("console.exclusion_zones_file: ")
    assert from_cli == from_console and reason in from_cli and "feature 0 (Kiruna)" in from_cli

"""One rule, two front ends: `drs …` and the console give the same answer, because the rule is in drs_link.

Each test runs the same situation through the real CLI entry point and through the console (a Pilot
pressing the keys an operator would), against the simulated RockBLOCK gateway on loopback and the real
store, and compares what each did or said.
"""

from __future__ import annotations

import json
import os
import pwd
import re
import socket
import subprocess
import sys
from collections.abc import Callable, Iterator
from datetime import datetime, timedelta
from pathlib import Path

import pytest

import console.commands.main as entry
from console.app import ConsoleSetup
from console.commands.console import live_setup
from console.predictions import PredictionService
from console.screens.iridium import IridiumScreen
from console.screens.modals import HazardModal, TextPromptModal
from drs_link.config import CapsuleConfig, load_config
from drs_link.errors import ConfigError, RefusedError
from drs_link.iridium import lifecycle as lc
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.gateway import RockblockGateway
from drs_link.iridium.mt import MtComposer
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.ops.checklist import PROCEDURE_DIR, ChecklistRun, StepState, load_checklists
from drs_link.ops.fleet import FleetState
from drs_link.ops.gonogo import GoNoGoReport
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.ops_state import SecondOperator
from drs_link.ops.origin import release_origin
from drs_link.sim import CapsuleSimulator
from drs_link.sim.keys import write_ed25519
from drs_link.sim.rockblock import SimulatedCapsule, SimulatedRockblock
from drs_link.store import Store, utc_now
from predictor import Terrain
from tests.clock import ManualClock, SkipClock
from tests.console.conftest import ConsoleUnderTest, console_on, wait_for
from tests.drs_link.conftest import SIM_SCALE, capsule_table
from tests.release_helpers import ROCKBLOCK_TOML, SYNC_WAIVER, write_weather

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


def console_for(config_path: Path, clock=utc_now) -> ConsoleUnderTest:  # type: ignore[no-untyped-def]
    config = load_config(config_path)
    store = Store.open(config.store_path)
    operations = OperatorOps(config, store, clock=clock, environ={"DRS_ONE_RULE_RB": PASSWORD})
    return console_on(
        operations, ConsoleSetup(mode="live", capsules=["DRS1"], clock=clock), live_timers=False
    )


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


async def console_sends_sounder_off(app: ConsoleUnderTest) -> None:
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


def seconds_until_noon(now: datetime) -> float:
    """How far to skip the clock to reach the next 12:00 UTC (a whole day at noon itself: skips go forward)."""
    noon = now.replace(hour=12, minute=0, second=0, microsecond=0)
    return (noon - now).total_seconds() % 86_400 or 86_400


@pytest.mark.asyncio
async def test_the_parachute_window_is_the_same_from_the_cli_and_the_console(
    tmp_path: Path, gateway: SimulatedRockblock, capsys: pytest.CaptureFixture[str], skip_clock: SkipClock
) -> None:
    """Both plan on the INTERVAL the unit runs (5 min, commanded and confirmed), not on one inferred.

    At noon UTC: within 15 min of midnight the rule refuses a window unconfirmed (the CI run of
    2026-12-03 did, at 23:4x), which is another test's subject, not this one's."""
    skip_clock.skip(seconds_until_noon(utc_now()))
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


# Go: the CLI's `drs capsule arm` / `drs capsule go` and the console's ARM / FIRE are one set of rules
# (``OperatorOps.arm``/``OperatorOps.fire``), pinned here against the capsule simulator on loopback SSH.

GO_PASSWORD = "pw-go"
TIME = re.compile(r"\d\d:\d\d:\d\dZ")
CHILD = "import sys; from console.commands.main import main; sys.exit(main(sys.argv[1:]))"


@pytest.fixture(scope="module")
def weather(tmp_path_factory: pytest.TempPathFactory) -> list[Path]:
    return write_weather(tmp_path_factory.mktemp("gfs"))


def go_config(tmp_path: Path, sim: CapsuleSimulator, key: Path, console: str = "") -> Path:
    known_hosts = tmp_path / "known_hosts"
    known_hosts.write_text(sim.known_hosts_line())
    table = capsule_table(sim, key, known_hosts=str(known_hosts), python="python3")
    capsule = "\n".join(f"{k} = {json.dumps(v)}" for k, v in table.items())
    path = tmp_path / "drs.toml"
    path.write_text(
        f'[operator]\nname = "EL"\n[data]\ndir = "{tmp_path / "data"}"\n'
        f"{ROCKBLOCK_TOML}"
        f'[console]\ncrew = ["EL", "MS"]\n{console}\n[[capsule]]\n{capsule}\n'
    )
    return path


class Face:
    """One front end's way to ARM and FIRE: ``drs`` (main(), or a child process) or the console's call
    path (``OperatorOps`` fed by its own polls into a fleet, as ``console.app`` feeds it)."""

    def __init__(
        self, kind: str, config: Path, weather: list[Path], capsys: pytest.CaptureFixture[str]
    ) -> None:
        self.kind, self.config, self.weather, self.capsys = kind, config, weather, capsys
        self.ops: OperatorOps | None = None

    def console_ops(self) -> OperatorOps:
        if self.ops is None:
            config = load_config(self.config)
            self.ops = OperatorOps(config, Store.open(config.store_path), environ={"DRS_GO_RB": GO_PASSWORD})
            files = list(self.weather)
            self.predictions = PredictionService(lambda: files, Terrain.sea_level, self.ops.state.clock)
        return self.ops

    def console_poll(self) -> GoNoGoReport:
        """What the console's timers do (poll, gateway check, prediction) and what its release screen asks."""
        ops = self.console_ops()
        fleet = FleetState.for_capsules(["DRS1"])
        for record in [*ops.links.poll("DRS1"), *ops.iridium.gateway_check()]:
            fleet.apply(record)
        origin = release_origin(fleet, "DRS1", ops.state.clock())
        if origin is not None:
            for record in self.predictions.predict("DRS1", origin):
                fleet.apply(record)
        return ops.release.gonogo("DRS1", fleet.capsules["DRS1"])

    def _cli(self, *argv: str) -> str | None:
        self.capsys.readouterr()
        code = entry.main(["--config", str(self.config), *argv])
        err = self.capsys.readouterr().err.strip()
        return None if code == 0 else err.removeprefix("drs: error: ")

    def arm(self, *waive: str) -> str | None:
        """ARM; None when armed, else the refusal."""
        if self.kind == "cli":
            return self._cli("capsule", "arm", "DRS1", "--weather", *map(str, self.weather), *waive)
        ops = self.console_ops()
        try:
            for argument in waive[1::2]:
                item, _, reason = argument.partition("=")
                ops.release.waive("DRS1", item, reason)
            ops.release.arm("DRS1", self.console_poll())
        except RefusedError as exc:
            return str(exc)
        return None

    def go(self, *waive: str, second: SecondOperator | None = None) -> str | None:
        """FIRE; None when released, else the refusal."""
        second = second or SecondOperator()
        if self.kind == "cli":
            people = [f"--second-operator={second.name}"] if second.name else []
            return self._cli("capsule", "go", "DRS1", "--confirm", "DRS1", "--weather", *map(str, self.weather),
                             *waive, *people)  # fmt: skip
        ops = self.console_ops()
        try:
            ops.release.fire("DRS1", "DRS1", self.console_poll, second)
        except RefusedError as exc:
            return str(exc)
        return None

    def close(self) -> None:
        if self.ops is not None:
            self.ops.close()


@pytest.fixture
def powered(
    tmp_path: Path, monkeypatch: pytest.MonkeyPatch
) -> Iterator[Callable[..., tuple[CapsuleSimulator, Path, Store]]]:
    """A powered simulated capsule waiting for Go, and a config for it (extra [console] lines given)."""
    monkeypatch.setenv("DRS_GO_RB", GO_PASSWORD)
    key = tmp_path / "keys" / "id_ed25519"
    public = write_ed25519(key)
    started: list[CapsuleSimulator] = []

    def start(console: str = "") -> tuple[CapsuleSimulator, Path, Store]:
        sim = CapsuleSimulator(authorized_keys=[public], clock_scale=SIM_SCALE)
        sim.start()
        started.append(sim)
        config = go_config(tmp_path, sim, key, console)
        assert entry.main(["--config", str(config), "capsule", "power-on", "DRS1", "--yes"]) == 0
        return sim, config, Store.open(load_config(config).store_path)

    yield start
    for sim in started:
        sim.stop()


def same_words(refusals: dict[str, str | None]) -> str:
    """The refusal both faces gave, once the times in it are blanked; they must be one sentence."""
    texts = {face: TIME.sub("HH:MM:SSZ", text or "") for face, text in refusals.items()}
    assert len(set(texts.values())) == 1 and all(texts.values()), refusals
    return texts["cli"]


def fire_results(store: Store) -> list[str]:
    return [a.result for a in store.audit("DRS1") if a.action == "fire"]


@pytest.mark.slow
def test_go_without_arm_is_refused_in_the_same_words_from_both_faces_and_nothing_reaches_the_pi(
    powered: Callable[..., tuple[CapsuleSimulator, Path, Store]],
    weather: list[Path],
    capsys: pytest.CaptureFixture[str],
) -> None:
    """#22: `drs capsule go` ran no go/no-go poll, no ARM window and no two-person rule."""
    sim, config, store = powered()
    refusals = {}
    for kind in ("cli", "console"):
        face = Face(kind, config, weather, capsys)
        refusals[kind] = face.go()
        face.close()
    assert same_words(refusals) == "DRS1: FIRE refused: not armed"
    assert sim.firmware.go_at is None
    assert fire_results(store) == ["refused", "refused"]


@pytest.mark.slow
def test_a_failing_go_no_go_item_refuses_arm_in_the_consoles_words_and_then_go(
    powered: Callable[..., tuple[CapsuleSimulator, Path, Store]],
    weather: list[Path],
    capsys: pytest.CaptureFixture[str],
) -> None:
    """No sync_source in this setup: "Storage sync complete" is NO-GO, naming what is missing, until waived."""
    sim, config, store = powered()
    arms, goes = {}, {}
    for kind in ("cli", "console"):
        face = Face(kind, config, weather, capsys)
        arms[kind], goes[kind] = face.arm(), face.go()
        face.close()
    assert same_words(arms) == (
        "DRS1: ARM refused: NO-GO: Storage sync complete: sync_source is not configured "
        "(set it in the capsule's [[capsule]] table: the payload data to upload)"
    )
    assert same_words(goes) == "DRS1: FIRE refused: not armed"
    assert sim.firmware.go_at is None
    assert [a.result for a in store.audit("DRS1") if a.action == "arm"] == ["refused", "refused"]


@pytest.mark.slow
@pytest.mark.parametrize("kind", ["cli", "console"])
def test_go_with_the_failing_item_waived_releases_and_the_waiver_is_in_the_audit(
    powered: Callable[..., tuple[CapsuleSimulator, Path, Store]],
    weather: list[Path],
    capsys: pytest.CaptureFixture[str],
    kind: str,
) -> None:
    sim, config, store = powered()
    face = Face(kind, config, weather, capsys)
    waive = ("--waive", f"sync={SYNC_WAIVER}")
    assert face.arm(*waive) is None
    assert face.go(*waive) is None, "the crew list is not needed without the rule: nobody was typed"
    face.close()
    assert sim.firmware.go_at is not None
    granted = [a.detail for a in store.audit("DRS1") if a.action == "waiver" and a.result == "granted"]
    assert granted and all(d == {"item": "sync", "reason": SYNC_WAIVER} for d in granted)
    actions = [(a.action, a.result) for a in store.audit("DRS1")]
    assert ("arm", "armed") in actions and ("fire", "authorised") in actions
    assert ("go", "released, Pi shut down") in actions and actions[-1][0] == "checklist.done"


@pytest.mark.slow
def test_a_waiver_given_to_arm_but_not_to_go_disarms_and_finish_go_is_no_back_door(
    powered: Callable[..., tuple[CapsuleSimulator, Path, Store]],
    weather: list[Path],
    capsys: pytest.CaptureFixture[str],
) -> None:
    """Waivers live in one process: `drs capsule go` without the waiver `arm` had sees the NO-GO, and the
    changed verdict closes the window. ``finish_go`` (no ARM) finishes only a Go that already left."""
    sim, config, store = powered()
    face = Face("cli", config, weather, capsys)
    assert face.arm("--waive", f"sync={SYNC_WAIVER}") is None
    refusal = face.go()
    assert refusal is not None and refusal.startswith(
        "DRS1: FIRE refused and disarmed: no longer GO: NO-GO: "
    ), refusal
    assert "Storage sync complete" in refusal
    assert face.go("--waive", f"sync={SYNC_WAIVER}") == "DRS1: FIRE refused: not armed: no longer GO: " + refusal.split(
        "no longer GO: ", 1)[1]  # fmt: skip
    ops = OperatorOps(load_config(config), store)
    with pytest.raises(RefusedError, match="DRS1: finish refused: only an unverified Go .* DRS1 is powered"):
        ops.release.finish_go("DRS1", "DRS1")
    ops.close()
    assert sim.firmware.go_at is None
    assert not [a for a in store.audit("DRS1") if a.action == "fire" and a.result == "authorised"]
    assert [a.result for a in store.audit("DRS1") if a.action == "go"] == ["refused"]


@pytest.mark.slow
def test_go_after_the_arm_window_expired_is_refused_the_same_from_both_faces(
    powered: Callable[..., tuple[CapsuleSimulator, Path, Store]],
    weather: list[Path],
    capsys: pytest.CaptureFixture[str],
    skip_clock: SkipClock,
) -> None:
    """The window runs out on the clock the rule reads (skipped past it in the test's process and in the
    private `drs server` the CLI's face starts), and FIRE checks it again then."""
    sim, config, store = powered("arm_window_s = 120.0")
    waive = ("--waive", f"sync={SYNC_WAIVER}")
    refusals = {}
    for kind in ("cli", "console"):
        face = Face(kind, config, weather, capsys)
        assert face.arm(*waive) is None
        skip_clock.skip(120.5)
        refusals[kind] = face.go(*waive)
        face.close()
    assert same_words(refusals) == "DRS1: FIRE refused: not armed: ARM window expired at HH:MM:SSZ"
    assert sim.firmware.go_at is None
    assert fire_results(store) == ["refused", "refused"]


@pytest.mark.slow
def test_with_the_rule_required_go_needs_another_logins_approval_from_both_faces(
    powered: Callable[..., tuple[CapsuleSimulator, Path, Store]],
    weather: list[Path],
    capsys: pytest.CaptureFixture[str],
) -> None:
    """#23: a typed `--second-operator` satisfied the two-person rule with require_second_operator on."""
    sim, config, store = powered("require_second_operator = true")
    waive = ("--waive", f"sync={SYNC_WAIVER}")
    alone, typed = {}, {}
    for kind in ("cli", "console"):
        face = Face(kind, config, weather, capsys)
        assert face.arm(*waive) is None
        alone[kind] = face.go(*waive)
        typed[kind] = face.go(*waive, second=SecondOperator(name="MS"))
        face.close()
        assert entry.main(["--config", str(config), "capsule", "disarm", "DRS1"]) == 0
    assert same_words(alone).startswith(
        "DRS1: FIRE refused: require_second_operator is on: a second login's approval is needed; ask another login"
    )
    assert "typed second operator is not accepted" in same_words(typed) and "drs approve ID" in same_words(
        typed
    )
    assert sim.firmware.go_at is None
    assert fire_results(store) == ["refused"] * 4


def drs_child(config: Path, *argv: str, env: dict[str, str] | None = None) -> subprocess.Popen[str]:
    """`drs argv` as another process (another console, another terminal)."""
    return subprocess.Popen([sys.executable, "-c", CHILD, "--config", str(config), *argv], text=True,
                            stdout=subprocess.PIPE, stderr=subprocess.PIPE, env={**os.environ, **(env or {})})  # fmt: skip


@pytest.mark.slow
def test_one_arm_per_capsule_across_processes_and_the_refusal_names_who_holds_it(
    powered: Callable[..., tuple[CapsuleSimulator, Path, Store]],
    weather: list[Path],
    capsys: pytest.CaptureFixture[str],
) -> None:
    """#23: two consoles were both ARMED on one capsule. A `drs capsule arm` process holds the window;
    this process, arming and firing as the console does, is refused and told who holds it."""
    sim, config, store = powered()
    child = drs_child(
        config, "capsule", "arm", "DRS1", "--weather", *map(str, weather), "--waive", f"sync={SYNC_WAIVER}"
    )
    out, err = child.communicate(timeout=120)
    assert child.returncode == 0, err
    console = Face("console", config, weather, capsys)
    refused = console.arm("--waive", f"sync={SYNC_WAIVER}")
    # The window is held by this account through its private operations server (drs_link.server): its pid.
    holder = re.escape(f"EL at {pwd.getpwuid(os.geteuid()).pw_name}@{socket.gethostname()} pid ") + r"\d+"
    assert refused is not None and re.fullmatch(
        f"DRS1: ARM refused: ARM window #1 is held by {holder} until HH:MM:SSZ; one ARM per capsule",
        TIME.sub("HH:MM:SSZ", refused),
    ), refused
    refused = console.go()
    assert refused is not None and re.fullmatch(
        f"DRS1: FIRE refused: the ARM window is held by {holder}, not this console", refused
    ), refused
    status = console.console_ops().state.ops("DRS1").arming.status()
    assert status.armed and not status.mine and re.fullmatch(f"held by {holder}", status.holder_text())
    console.close()
    assert sim.firmware.go_at is None
    armed = [a for a in store.audit("DRS1") if a.action == "arm"]
    assert [a.result for a in armed] == ["armed", "refused"] and armed[0].session is not None


OVERRIDE = "the chase team sees it on the ground; GNSS frozen"


def parachute_refusal(config: Path, front_end: str, capsys: pytest.CaptureFixture[str], *people: str) -> str:
    """PARACHUTE in flight with a landed override, from ``drs mt send`` or through ``OperatorOps.send_mt``
    (what the console's commanding screen calls, and any other caller)."""
    if front_end == "cli":
        capsys.readouterr()
        argv = ["mt", "send", "DRS1", "--parachute", "next", "--accept-midnight", "--confirm", "DRS1",
                "--override-landed", OVERRIDE, *people]  # fmt: skip
        assert cli(config, *argv) == 1
        return capsys.readouterr().err.strip().removeprefix("drs: error: ")
    config_ = load_config(config)
    ops = OperatorOps(config_, Store.open(config_.store_path), environ={"DRS_ONE_RULE_RB": PASSWORD})
    now = utc_now()
    message = MtComposer().add("PARACHUTE", (now.hour, now.minute)).build()
    second = SecondOperator(name=people[1] if people else None)
    with pytest.raises(RefusedError) as refused:
        ops.iridium.send_mt("DRS1", message, "DRS1", second, override_landed=OVERRIDE)
    return str(refused.value)


@pytest.mark.parametrize("front_end", ["cli", "operations"])
def test_parachute_in_flight_is_refused_through_any_caller_and_nothing_reaches_the_gateway(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    front_end: str,
) -> None:
    """#22: `OperatorOps.send_mt` never gated; only the screen called the landed gate before it."""
    monkeypatch.setenv("DRS_ONE_RULE_RB", PASSWORD)
    config = write_config(tmp_path, gateway)
    store = Store.open(load_config(config).store_path)
    falling(store, utc_now() - timedelta(minutes=12), 6)
    refused = parachute_refusal(config, front_end, capsys)
    assert refused == (
        "DRS1: PARACHUTE refused: overriding the landed check needs a second operator or a logged "
        "single-operator waiver"
    )
    assert gateway.requests == []
    assert store.query("SELECT COUNT(*) AS n FROM mt_command")[0]["n"] == 0


@pytest.mark.parametrize("front_end", ["cli", "operations"])
def test_with_the_rule_on_a_typed_second_operator_cannot_override_the_landed_gate(
    tmp_path: Path,
    gateway: SimulatedRockblock,
    monkeypatch: pytest.MonkeyPatch,
    capsys: pytest.CaptureFixture[str],
    front_end: str,
) -> None:
    """#23: `--override-landed "…" --second-operator Bob` queued PARACHUTE while it fell at 16 m/s."""
    monkeypatch.setenv("DRS_ONE_RULE_RB", PASSWORD)
    config = write_config(tmp_path, gateway)
    config.write_text(config.read_text().replace(
        "require_second_operator = false", 'require_second_operator = true\ncrew = ["alice", "bob"]'
    ))  # fmt: skip
    store = Store.open(load_config(config).store_path)
    falling(store, utc_now() - timedelta(minutes=12), 6)
    refused = parachute_refusal(config, front_end, capsys, "--second-operator", "bob")
    assert refused.startswith(
        "DRS1: PARACHUTE refused: require_second_operator is on: a typed second operator is not accepted; "
        "ask another login to approve it"
    )
    assert gateway.requests == []
    [audited] = [a for a in store.audit("DRS1") if a.action == "mt.parachute"]
    assert audited.result == "refused"

"""Fixtures for the console: the real demo world (SSH simulators, simulated RockBLOCK, MO receiver,
demo weather and terrain), and a fixed-time console fed from telemetry records for snapshots."""

from __future__ import annotations

import os
import shutil
import subprocess
import tempfile
import time
import uuid
from collections.abc import Callable, Iterator
from dataclasses import replace
from datetime import UTC, datetime, timedelta
from pathlib import Path
from typing import Any

import pytest
from textual.pilot import Pilot

import console.app as console_app
from console.app import ConsoleSetup, DrsConsole
from console.commands.console import _team, demo_setup
from console.demo import DemoWorld, write_demo_terrain
from console.predictions import PredictionService, ReleaseOrigin
from drs_link.config import Config, parse_config
from drs_link.iridium.firmware import GnssFix, format_mo
from drs_link.iridium.reports import Delivery, ReportStore
from drs_link.ops.arm_window import ArmWindow, ArmWindows
from drs_link.ops.operator_ops import OperatorOps
from drs_link.ops.telemetry import (
    BalloonSample,
    GatewaySample,
    GnssSample,
    LinkSample,
    ReleaseSample,
    Sample,
    StorageSample,
    SyncSample,
    TelemetryRecord,
)
from drs_link.server import InProcessServer
from drs_link.server.desks import holder_of
from drs_link.server.peers import Peer, account_of
from drs_link.store import Store
from predictor import Terrain
from predictor.environment.demo_weather import demo_weather_files

T0 = datetime(2026, 9, 1, 12, 0, tzinfo=UTC)
SITE = (67.8887, 21.0856)
DEMO_SPEED = 8.0
DEMO_TEST_ARM_WINDOW_S = 1800.0
"""The demo's ARM window in its tests, in demo seconds (225 s of wall clock at ``DEMO_SPEED``).

The demo's own, 120 demo seconds, is 15 s of wall clock: a starved run (nice 19 beside two CPU hogs) took
longer than that to type a name and a reason into the FIRE dialog, and the window ran out before the
refusal the test was about. A test of the window's end skips the clock past it (``SkipClock``)."""


STATE_TIMEOUT_S = 120.0
"""How long a test waits for the console to reach a state before calling it a failure.

A limit, not an expectation: on an idle machine every wait ends in well under a second, but a loaded
2-core CI machine (numba compiling in one process, sshd and the simulators in others) was seen to take
30 s. The test still ends the moment the state is reached, so a generous limit costs nothing."""


class ConsoleUnderTest(DrsConsole):
    """A console as a test drives it, beside the test's own hold on what the server keeps: ``store`` (the
    server's store, read by the test) and ``ops`` (an engine over it, for what a test sets up or checks,
    as another process on the store would). The console itself reaches neither: it is the server's client."""

    CSS_PATH = [str(Path(console_app.__file__).parent / path) for path in DrsConsole.CSS_PATH]
    """Textual reads a relative stylesheet path beside the module of the app's class: here, the console's."""

    def __init__(
        self, setup: ConsoleSetup, store: Store, ops: OperatorOps | None = None, live_timers: bool = True
    ) -> None:
        super().__init__(setup, live_timers)
        self.store = store
        self.ops = ops
        self.stops: list[Callable[[], None]] = []
        """What ends with the console: the private server ``console_on`` started for it."""

    def on_unmount(self) -> None:
        super().on_unmount()
        for stop in self.stops:
            stop()


def offline_server(
    config: Config, request: pytest.FixtureRequest, clock: Callable[[], datetime] | None = None
) -> Path:
    """An operations server in this process on ``config`` (on ``clock``), ended with the test: what a
    replay reads History from, or a console with nothing behind it commands."""
    server = InProcessServer(config, clock=clock)
    request.addfinalizer(server.stop)
    return server.socket


def console_on(ops: OperatorOps, setup: ConsoleSetup, live_timers: bool = True) -> ConsoleUnderTest:
    """A commanding console on ``ops``'s store, through a private server in this process on ``ops``'s
    configuration, clock and gateway password (ended with the console); the zones and recording are
    ``ops``'s too."""
    server = InProcessServer(ops.state.config, environ=ops.state.environ, clock=ops.state.clock)
    setup = replace(setup, server=server.socket, zones=ops.release.zones,
                    zones_file=ops.state.config.console.exclusion_zones_file, recorder=ops.state.recorder)  # fmt: skip
    try:
        app = ConsoleUnderTest(setup, ops.state.store, ops, live_timers)
    except BaseException:
        server.stop()
        raise
    app.stops.append(server.stop)
    return app


async def wait_for(
    pilot: Pilot[Any],
    condition: Callable[[], bool],
    timeout_s: float = STATE_TIMEOUT_S,
    skip: Callable[[], None] | None = None,
) -> None:
    """Let the app run until ``condition`` holds; fail after ``timeout_s`` (never a fixed sleep).
    ``skip``: called between two looks, to move the clock on where only time stands in the way
    (``tests.clock.SkipClock.skipper``)."""
    deadline = time.monotonic() + timeout_s
    while not condition():
        if time.monotonic() > deadline:
            raise AssertionError(f"the console did not reach the expected state within {timeout_s:.0f} s")
        if skip is not None:
            skip()
        await pilot.pause(0.05)


@pytest.fixture
def demo(tmp_path: Path) -> Iterator[tuple[DemoWorld, ConsoleUnderTest]]:
    """The whole demo, as ``drs demo`` wires it, with its world running ``DEMO_SPEED`` times faster."""
    world = DemoWorld(tmp_path / "demo", DEMO_SPEED)
    config = world.start()
    config = replace(config, console=replace(config.console, arm_window_s=DEMO_TEST_ARM_WINDOW_S))
    setup = None
    try:
        setup = demo_setup(world, config, tmp_path / "exports", poll_period_s=0.5, prediction_period_s=2.0)
        assert world.store is not None
        ops = OperatorOps(config, world.store, clock=world.clock, environ=world.environ)
        yield world, ConsoleUnderTest(setup, world.store, ops)
    finally:
        if setup is not None:
            setup.close()
        world.stop()


def offline_config(tmp_path: Path) -> Config:
    """Three capsules nobody listens for (port 9): the console is built but never connects."""
    capsules = [
        {
            "name": name,
            "host": "127.0.0.1",
            "port": 9,
            "imei": f"30043406000{i:04d}",
            "rockblock_serial": 17000 + i,
        }
        for i, name in enumerate(("DRS1", "DRS2", "DRS3"), start=1)
    ]
    return parse_config({
        "operator": {"name": "EL"}, "data": {"dir": str(tmp_path / "data")},
        "console": {"team_position": "67.64,21.99"}, "capsule": capsules,
    })  # fmt: skip


@pytest.fixture(scope="session")
def prediction_service(tmp_path_factory: pytest.TempPathFactory) -> PredictionService:
    """Predictions from the demo atmosphere and terrain at a fixed time (same numbers every run)."""
    root = tmp_path_factory.mktemp("prediction")
    terrain = write_demo_terrain(root / "dem.nc")
    files = demo_weather_files(SITE[0], SITE[1], T0, cache_dir=root / "weather", hours=6)
    return PredictionService(lambda: files, lambda: Terrain.from_netcdf(terrain), lambda: T0)


@pytest.fixture(scope="session")
def canned_prediction(prediction_service: PredictionService) -> list[TelemetryRecord]:
    return prediction_service.predict(
        "DRS1", ReleaseOrigin(SITE[0], SITE[1], 31500.0, "DRS1 GNSS"), release_in=(0, 10)
    )


def canned_records(prediction: list[TelemetryRecord]) -> list[TelemetryRecord]:
    """One fleet at T0: DRS1 powered with a fix, DRS2 idle and half synced, DRS3 with a stale link."""

    def rec(capsule: str | None, sample: Sample, age_s: float = 0.0) -> TelemetryRecord:
        return TelemetryRecord(T0 - timedelta(seconds=age_s), capsule, sample)

    storage = StorageSample(used_bytes=12_400_000_000, total_bytes=128_000_000_000, raid="healthy")
    records = [
        rec(None, GatewaySample(credentials_ok=True)),
        rec(None, BalloonSample(lat=SITE[0], lon=SITE[1], alt_m=31500.0), 5),
        rec("DRS1", LinkSample(up=True), 3),
        rec("DRS1", ReleaseSample(state="powered", nmea_seen=True), 3),
        rec(
            "DRS1",
            GnssSample(has_fix=True, sats=9, hdop=0.9, lat=SITE[0], lon=SITE[1], alt_m=31500.0),
            3,
        ),  # fmt: skip
        rec("DRS1", storage, 4),
        rec("DRS1", SyncSample(fraction=1.0, bytes_pending=0), 4),
        rec("DRS2", LinkSample(up=True), 2),
        rec("DRS2", ReleaseSample(state="idle", nmea_seen=False), 2),
        rec("DRS2", storage, 2),
        rec("DRS2", SyncSample(fraction=0.5, bytes_pending=400_000), 2),
        rec("DRS3", LinkSample(up=True), 95),
        rec("DRS3", ReleaseSample(state="idle", nmea_seen=False), 95),
        rec("DRS3", replace(storage, raid="degraded"), 95),
    ]
    return records + [TelemetryRecord(T0 - timedelta(seconds=6), r.capsule, r.data) for r in prediction]


def window_of_this_account(app: DrsConsole, capsule: str = "DRS1", firing: bool = False) -> ArmWindow:
    """An ARM window held by this account at the console's server, written to the store as the server's
    ARM writes it (the canned capsules nobody listens for are never polled GO); FIRING when ``firing``."""
    holder = holder_of(Peer(os.geteuid(), account_of(os.geteuid()), "EL"))
    windows = ArmWindows(app.store)
    now = app.store.clock()
    window, _ = windows.open(capsule, holder, "test", "EL", now, now + timedelta(minutes=1), "")
    assert window is not None
    if firing:
        assert windows.start_firing(window.id, holder, now)
    return window


def seed_reports(store: Store, imei: str, start: datetime, count: int, interval_min: int = 2) -> None:
    """Reports of a landed capsule, byte-exact as the firmware writes them, stored as the webhook would."""
    reports = ReportStore(store)
    for n in range(count):
        at = start + timedelta(minutes=interval_min * n)
        descending = n < count - 3
        alt = 9000.0 - 3000.0 * n if descending else 412.0
        fix = GnssFix(at, 67.70 + 0.001 * min(n, count - 3), 21.60, max(alt, 412.0), 6.0 if descending else 0.0,
                      90.0, 0.9, 9)  # fmt: skip
        payload = format_mo(fix, 8.7, n)
        reports.add(Delivery(imei, n, payload.hex(), "webhook", at + timedelta(seconds=20),
                             transmit_utc=at + timedelta(seconds=15)))  # fmt: skip


@pytest.fixture
def canned_app(
    tmp_path: Path,
    canned_prediction: list[TelemetryRecord],
    prediction_service: PredictionService,
    request: pytest.FixtureRequest,
) -> Callable[..., ConsoleUnderTest]:
    """A console at a fixed time, data from records, no timers: what it shows never changes (a live one
    acts through an operations server of its own, in this process, ended with it)."""

    def build(mode: str = "live", now: datetime = T0) -> ConsoleUnderTest:
        config = offline_config(tmp_path)
        store = Store.open(config.store_path)
        operations = OperatorOps(config, store, clock=lambda: now) if mode == "live" else None
        store.append_audit("EL", "DRS1", "power-on", "ok", {"session": "s1"}, when=T0 - timedelta(minutes=2))
        store.append_audit(
            "EL", "DRS1", "waiver", "granted", {"item": "gnss"}, when=T0 - timedelta(minutes=1)
        )
        seed_reports(store, config.capsules[1].imei or "", T0 - timedelta(minutes=30), 8)
        setup = ConsoleSetup(
            mode=mode, capsules=["DRS1", "DRS2", "DRS3"], clock=lambda: now, team_position=_team(config),
            export_dir=tmp_path / "exports", predictions=prediction_service if mode == "live" else None,
        )  # fmt: skip
        if operations is not None:
            app = console_on(operations, setup, live_timers=False)
        else:
            server = offline_server(config, request, lambda: now)
            app = ConsoleUnderTest(replace(setup, server=server), store, live_timers=False)
        for record in canned_records(canned_prediction):
            app.fleet.apply(record)
        return app

    return build


@pytest.fixture(scope="session")
def tmux_server() -> Iterator[None]:
    """One tmux server for every test: killing a test's last session ends the server, and the next
    test's new-session raced its shutdown ("server exited unexpectedly") on a loaded CI machine."""
    tmux = shutil.which("tmux")
    if tmux is None:
        pytest.skip("tmux is not installed (.ci/run installs it)")
    # This run's own tmux server (its socket in a directory of its own): parallel workers, a second
    # suite at once or a developer's tmux never share a server, so none can end another's. TMUX is
    # dropped too: inside tmux it would point every command at the developer's server.
    saved = {name: os.environ.get(name) for name in ("TMUX_TMPDIR", "TMUX")}
    socket_dir = tempfile.mkdtemp(prefix="drs-tmux-")
    os.environ["TMUX_TMPDIR"] = socket_dir
    os.environ.pop("TMUX", None)
    keeper = f"drs-keeper-{uuid.uuid4().hex[:8]}"
    subprocess.run([tmux, "new-session", "-d", "-s", keeper, "sleep 86400"], check=True)
    try:
        yield
    finally:
        subprocess.run([tmux, "kill-server"], check=False)
        shutil.rmtree(socket_dir, ignore_errors=True)
        for name, value in saved.items():
            if value is None:
                os.environ.pop(name, None)
            else:
                os.environ[name] = value

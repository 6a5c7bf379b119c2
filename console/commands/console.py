"""``drs console [--demo] [--replay FILE]`` and ``drs demo``: build the console's setup and run it.

The console is a full-screen terminal app; started without a terminal (a pipe, CI, cron) it
would hang or draw garbage, so it refuses with one line instead. Textual, the predictor and the
SSH stack are imported only when the console starts, so every other ``drs`` command stays quick.
"""

from __future__ import annotations

import argparse
import os
import pwd
import sys
import tempfile
import time
from collections.abc import Callable
from dataclasses import replace
from datetime import datetime, timedelta
from pathlib import Path
from typing import TYPE_CHECKING

from drs_link.config import Config, load_config
from drs_link.errors import ConfigError, LinkError
from drs_link.ops import TelemetryRecord, TelemetryRecorder, read_recording

if TYPE_CHECKING:
    from console.context import ConsoleSetup
    from console.demo import DemoWorld
    from drs_link.feeds import BalloonFeed
    from predictor import Terrain

NOT_A_TERMINAL = (
    "the console is a full-screen terminal app and stdout is not a terminal; "
    "run it from an interactive shell (for a scripted check use `drs capsule status`)"
)


LOW_BANDWIDTH_HELP = (
    "for a thin SSH link: no animation or zebra stripes, the fleet's ages in 10-s steps (countdowns stay "
    "exact); also [console] low_bandwidth = true"
)


def register(subparsers: argparse._SubParsersAction) -> None:
    console = subparsers.add_parser("console", help="the operator console (full-screen terminal app)")
    mode = console.add_mutually_exclusive_group()
    mode.add_argument("--demo", action="store_true", help="simulated capsules, gateway, weather and terrain")
    mode.add_argument(
        "--replay", type=Path, metavar="FILE", help="replay a telemetry recording (no commanding)"
    )
    console.add_argument(
        "--speed", type=float, default=None, help="demo time scale / replay speed (default 4 / 1)"
    )
    console.add_argument(
        "--weather", type=Path, nargs="+", metavar="GRIB", help="GFS GRIB2 files for predictions"
    )
    console.add_argument(
        "--terrain", type=Path, metavar="DIR", help="SRTM tiles / DEM directory for predictions"
    )
    console.add_argument("--low-bandwidth", action="store_true", help=LOW_BANDWIDTH_HELP)
    console.set_defaults(func=cmd_console)
    demo = subparsers.add_parser("demo", help="the console with everything simulated (= drs console --demo)")
    demo.add_argument(
        "--speed", type=float, default=None, help="simulated seconds per real second (default 4)"
    )
    demo.add_argument("--low-bandwidth", action="store_true", help=LOW_BANDWIDTH_HELP)
    demo.add_argument(
        "--live", action="store_true",
        help="rehearse the real release: the demo world behind the LIVE console, configured from a drs.toml "
        "it writes (absolute paths), at the real pace",
    )  # fmt: skip
    demo.set_defaults(func=cmd_demo, demo=True, replay=None, weather=None, terrain=None)


def _require_terminal() -> None:
    if not (sys.stdout.isatty() and sys.stdin.isatty()):
        raise LinkError(NOT_A_TERMINAL)


def _team(config: Config) -> tuple[float, float] | None:
    from drs_link.ops import parse_position

    text = config.console.team_position.strip()
    if not text:
        return None
    try:
        return parse_position(text)
    except (LinkError, ValueError) as exc:
        raise ConfigError(f"console.team_position: {exc}") from None


def started_balloon_feed(config: Config, clock: Callable[[], datetime]) -> BalloonFeed | None:
    """The configured ground-station feed, already listening: a port in use stops the start, not a launch."""
    from drs_link.feeds import BalloonFeed

    if not config.balloon_feed.kind:
        return None
    feed = BalloonFeed(config.balloon_feed, clock)
    feed.start()
    return feed


def run_console(setup: ConsoleSetup) -> int:
    from console.app import DrsConsole

    try:
        return DrsConsole(setup).run() or 0
    finally:
        setup.close()


def _recorder(config: Config) -> TelemetryRecorder:
    """Each console its own file, named for its account and process: two operators' consoles started in the
    same second once met at one file that only the first could write (issue #29)."""
    stamp = time.strftime("%Y%m%dT%H%M%SZ", time.gmtime())
    account = pwd.getpwuid(os.geteuid()).pw_name
    return TelemetryRecorder(
        config.data.dir / "recordings" / f"telemetry-{stamp}-{account}-{os.getpid()}.jsonl"
    )


class ReplayFeed:
    """Hands out recorded records as the replay clock passes their times (``speed`` × real time)."""

    def __init__(self, records: list[TelemetryRecord], speed: float) -> None:
        if speed <= 0:
            raise ConfigError("--speed must be positive")
        self.records = records
        self.speed = speed
        self.start = records[0].time
        self._t0 = time.monotonic()
        self._next = 0

    def clock(self) -> datetime:
        return self.start + timedelta(seconds=(time.monotonic() - self._t0) * self.speed)

    def due(self) -> list[TelemetryRecord]:
        now = self.clock()
        out = []
        while self._next < len(self.records) and self.records[self._next].time <= now:
            out.append(self.records[self._next])
            self._next += 1
        return out


def replay_setup(path: Path, speed: float, config: Config) -> tuple[ConsoleSetup, ReplayFeed]:
    """The recording through the same views; History and the checklist ticks are the operations server's
    (read, never written); nothing commands."""
    from console.context import ConsoleSetup

    records = read_recording(path)
    feed = ReplayFeed(records, speed)
    names = sorted({r.capsule for r in records if r.capsule}) or [c.name for c in config.capsules]
    setup = ConsoleSetup(
        mode="replay", capsules=names, server=operations_server(config), clock=feed.clock, banner_note=f"{path.name} ×{speed:g}",
        replay_feed=feed.due,
    )  # fmt: skip
    return setup, feed


def live_setup(config: Config, weather: list[Path] | None, terrain: Path | None) -> ConsoleSetup:
    from console.context import ConsoleSetup
    from console.predictions import PredictionService, capsule_models
    from drs_link.ops import load_exclusion_zones, utc_now
    from predictor import Terrain

    if not config.capsules:
        raise ConfigError(
            "no [[capsule]] in the configuration: add one (see docs/console.md) or try `drs demo`"
        )
    server = operations_server(config)
    predictions = None
    if weather:
        files = list(weather)
        terrain_factory: Callable[[], Terrain] = (
            (lambda: Terrain.from_dir(terrain)) if terrain is not None else Terrain.sea_level
        )
        models = capsule_models([(c.name, c.model) for c in config.capsules])
        predictions = PredictionService(lambda: files, terrain_factory, utc_now, models)
    return ConsoleSetup(
        mode="live", capsules=[c.name for c in config.capsules], server=server, recorder=_recorder(config),
        zones=load_exclusion_zones(config.console.exclusion_zones_file),
        zones_file=config.console.exclusion_zones_file, weather=tuple(weather or ()), predictions=predictions,
        balloon_feed=started_balloon_feed(config, utc_now),
        team_position=_team(config), export_dir=config.data.dir / "exports",
        prediction_period_s=config.console.prediction_period_s,
    )  # fmt: skip


def operations_server(config: Config) -> Path:
    """The socket every action of this console goes through: the team's server (``[server] socket``),
    else this account's private one, started on demand (``drs_link.server.private``)."""
    if config.server.socket:
        return Path(config.server.socket).expanduser()
    from console.commands.server import predictor_for
    from drs_link.server import ensure_private_server

    return ensure_private_server(config, predictor_for)


def cmd_console(args: argparse.Namespace) -> int:
    _require_terminal()
    if args.demo:
        return run_demo(args.speed or 4.0, args.low_bandwidth)
    config = load_config(args.config)
    thin = args.low_bandwidth or config.console.low_bandwidth
    if args.replay is not None:
        setup, _ = replay_setup(args.replay, args.speed or 1.0, config)
        return run_console(replace(setup, low_bandwidth=thin))
    from console.chase import started_chase_feed

    setup = replace(live_setup(config, args.weather, args.terrain), low_bandwidth=thin)
    chase = started_chase_feed(config, setup)
    try:
        return run_console(setup)
    finally:
        if chase is not None:
            chase.stop()


def cmd_demo(args: argparse.Namespace) -> int:
    if args.live and args.speed not in (None, 1.0):
        raise ConfigError(
            "--live runs at the real pace (the live console reads the wall clock): drop --speed"
        )
    _require_terminal()
    if args.live:
        return run_live_demo(args.low_bandwidth)
    return run_demo(args.speed or 4.0, args.low_bandwidth)


def run_live_demo(low_bandwidth: bool = False) -> int:
    """``drs demo --live``: the world in this process, the console in live mode from the file it wrote."""
    from console.chase import started_chase_feed
    from console.commands.invocation import drs_command
    from console.live_demo import rehearsal_lines, start_live_demo

    root = Path(tempfile.mkdtemp(prefix="drs-live-demo-"))
    print(f"drs demo --live: starting simulated capsules, gateway and weather in {root} …", flush=True)
    world, path, _ = start_live_demo(root)
    said = rehearsal_lines(drs_command(), path, world)
    try:
        print("\n".join(said), flush=True)
        config = load_config(str(path))  # read back from the file, as a launch-day console does
        setup = replace(
            live_setup(config, world.weather_files, world.terrain_file.parent), low_bandwidth=low_bandwidth
        )
        chase = started_chase_feed(config, setup)
        try:
            result = run_console(setup)
        finally:
            if chase is not None:
                chase.stop()
    finally:
        world.stop()
    try:
        print(
            "\n".join([*said[:2], f"drs demo --live: session kept in {root} (the simulators have stopped)"])
        )
    except OSError:
        pass  # the terminal hung up
    return result


def demo_setup(
    world: DemoWorld,
    config: Config,
    export_dir: Path,
    recorder: TelemetryRecorder | None = None,
    poll_period_s: float | None = None,
    prediction_period_s: float | None = None,
) -> ConsoleSetup:
    """The console wired to a started demo world as ``drs demo`` runs it; tests and screenshots change the pace."""
    from console.commands.server import predictor_for
    from console.context import ConsoleSetup
    from console.predictions import PredictionService
    from drs_link.ops import load_exclusion_zones
    from drs_link.server import InProcessServer, Periods

    speed = world.speed
    poll_s = Periods.at_scale(speed).poll_s if poll_period_s is None else poll_period_s
    # the world's password stays in here; the server polls at the pace the console judges ages by
    server = InProcessServer(config, predictor_for, world.environ, poll_period_s=poll_s)
    feed = started_balloon_feed(config, world.clock)
    world.send_balloon_position(world.clock())  # the world's first was sent before the feed listened
    return ConsoleSetup(
        mode="demo", capsules=[c.name for c in config.capsules], clock=world.clock, recorder=recorder,
        zones=load_exclusion_zones(config.console.exclusion_zones_file),
        zones_file=config.console.exclusion_zones_file, server=server.socket, stop_server=server.stop, weather=tuple(world.weather_files),
        predictions=PredictionService(lambda: world.weather_files, world.terrain, world.clock),
        balloon_feed=feed, team_position=_team(config),
        export_dir=export_dir, banner_note=f"×{speed:g} time",
        poll_period_s=poll_s,
        prediction_period_s=(
            config.console.prediction_period_s / speed if prediction_period_s is None else prediction_period_s
        ),
        time_scale=speed,
    )  # fmt: skip


def replay_command(recording: Path) -> str:
    """The demo's last line: the replay command as a fresh shell runs it (`drs` is often not on its PATH)."""
    from console.commands.invocation import drs_command

    return f"{drs_command()} console --replay {recording}"


def run_demo(speed: float, low_bandwidth: bool = False) -> int:
    from console.demo import DemoWorld

    root = Path(tempfile.mkdtemp(prefix="drs-demo-"))
    try:
        world = DemoWorld(root, speed)
    except ValueError as exc:
        raise ConfigError(f"--speed: {exc}") from None
    print(f"drs demo: starting simulated capsules, gateway and weather in {root} …", flush=True)
    try:
        config = world.start()
        recorder = _recorder(config)
        setup = demo_setup(world, config, root / "exports", recorder)
        result = run_console(replace(setup, low_bandwidth=low_bandwidth))
    finally:
        world.stop()
    try:
        print(f"drs demo: session kept in {root}; replay it with: {replay_command(recorder.path)}")
    except OSError:
        pass  # the terminal hung up (the session was lost): the store and recording say it all
    return result

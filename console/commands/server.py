"""``drs server``: run the operations server (``drs_link.server``), and ``drs server bench``.

Shared use runs it as its own account under systemd (``drs setup server --group G`` writes the unit);
single-operator use never runs it by hand: the first ``drs`` command that acts starts a private one.
"""

from __future__ import annotations

import argparse
from pathlib import Path
from typing import TYPE_CHECKING

from drs_link.errors import LinkError
from predictor.errors import UsageError

if TYPE_CHECKING:
    from drs_link.ops import LiveSource, OpsState, Predict

SHARED_SOCKET = Path("/run/drs/drs.sock")
"""Where a shared server listens by default: systemd's ``RuntimeDirectory=drs``."""


def register(subparsers: argparse._SubParsersAction) -> None:
    server = subparsers.add_parser(
        "server",
        help="the operations server: holds the store, the capsule links and the gateway credentials",
        description="Run the one process that acts: every drs command and console connects to it over a "
        "Unix socket, and it knows each caller's account from the kernel. Shared (default): the "
        "[[operator]] list of its own configuration maps accounts to operators; the configuration must "
        "be writable by this account or root only, and the data directory 0700. --private: this "
        "account's own server (started on demand by drs; one account reaches it).",
    )
    server.add_argument("--private", action="store_true", help="this account's own server (0600 socket)")
    server.add_argument(
        "--socket", type=Path, help=f"where to listen (default: [server] socket, else {SHARED_SOCKET})"
    )
    server.add_argument("--group", help="shared: the operators' group, given the socket (mode 0660)")
    server.add_argument("--idle-exit", type=float, metavar="S", help="exit after S seconds without a request")
    server.set_defaults(func=run_server)
    actions = server.add_subparsers(dest="server_action", metavar="ACTION")
    bench = actions.add_parser("bench", help="measure a command's round trip through the server (p50/p99)")
    bench.add_argument("--rounds", type=int, default=2000, help="round trips to time (default 2000)")
    bench.set_defaults(func=run_bench)


def predictor_for(files: list[Path], desk: OpsState) -> Predict:
    """The "release now" prediction go/no-go judges: the console's prediction service, on ``files``."""
    from console.predictions import PredictionService, capsule_models
    from predictor import Terrain

    models = capsule_models([(c.name, c.model) for c in desk.config.capsules])
    service = PredictionService(lambda: files, Terrain.sea_level, desk.clock, models)
    return lambda name, origin: service.predict(name, origin, release_in=(0,))


def live_for(files: list[Path], dem: Path | None, desk: OpsState) -> LiveSource:
    """The live re-prediction ``drs recovery --map --weather`` draws: the console's prediction service on
    ``files``, over the terrain of ``dem`` (else sea level), flying each capsule's model."""
    from console.predictions import PredictionService, capsule_models
    from predictor import Terrain

    models = capsule_models([(c.name, c.model) for c in desk.config.capsules])
    ground = Terrain.from_dir(dem) if dem is not None else Terrain.sea_level()
    return PredictionService(lambda: files, lambda: ground, desk.clock, models).live


def run_server(args: argparse.Namespace) -> int:
    import asyncio

    from drs_link.config import load_config
    from drs_link.server import OperationsServer

    config = load_config(args.config)
    if args.private and args.group:
        raise UsageError("--group is for a shared server; a private one is this account's alone")
    socket_path = args.socket or (Path(config.server.socket) if config.server.socket else SHARED_SOCKET)
    server = OperationsServer(
        config, "private" if args.private else "shared", socket_path.expanduser(), group=args.group, idle_exit_s=args.idle_exit,
        predictor_for=predictor_for, live_for=live_for,
    )  # fmt: skip
    try:
        asyncio.run(server.run(lambda line: print(line, flush=True)))
    except OSError as exc:
        raise LinkError(f"cannot listen on {socket_path}: {exc.strerror}") from None
    return 0


def run_bench(args: argparse.Namespace) -> int:
    """Round trips of ``hello`` and of the approvals list (a store read) through this account's server."""
    import time

    from drs_link.config import load_config
    from drs_link.server import Client

    if not 10 <= args.rounds <= 1_000_000:
        raise UsageError("--rounds must be from 10 to 1000000")
    with Client.for_config(load_config(args.config)) as client:
        client.hello()
        for name, verb in (("hello (identity only)", client.hello), ("approvals list (a store read)",
                                                                      client.approvals.waiting)):  # fmt: skip
            times = []
            for _ in range(args.rounds):
                start = time.perf_counter()
                verb()
                times.append((time.perf_counter() - start) * 1000.0)
            times.sort()
            p50, p99 = times[len(times) // 2], times[min(len(times) - 1, int(len(times) * 0.99))]
            print(
                f"{name}: p50 {p50:.2f} ms, p99 {p99:.2f} ms, max {times[-1]:.2f} ms ({args.rounds} rounds)"
            )
    return 0

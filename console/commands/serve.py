"""``drs serve predictor``: our predictor behind a Tawhiri v1 API, for chase software on the LAN.

A chase car runs chasemapper, which asks a Tawhiri URL for every prediction; pointed here, it gets
the project's descent (with the selected model, terrain and weather) instead of SondeHub's, with no
network beyond the car. The server, its request checks and its response shape live in
``predictor.tawhiri.api``; this module only reads the command line, so ``drs --help`` stays quick.
"""

from __future__ import annotations

import argparse
import logging
import sys
import threading
from pathlib import Path
from typing import TYPE_CHECKING

from console.commands.argparser import input_file
from console.commands.stopping import stop_signals
from predictor.errors import PredictorError, UsageError

log = logging.getLogger(__name__)

if TYPE_CHECKING:  # the server loads the descent engine (numba): only when it is started
    from predictor.tawhiri import ApiServer

DEFAULT_PORT = 8090


def register(subparsers: argparse._SubParsersAction) -> None:
    serve = subparsers.add_parser("serve", help="serve predictions over HTTP (a Tawhiri v1 API)")
    services = serve.add_subparsers(dest="service", metavar="SERVICE", required=True)
    parser = services.add_parser(
        "predictor",
        help="answer GET /api/v1/ as Tawhiri does, a DRS capsule with its model (chasemapper, SondeHub predictor)",
        description="Answer Tawhiri v1 API requests (standard, float and reverse profiles): a constant-rate ascent drifting "
        "with the wind, then our descent from the burst, with our ellipse and model under 'drs'.",
    )
    weather = parser.add_mutually_exclusive_group(required=True)
    weather.add_argument("--weather", nargs="+", type=lambda text: Path(input_file("--weather")(text)),
                         metavar="FILE", help="GFS GRIB2 files; - reads one from standard input")  # fmt: skip
    weather.add_argument(
        "--weather-dir",
        type=Path,
        metavar="DIR",
        help="the GRIB2 files in DIR, listed again for every request",
    )
    weather.add_argument(
        "--demo-weather", action="store_true", help="the generated DEMO atmosphere (not a forecast)"
    )
    parser.add_argument(
        "--dem", metavar="DIR", help="terrain: SRTM .hgt tiles and/or NetCDF DEMs (default sea level)"
    )
    parser.add_argument(
        "--model",
        type=lambda text: Path(input_file("--model")(text)),
        metavar="PATH",
        help="a calibrated model (drs calibrate --save-model); - reads standard input",
    )
    parser.add_argument("--host", default="127.0.0.1", help="address to listen on (0.0.0.0 for the LAN)")
    parser.add_argument(
        "--port", type=int, default=DEFAULT_PORT, help=f"TCP port (default {DEFAULT_PORT}; 0: any free)"
    )
    parser.add_argument("--cache-dir", metavar="DIR", help="weather cache (default ~/.cache/drs/weather)")
    parser.set_defaults(func=run, log_default=logging.INFO)  # a service: its access log is its record


def run(args: argparse.Namespace) -> int:
    server = build_server(args)
    demo = " with DEMO weather (not a forecast)" if args.demo_weather else ""
    health = server.service.health()
    warm = (
        f"weather loaded and compiled code warm in {health['warmed_in_s']:g} s"
        if health["status"] == "ok"
        else f"NOT READY: {health['weather'].get('error', 'the warm-up flight failed')} (see /health)"
    )
    with stop_signals() as wait_for_stop:
        threading.Thread(target=server.serve_forever, name="drs-serve-predictor", daemon=True).start()
        print(
            f"drs serve predictor: Tawhiri v1 API at {server.url}{demo} ({warm}); Ctrl-C or SIGTERM stops "
            "it, after answering what has arrived",
            file=sys.stderr,
            flush=True,
        )
        log.info("stopping", extra={"signal": wait_for_stop(None)})
        unanswered = server.drain()
    log.info("stopped", extra={"unanswered": unanswered})
    return 0


def build_server(args: argparse.Namespace) -> ApiServer:
    """The server the command line asks for: its weather loaded and its compiled code warm, then
    listening but not yet serving (so the first request after the ready line is answered at once)."""
    if not 0 <= args.port <= 65535:
        raise UsageError(f"--port {args.port} is not a TCP port (0-65535)")
    if args.weather_dir is not None and not args.weather_dir.is_dir():
        raise PredictorError(f"--weather-dir {args.weather_dir} is not a directory")
    from drs_link.config import load_config
    from predictor.environment import Terrain
    from predictor.prediction import flown_model
    from predictor.tawhiri import ApiServer, FlownModel, PredictorService, WeatherSource

    config = load_config(getattr(args, "config", None))
    known = [capsule for capsule in config.capsules if capsule.imei]
    fixes = None
    if known:
        from drs_link.feeds import StoredFixes

        fixes = StoredFixes(config)
    default = flown_model(args.model, None, None, None)
    models = {
        capsule.name: FlownModel(flown_model(capsule.model, None, None, None), capsule.model)
        if capsule.model is not None
        else FlownModel(default, args.model)
        for capsule in known
    }
    source = WeatherSource(
        files=tuple(args.weather or ()), directory=args.weather_dir, demo=args.demo_weather
    )
    terrain = Terrain.from_dir(args.dem) if args.dem else Terrain.sea_level()
    service = PredictorService(source, terrain, default, args.model, args.cache_dir, fixes, models)
    service.warm()
    if args.weather is not None and service.health()["weather"]["loaded"] is False:
        raise PredictorError(f"--weather: {service.health()['weather'].get('error', 'no weather')}")
    try:
        return ApiServer(service, args.host, args.port)
    except OSError as exc:
        raise PredictorError(f"cannot listen on {args.host}:{args.port}: {exc.strerror or exc}") from None

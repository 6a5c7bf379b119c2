"""``drs recovery``: landing estimate, distance from you, GPX/KML and the recovery map, from a terminal.

A client of the operations server (issue #29): the server reads the stored reports (and, for
``--map --weather``, re-predicts the landing on weather files the caller's account could read) and
answers in typed values; this process reads what is the operator's own (their position, their gpsd,
their predicted track, their terrain files) and writes every file, so the files are theirs.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from pathlib import Path
from typing import TYPE_CHECKING

from console.commands.argparser import input_file, position_or_gpsd
from drs_link.config import load_config
from drs_link.errors import LinkError
from predictor.geofiles import piped

if TYPE_CHECKING:
    from drs_link.server.protocol import DescentView
    from drs_link.server.recovery import LiveFor


def register(subparsers: argparse._SubParsersAction) -> None:
    recovery = subparsers.add_parser("recovery", help="landing estimate, distance from you, GPX/KML export")
    recovery.add_argument("name")
    recovery.add_argument(
        "--from", dest="origin", type=position_or_gpsd, metavar="LAT,LON|gpsd", help="your position, or gpsd"
    )
    recovery.add_argument(
        "--gpx", type=Path, metavar="OUT", help="write GPX for a handheld (landings, tracks); - for stdout"
    )
    recovery.add_argument(
        "--kml", type=Path, metavar="OUT", help="write KML of the landings and tracks; - for stdout"
    )
    recovery.add_argument(
        "--predicted",
        type=lambda text: Path(input_file("--predicted")(text)),
        metavar="GEOJSON",
        help="a predicted track (LineString); - reads standard input",
    )
    recovery.add_argument(
        "--json", action="store_true", help="print JSON (the summary line is one of its fields)"
    )
    recovery.add_argument(
        "--map", type=Path, metavar="OUT.png",
        help="draw the track, the live predicted landing with its 1σ/2σ ellipses, the last fix and the chase",
    )  # fmt: skip
    recovery.add_argument(
        "--chase",
        type=position_or_gpsd,
        metavar="LAT,LON|gpsd",
        help="the chase car on the map (default: --from)",
    )
    recovery.add_argument(
        "--weather",
        type=Path,
        nargs="+",
        metavar="GRIB",
        help="GFS GRIB2 files: the map's live re-prediction",
    )
    recovery.add_argument(
        "--dem", type=Path, metavar="DIR", help="terrain: the map's shading and the prediction's ground"
    )
    recovery.set_defaults(func=_recovery)


def _says_demo(node: object) -> bool:
    """Whether any member of a GeoJSON document says ``is_demo`` (drs predict marks every feature)."""
    if isinstance(node, dict):
        return node.get("is_demo") is True or any(_says_demo(v) for v in node.values())
    return isinstance(node, list) and any(_says_demo(v) for v in node)


def _read_predicted(path: Path) -> tuple[list[tuple[float, float, float]], bool]:
    """The first path of a GeoJSON file as (lat, lon, alt) points: a LineString, or a MultiLineString
    (a path cut at ±180°, as drs predict --geojson writes one) with its parts joined; and whether the
    file says it was predicted on demo weather, which the recovery files must then say too."""
    try:
        document = json.loads(path.read_text(encoding="utf-8"))
    except (OSError, UnicodeDecodeError, json.JSONDecodeError) as exc:
        raise LinkError(f"--predicted {path}: cannot read GeoJSON ({type(exc).__name__})") from None
    stack = [document]
    while stack:
        node = stack.pop(0)
        if isinstance(node, dict):
            kind = node.get("type")
            if kind in {"LineString", "MultiLineString"} and isinstance(node.get("coordinates"), list):
                lines = node["coordinates"] if kind == "MultiLineString" else [node["coordinates"]]
                try:
                    points = [
                        (float(c[1]), float(c[0]), float(c[2]) if len(c) > 2 else 0.0)
                        for line in lines
                        for c in line
                    ]
                except (TypeError, ValueError, IndexError):
                    raise LinkError(f"--predicted {path}: LineString coordinates are not numbers") from None
                return points, _says_demo(document)
            stack.extend(v for v in node.values() if isinstance(v, dict | list))
        elif isinstance(node, list):
            stack.extend(v for v in node if isinstance(v, dict | list))
    raise LinkError(f"--predicted {path}: no LineString in the GeoJSON")


def _recovery(args: argparse.Namespace) -> int:
    """The server reads the reports (and re-predicts, for a map with weather); this process reads the
    team's position and the predicted track, which are the operator's, and writes every file asked for."""
    import msgspec

    from drs_link.positions import parse_position, read_gpsd_position
    from drs_link.server import PROTOCOL, Client
    from drs_link.server.protocol import RecoveryRequest
    from predictor.geofiles import write_text
    from predictor.prediction import emit, far_team_warning

    # With --json or a '-' output, stdout carries that one document and the lines for people go to stderr.
    said = sys.stderr if piped(gpx=args.gpx, kml=args.kml, json=args.json) or args.json else sys.stdout
    team = None
    if args.origin == "gpsd":
        team = read_gpsd_position()
    elif args.origin is not None:
        team = parse_position(args.origin)
    predicted, predicted_is_demo = _read_predicted(args.predicted) if args.predicted else ([], False)
    request = RecoveryRequest(
        PROTOCOL, team, tuple(predicted), predicted_is_demo, bool(args.gpx), bool(args.kml), bool(args.map),
        absolute(args.weather), None if args.dem is None else str(args.dem.absolute()),
    )  # fmt: skip
    with Client.for_config(load_config(args.config), live_for=_live_for()) as client:
        readout = client.recovery(args.name, request)
    if team is not None and readout.capsule_at is not None:
        emit(far_team_warning(team, (readout.capsule_at.lat, readout.capsule_at.lon)))
    if not args.json:
        print(readout.document.summary, file=said)
        if readout.landed is not None:
            print(readout.landed, file=said)
    for option, path, text, what in (
        ("gpx", args.gpx, readout.gpx, "GPX"),
        ("kml", args.kml, readout.kml, "KML"),
    ):
        if path:
            assert text is not None, f"the server sent no {option}"
            write_text(path, text, what)
            print(f"wrote {path}", file=said)
    if args.map:
        assert readout.descent is not None, "the server sent no descent"
        chase = (
            team if args.chase is None
            else read_gpsd_position() if args.chase == "gpsd"
            else parse_position(args.chase)
        )  # fmt: skip
        _draw_map(args, readout.document.capsule, readout.descent, chase)
        print(f"wrote {args.map}", file=said)
    if args.json:
        print(json.dumps(msgspec.to_builtins(readout.document), indent=2))
    return 0


def absolute(paths: list[Path] | None) -> tuple[str, ...]:
    """Paths as this process names them: the server does not share its working directory."""
    return tuple(str(p.absolute()) for p in paths or ())


def _live_for() -> LiveFor:
    """The live re-prediction a private server in this process runs (``DRS_PRIVATE_SERVER=thread``)."""
    from console.commands.server import live_for

    return live_for


def _draw_map(
    args: argparse.Namespace, name: str, descent: DescentView, chase: tuple[float, float] | None
) -> None:
    """The recovery picture from the server's descent (its live re-prediction flew the weather), drawn
    here over this operator's own terrain files."""
    from console.recovery_map import LiveLanding, draw_recovery_map, picture_from
    from predictor import Terrain

    live = descent.live
    predicted = None
    if live is not None and math.isfinite(live.sigma_major_km):
        predicted = LiveLanding(
            live.lat, live.lon, live.sigma_major_km, live.sigma_minor_km, live.major_axis_bearing_deg
        )
    last = (descent.track[-1].time, descent.track[-1].alt_m) if descent.track else None
    picture = picture_from(
        name,
        tuple((p.lat, p.lon) for p in descent.track),
        last,
        (descent.landed.lat, descent.landed.lon) if descent.landed is not None else None,
        predicted,
        (live.time, live.correction) if live is not None else None,
        descent.live_error,
        chase,
        weather=bool(args.weather),
    )
    draw_recovery_map(picture, args.map, Terrain.from_dir(args.dem) if args.dem else None)

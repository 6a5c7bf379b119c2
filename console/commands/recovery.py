"""``drs recovery``: landing estimate, distance from you, GPX/KML and the recovery map, from a terminal.

Not yet a client of the operations server (issue #29): it opens ``Operations`` in this process to read
the stored reports (and, with ``--map --weather``, re-predicts there), so in shared use it needs the
store, which only the server holds (docs/console.md). Its own module so that the Iridium commands
(``console.commands.iridium``) are clients whole.
"""

from __future__ import annotations

import argparse
import json
import math
import sys
from datetime import datetime
from pathlib import Path
from typing import TYPE_CHECKING

from console.commands.argparser import input_file, position_or_gpsd
from drs_link.config import CapsuleConfig, Config, load_config
from drs_link.errors import LinkError
from predictor.geofiles import piped

if TYPE_CHECKING:  # the recovery pipeline loads pyproj, ops paramiko: not for --help
    from drs_link.ops import LandingEstimate, Operations, StoredReport, TrackPoint


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


def _open(args: argparse.Namespace) -> tuple[Config, Operations]:
    from drs_link.ops import Operations, cli_holder

    config = load_config(args.config)
    return config, Operations.open(config, holder=cli_holder())


def _capsule_reports(ops: Operations, name: str) -> tuple[CapsuleConfig, list[StoredReport]]:
    return ops.config.capsule(name), ops.reports_of(name)


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
    from drs_link.ops import (
        detect_landing,
        parse_position,
        phone_summary,
        read_gpsd_position,
        track_from_reports,
        write_gpx,
        write_kml,
    )
    from predictor.prediction import emit, far_team_warning

    # With --json or a '-' output, stdout carries that one document and the lines for people go to stderr.
    said = sys.stderr if piped(gpx=args.gpx, kml=args.kml, json=args.json) or args.json else sys.stdout
    _, ops = _open(args)
    capsule, reports = _capsule_reports(ops, args.name)
    team = None
    if args.origin == "gpsd":
        team = read_gpsd_position()
    elif args.origin is not None:
        team = parse_position(args.origin)
    predicted, predicted_is_demo = _read_predicted(args.predicted) if args.predicted else ([], False)
    track = track_from_reports(reports)
    landing = detect_landing(track)
    coarse = None
    if reports and (position := reports[-1].iridium_position()) is not None:
        coarse = (*position, reports[-1].session_time)
    capsule_at = (landing.lat, landing.lon) if landing else (track[-1].lat, track[-1].lon) if track else None
    if team is not None and capsule_at is not None:
        emit(far_team_warning(team, capsule_at))
    summary = phone_summary(capsule.name, landing, track[-1] if track else None, team, coarse)
    if not args.json:
        print(summary, file=said)
        if landing is not None:
            print(
                f"landed {landing.landed_at:%Y-%m-%d %H:%M:%S}Z at {landing.alt_m:.0f} m; "
                f"{landing.count} fixes kept, {landing.rejected} rejected; "
                f"last on site {landing.last_fix_at:%H:%M:%S}Z",
                file=said,
            )
    if args.gpx:
        write_gpx(args.gpx, capsule.name, track, predicted, landing, predicted_is_demo=predicted_is_demo)
        print(f"wrote {args.gpx}", file=said)
    if args.kml:
        write_kml(args.kml, capsule.name, track, predicted, landing, predicted_is_demo=predicted_is_demo)
        print(f"wrote {args.kml}", file=said)
    if args.map:
        chase = (
            team
            if args.chase is None
            else read_gpsd_position()
            if args.chase == "gpsd"
            else parse_position(args.chase)
        )
        _draw_map(args, ops, capsule.name, reports, chase)
        print(f"wrote {args.map}", file=said)
    if args.json:
        print(json.dumps(_recovery_json(capsule.name, summary, landing, track, team, coarse), indent=2))
    return 0


def _draw_map(
    args: argparse.Namespace,
    ops: Operations,
    name: str,
    reports: list[StoredReport],
    chase: tuple[float, float] | None,
) -> None:
    """The recovery picture: the live re-prediction needs the weather (and flies the capsule's model)."""
    from console.predictions import PredictionService, capsule_models
    from console.recovery_map import draw_recovery_map, recovery_picture
    from drs_link.ops import follow_descent
    from predictor import Terrain

    terrain = Terrain.from_dir(args.dem) if args.dem else None
    live = None
    if args.weather:
        files = list(args.weather)
        models = capsule_models([(c.name, c.model) for c in ops.config.capsules])
        ground = terrain or Terrain.sea_level()
        live = PredictionService(lambda: files, lambda: ground, ops.clock, models).live
    descent = follow_descent(reports, name, live)
    picture = recovery_picture(name, descent, chase, weather=bool(args.weather))
    draw_recovery_map(picture, args.map, terrain)


def _recovery_json(
    name: str,
    summary: str,
    landing: LandingEstimate | None,
    track: list[TrackPoint],
    team: tuple[float, float] | None,
    coarse: tuple[float, float, float, datetime] | None,
) -> dict[str, object]:
    """What the summary line says, as numbers: the distance and bearing are from the team to the best
    position there is (the landing, else the last fix, else Iridium's coarse one)."""
    from drs_link.ops import distance_bearing, iso_utc

    last = track[-1] if track else None
    document: dict[str, object] = {
        "capsule": name,
        "summary": summary,
        "landing": None if landing is None else {
            "lat": landing.lat, "lon": landing.lon, "alt_m": landing.alt_m,
            "std_m": None if math.isnan(landing.std_m) else landing.std_m, "fixes": landing.count,
            "rejected": landing.rejected, "landed_utc": iso_utc(landing.landed_at),
            "last_fix_utc": iso_utc(landing.last_fix_at),
            "moved_utc": iso_utc(landing.moved_at) if landing.moved_at else None,
        },
        "last_fix": None if last is None else {
            "time_utc": iso_utc(last.time), "lat": last.lat, "lon": last.lon, "alt_m": last.alt_m,
            "speed_ms": last.speed_ms,
        },
        "iridium_position": None if coarse is None else {
            "lat": coarse[0], "lon": coarse[1], "cep_m": coarse[2], "time_utc": iso_utc(coarse[3]),
        },
        "from": None if team is None else {"lat": team[0], "lon": team[1]},
    }  # fmt: skip
    best = (
        (landing.lat, landing.lon)
        if landing
        else (last.lat, last.lon)
        if last
        else coarse[:2]
        if coarse
        else None
    )
    if team is not None and best is not None:
        distance, bearing = distance_bearing(team[0], team[1], best[0], best[1])
        document["distance_m"], document["bearing_deg"] = distance, bearing
    return document
